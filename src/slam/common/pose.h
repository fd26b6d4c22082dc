#pragma once
// Poses and trajectories. A pose named a_from_b maps coordinates in frame b to frame a
// (p_in_a = a_from_b * p_in_b). Trajectories hold world_from_cam (camera-to-world), as KITTI and
// TUM files do.
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace pcr {

using SE3 = Eigen::Isometry3d;

struct StampedPose {
  int64_t t_ns = 0;          // timestamp in nanoseconds
  int64_t frame_index = -1;  // index of the input frame it belongs to, -1 when unknown
  SE3 world_from_cam = SE3::Identity();
};

using Trajectory = std::vector<StampedPose>;

inline int64_t SecondsToNs(double t_s) {
  return static_cast<int64_t>(t_s * 1e9 + (t_s >= 0 ? 0.5 : -0.5));
}
inline double NsToSeconds(int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }

// Total length of the path traced by the positions, in metres.
double PathLength(const Trajectory& trajectory);

}  // namespace pcr
