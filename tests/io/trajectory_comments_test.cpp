// '#' comment lines in KITTI-format poses: skipped, as evo does and as the eval command's format
// detection already did (the reader used to refuse them: "expected 12 numbers, found 2").
#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "io/trajectory_io.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

std::string KittiLineAtZ(double z) { return "1 0 0 0 0 1 0 0 0 0 1 " + std::to_string(z) + "\n"; }

TEST(KittiTrajectoryComments, CommentLinesAreSkippedAndTakeNoFrameIndex) {
  std::istringstream in("# timestamp-free KITTI poses\n" + KittiLineAtZ(0) + "  # a note\n" +
                        KittiLineAtZ(1) + KittiLineAtZ(2) + "# end\n\n");
  const Trajectory t = ReadKittiTrajectory(in, "poses.txt");
  ASSERT_EQ(t.size(), 3u);
  for (int64_t i = 0; i < 3; ++i) {
    EXPECT_EQ(t[i].frame_index, i);
    EXPECT_DOUBLE_EQ(t[i].world_from_cam.translation().z(), static_cast<double>(i));
  }
}

TEST(KittiTrajectoryComments, ABlankLineBeforeDataIsStillRefused) {
  // A blank line would shift the frame indices; a comment after it does not change that.
  std::istringstream in(KittiLineAtZ(0) + "\n# note\n" + KittiLineAtZ(1));
  try {
    ReadKittiTrajectory(in, "poses.txt");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(std::string(e.what()).find("blank line"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pcr
