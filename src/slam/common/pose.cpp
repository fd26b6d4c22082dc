#include "slam/common/pose.h"

namespace pcr {

double PathLength(const Trajectory& trajectory) {
  double length_m = 0;
  for (size_t i = 1; i < trajectory.size(); ++i)
    length_m += (trajectory[i].world_from_cam.translation() -
                 trajectory[i - 1].world_from_cam.translation())
                    .norm();
  return length_m;
}

}  // namespace pcr
