#include "sim/instances.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::sim {
namespace {

std::vector<InstanceInfo> Sample() {
  InstanceInfo car{3, ObjectClass::kCar, false, 0.0, {1.8, 1.5, 4.2}};
  InstanceInfo person{7, ObjectClass::kPerson, true, 1.4, {0.46, 1.8, 0.26}};
  InstanceInfo bike{8, ObjectClass::kBicycle, true, 4.5, {0.6, 1.0, 1.72}};
  return {car, person, bike};
}

TEST(InstancesTest, LookUpByIdSeparatesBackgroundSkyAndObjects) {
  const InstanceTable table(Sample());
  EXPECT_EQ(table.size(), 3u);
  EXPECT_FALSE(table.IsObject(kStaticInstanceId));
  EXPECT_FALSE(table.IsObject(kSkyInstanceId));
  EXPECT_EQ(table.ClassNameOf(kStaticInstanceId), "background");
  EXPECT_EQ(table.ClassNameOf(kSkyInstanceId), "sky");
  EXPECT_EQ(table.ClassNameOf(3), "car");
  EXPECT_EQ(table.ClassNameOf(8), "bicycle");
  EXPECT_EQ(table.ClassNameOf(4), "unknown");
  EXPECT_FALSE(table.IsMoving(3));
  EXPECT_TRUE(table.IsMoving(7));
  EXPECT_FALSE(table.IsMoving(4));
  ASSERT_NE(table.Find(7), nullptr);
  EXPECT_DOUBLE_EQ(table.Find(7)->speed_mps, 1.4);
  EXPECT_THROW(InstanceTable({InstanceInfo{kSkyInstanceId}}), std::invalid_argument);
}

TEST(InstancesTest, TextRoundTripAndErrorsNameTheLine) {
  const InstanceTable table(Sample());
  const std::string dir = test::MakeTempDir("sim_instances");
  const std::string path = dir + "/instances.txt";
  {
    std::ofstream out(path);
    table.Write(out);
  }
  const InstanceTable back = InstanceTable::Read(path);
  ASSERT_EQ(back.size(), table.size());
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_EQ(back.all()[i].id, table.all()[i].id);
    EXPECT_EQ(back.all()[i].object_class, table.all()[i].object_class);
    EXPECT_EQ(back.all()[i].moving, table.all()[i].moving);
    EXPECT_NEAR(back.all()[i].speed_mps, table.all()[i].speed_mps, 1e-3);
    EXPECT_NEAR((back.all()[i].size_m - table.all()[i].size_m).norm(), 0.0, 1e-3);
  }
  {
    std::ofstream out(path);
    out << "# comment\n3 car 0 0 1 1 1\n4 truck 1 2 1 1 1\n";
  }
  try {
    InstanceTable::Read(path);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_NE(std::string(e.what()).find("truck"), std::string::npos);
  }
  {
    std::ofstream out(path);
    out << "3 car 2 0 1 1 1\n";
  }
  EXPECT_THROW(InstanceTable::Read(path), InputError);
  EXPECT_THROW(InstanceTable::Read(dir + "/missing.txt"), InputError);
  std::filesystem::remove_all(dir);
}

TEST(InstancesTest, MovingMaskMarksOnlyMovingInstances) {
  const InstanceTable table(Sample());
  cv::Mat ids(2, 3, CV_16UC1);
  ids.at<uint16_t>(0, 0) = 0;
  ids.at<uint16_t>(0, 1) = 3;
  ids.at<uint16_t>(0, 2) = 7;
  ids.at<uint16_t>(1, 0) = 8;
  ids.at<uint16_t>(1, 1) = kSkyInstanceId;
  ids.at<uint16_t>(1, 2) = 9;
  const cv::Mat mask = MovingMask(ids, table);
  EXPECT_EQ(mask.at<uint8_t>(0, 0), 0);
  EXPECT_EQ(mask.at<uint8_t>(0, 1), 0);
  EXPECT_EQ(mask.at<uint8_t>(0, 2), 255);
  EXPECT_EQ(mask.at<uint8_t>(1, 0), 255);
  EXPECT_EQ(mask.at<uint8_t>(1, 1), 0);
  EXPECT_EQ(mask.at<uint8_t>(1, 2), 0);
}

}  // namespace
}  // namespace pcr::sim
