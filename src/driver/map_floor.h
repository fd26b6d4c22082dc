#pragma once
// What a map's own observations allow: its keyframes' SE(3) ATE against the ground truth, and
// the same after a global bundle adjustment run to convergence (LoopCloser's global BA with the
// run's loop options, more iterations and a tighter tolerance) from two starts: the map's own
// estimate, and the ground truth (every keyframe moved to its true pose, expressed in the map's
// world through its first keyframe, its points carried along with their keyframes as in a loop
// correction). Started at the truth, the solve ends at the maximum-likelihood estimate of the
// map's observations and associations nearest to it: the error they leave to any back end, a
// loop correction included. For benchmarks and tests (bench_loop --floor); needs ground truth
// whose indices are the keyframes' frame indices (keyframe ids, for a run from frame 0).
#include <limits>
#include <vector>

#include "slam/common/pose.h"
#include "slam/loop/loop_closer.h"
#include "slam/map/map.h"

namespace pcr::driver {

struct MapFloorOptions {
  int iterations = 100;
  double function_tolerance = 1e-10;
};

// Mean residual of a map's keyframe observations at one ORB pyramid level: observed minus
// projected, in level-0 pixels, over the observations within BA's chi-square gate
// (BundleAdjustmentOptions' chi2_mono / chi2_stereo; the points in front of their camera).
// radial_u, radial_v: the horizontal and vertical residual signed away from the principal point
// (negative: the keypoints lie nearer the image's centre than their points project). disparity:
// observed minus predicted disparity over the stereo observations. Noise averages out of these
// means; what stays is a systematic part of the observations that no back end removes.
struct LevelResidual {
  int level = 0;
  int observations = 0, stereo = 0;
  double radial_u_px = 0, radial_v_px = 0, disparity_px = 0;
};

// Per pyramid level that holds an observation, in level order.
std::vector<LevelResidual> ResidualsByLevel(const Map& map);

struct MapFloor {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  int keyframes = 0;
  double map_m = kNaN;         // the map's keyframes as they are
  double converged_m = kNaN;   // after the solve from the map's estimate
  double start_m = kNaN;       // the keyframes moved to the truth, before the solve (~0)
  double from_truth_m = kNaN;  // after the solve from the truth
  double solve_s = 0;          // both solves
  // ResidualsByLevel of the map after the solve from its own estimate.
  std::vector<LevelResidual> converged_residuals;
};

// SE(3)-aligned RMSE of the map's keyframe positions against truth (NaN when fewer than 3
// keyframes are associated).
double KeyframeAte(const Map& map, const Trajectory& truth);

// Throws std::out_of_range when a keyframe's frame index is outside truth, ConfigError for
// invalid options.
MapFloor MapEstimateFloor(const Map& map, const Trajectory& truth,
                          const LoopClosingOptions& loop_options,
                          const MapFloorOptions& options = {});

}  // namespace pcr::driver
