#pragma once
// KITTI odometry devkit metrics (evaluate_odometry.cpp of the benchmark), on associated poses:
//   dist[k] = path length of the ground truth from pose 0 to pose k;
//   for first = 0, step, 2 step, ... and each length L: last = the first pose with
//     dist[last] > dist[first] + L (segment skipped when none);
//   delta_gt = gt[first]^-1 gt[last], delta_est = est[first]^-1 est[last],
//   E = delta_est^-1 delta_gt; r_err = acos(clamp((trace(R_E) - 1) / 2)) / L [rad/m],
//   t_err = ||t_E|| / L [1/m].
// t_rel = 100 * mean(t_err) [%], r_rel = 100 * mean(r_err) in degrees [deg/100 m], the mean
// taken over all segments of all lengths, as the devkit's summary does.
#include <cstddef>
#include <limits>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "slam/common/pose.h"

namespace pcr::eval {

struct KittiMetricsOptions {
  // Distinct positive lengths in metres (a repeated one would count its segments twice).
  std::vector<double> lengths_m = {100, 200, 300, 400, 500, 600, 700, 800};
  int step_frames = 10;         // first frames 0, step, 2 step, ...
  double frame_period_s = 0.1;  // for the devkit's segment speed only (10 Hz)

  bool IsValid(std::string* why) const;
};

struct KittiSegmentError {
  size_t first = 0;  // associated pose indices
  size_t last = 0;
  double length_m = 0;
  double r_err_rad_per_m = 0;
  double t_err_per_m = 0;  // metres of error per metre travelled
  double speed_mps = 0;    // length / (frame_period * (last - first + 1)), as the devkit
};

struct KittiLengthSummary {
  double length_m = 0;
  size_t count = 0;
  double t_rel_percent = std::numeric_limits<double>::quiet_NaN();
  double r_rel_deg_per_100m = std::numeric_limits<double>::quiet_NaN();
};

struct KittiMetrics {
  std::vector<KittiSegmentError> segments;
  std::vector<KittiLengthSummary> per_length;  // one per option length, in option order
  double t_rel_percent = std::numeric_limits<double>::quiet_NaN();       // NaN: no segment
  double r_rel_deg_per_100m = std::numeric_limits<double>::quiet_NaN();  // NaN: no segment

  bool HasSegments() const { return !segments.empty(); }
};

// reference[i] and estimate[i] associated (sizes must match, else std::invalid_argument);
// invalid options throw std::invalid_argument.
KittiMetrics ComputeKittiMetrics(const Trajectory& reference, const Trajectory& estimate,
                                 const KittiMetricsOptions& options);

nlohmann::json ToJson(const KittiMetrics& metrics);

}  // namespace pcr::eval
