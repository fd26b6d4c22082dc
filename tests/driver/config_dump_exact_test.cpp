// config.yaml reads back as the very doubles the run used (shortest round-trip text), so that a
// rerun with --config OUT/config.yaml is the same run.
#include <gtest/gtest.h>

#include <string>

#include "driver/config_schema.h"
#include "driver/slam_config.h"
#include "io/io_test_util.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

TEST(ConfigDump, DoublesReadBackExactlyAndShort) {
  double exact = 0.5371506532679237, tenth = 0.1, whole = 707.0, tiny = 1.25e-7;
  ConfigSchema s;
  s.Add("n", "exact", &exact);
  s.Add("n", "tenth", &tenth);
  s.Add("n", "whole", &whole);
  s.Add("n", "tiny", &tiny);
  const std::string dumped = s.Dump();
  // Short where short is exact: no 0.10000000000000001.
  EXPECT_NE(dumped.find("tenth: 0.1\n"), std::string::npos) << dumped;
  EXPECT_NE(dumped.find("exact: 0.5371506532679237\n"), std::string::npos) << dumped;
  double exact2 = 0, tenth2 = 0, whole2 = 0, tiny2 = 0;
  ConfigSchema s2;
  s2.Add("n", "exact", &exact2);
  s2.Add("n", "tenth", &tenth2);
  s2.Add("n", "whole", &whole2);
  s2.Add("n", "tiny", &tiny2);
  s2.LoadString(dumped, "dump");
  EXPECT_EQ(exact2, exact);
  EXPECT_EQ(tenth2, tenth);
  EXPECT_EQ(whole2, whole);
  EXPECT_EQ(tiny2, tiny);
}

// The finding's case: a calibration's baseline and exact chi-square quantiles given with --set,
// then config.yaml given back as --config.
TEST(ConfigDump, RerunWithTheWrittenConfigHasTheSameValues) {
  const std::vector<std::string> overrides = {"camera.fx=707.0912",
                                              "camera.fy=707.0912",
                                              "camera.cx=601.8873",
                                              "camera.cy=183.1104",
                                              "camera.baseline_m=0.5371506532679237",
                                              "tracking.chi2_mono=5.991464547107979",
                                              "tracking.chi2_stereo=7.814727903251178"};
  std::string yaml;
  const RunConfig first = LoadRunConfig("", overrides, &yaml);
  const std::string dir = test::MakeTempDir("config_dump_exact");
  const std::string path = dir + "/config.yaml";
  test::WriteText(path, yaml);
  std::string yaml2;
  const RunConfig second = LoadRunConfig(path, {}, &yaml2);
  EXPECT_EQ(second.camera.baseline_m, 0.5371506532679237);
  EXPECT_EQ(second.camera.baseline_m, first.camera.baseline_m);
  EXPECT_EQ(second.slam.tracker.pose.chi2_mono, first.slam.tracker.pose.chi2_mono);
  EXPECT_EQ(second.slam.tracker.pose.chi2_stereo, first.slam.tracker.pose.chi2_stereo);
  EXPECT_EQ(yaml2, yaml);  // the same file again
}

}  // namespace
}  // namespace pcr::driver
