// libFuzzer target: KITTI pose, TUM and times.txt parsers on arbitrary bytes. Bad input must end
// in pcr::InputError, never in a crash, a hang or another exception; parsed poses must be exact
// rotations.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <string>

#include "io/trajectory_io.h"
#include "slam/common/error.h"

namespace {

void CheckTrajectory(const pcr::Trajectory& trajectory) {
  for (const pcr::StampedPose& pose : trajectory) {
    const Eigen::Matrix3d r = pose.world_from_cam.linear();
    if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-9)
      std::abort();
    if (!pose.world_from_cam.translation().allFinite()) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    std::istringstream in(text);
    CheckTrajectory(pcr::ReadKittiTrajectory(in, "fuzz.kitti"));
  } catch (const pcr::InputError&) {
  }
  try {
    std::istringstream in(text);
    const pcr::Trajectory trajectory = pcr::ReadTumTrajectory(in, "fuzz.tum");
    CheckTrajectory(trajectory);
    for (size_t i = 1; i < trajectory.size(); ++i)
      if (trajectory[i].t_ns <= trajectory[i - 1].t_ns) std::abort();
  } catch (const pcr::InputError&) {
  }
  try {
    std::istringstream in(text);
    const std::vector<int64_t> times = pcr::ReadKittiTimes(in, "fuzz.times");
    for (size_t i = 1; i < times.size(); ++i)
      if (times[i] <= times[i - 1]) std::abort();
  } catch (const pcr::InputError&) {
  }
  return 0;
}
