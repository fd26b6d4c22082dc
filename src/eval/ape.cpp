#include "eval/ape.h"

#include <stdexcept>
#include <string>

#include "eval/pose_math.h"

namespace pcr::eval {

ApeResult ComputeApe(const Trajectory& reference, const Trajectory& estimate) {
  if (reference.size() != estimate.size())
    throw std::invalid_argument("ComputeApe: " + std::to_string(reference.size()) +
                                " reference poses but " + std::to_string(estimate.size()) +
                                " estimate poses");
  ApeResult r;
  r.trans_error_m.reserve(reference.size());
  r.rot_error_deg.reserve(reference.size());
  for (size_t i = 0; i < reference.size(); ++i) {
    const SE3 error = reference[i].world_from_cam.inverse() * estimate[i].world_from_cam;
    r.trans_error_m.push_back(error.translation().norm());
    r.rot_error_deg.push_back(RotationAngleRad(error.linear()) * kDegPerRad);
  }
  r.trans_m = ComputeStatistics(r.trans_error_m);
  r.rot_deg = ComputeStatistics(r.rot_error_deg);
  return r;
}

}  // namespace pcr::eval
