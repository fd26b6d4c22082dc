#pragma once
// Small rotation helpers shared by the metrics.
#include <Eigen/Core>
#include <numbers>

namespace pcr::eval {

inline constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// Angle of the rotation (angle-axis magnitude) in [0, pi], accurate for small and large angles
// (atan2 of the skew part against the trace part; matches evo's so3_log angle).
double RotationAngleRad(const Eigen::Matrix3d& rotation);

}  // namespace pcr::eval
