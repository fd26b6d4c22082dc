#include "eval/trajectory_format.h"

#include <gtest/gtest.h>

#include <sstream>

#include "slam/common/error.h"

namespace pcr::eval {
namespace {

TrajectoryFormat Detect(const std::string& text) {
  std::istringstream in(text);
  return DetectTrajectoryFormat(in, "mem.txt");
}

TEST(TrajectoryFormatTest, CountsTokensOfTheFirstDataLine) {
  EXPECT_EQ(Detect("1 0 0 0 0 1 0 0 0 0 1 0\n"), TrajectoryFormat::kKitti);
  EXPECT_EQ(Detect("# timestamp tx ty tz qx qy qz qw\n\n0.1 1 2 3 0 0 0 1\n"),
            TrajectoryFormat::kTum);
  try {
    Detect("\n# c\n1 2 3\n");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.file(), "mem.txt");
  }
  EXPECT_THROW(Detect("# only a comment\n"), InputError);
  EXPECT_THROW(DetectTrajectoryFormat("/nonexistent/dir/poses.txt"), InputError);
  EXPECT_EQ(ToString(TrajectoryFormat::kTum), "tum");
}

}  // namespace
}  // namespace pcr::eval
