#pragma once
// Small rotation helpers shared by the metrics.
#include <Eigen/Core>
#include <numbers>

#include "slam/common/lie.h"

namespace pcr::eval {

inline constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// Angle of the rotation (angle-axis magnitude) in [0, pi], accurate for small and large angles
// (atan2 of the skew part against the trace part; matches evo's so3_log angle): the one of
// slam/common/lie.h.
using pcr::RotationAngleRad;

}  // namespace pcr::eval
