#include "eval/pose_math.h"

#include <cmath>

namespace pcr::eval {

double RotationAngleRad(const Eigen::Matrix3d& r) {
  // For R = exp(theta [a]x): trace(R) = 1 + 2 cos(theta), vee(R - R^T) = 2 sin(theta) a.
  const Eigen::Vector3d skew(r(2, 1) - r(1, 2), r(0, 2) - r(2, 0), r(1, 0) - r(0, 1));
  const double sin_part = 0.5 * skew.norm();
  const double cos_part = 0.5 * (r.trace() - 1.0);
  return std::atan2(sin_part, cos_part);
}

}  // namespace pcr::eval
