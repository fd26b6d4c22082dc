#include "eval/rpe.h"

#include <fmt/format.h>

#include <cmath>
#include <map>
#include <stdexcept>

#include "eval/pose_math.h"

namespace pcr::eval {
namespace {

double Step(const Trajectory& t, size_t i) {
  return (t[i].world_from_cam.translation() - t[i - 1].world_from_cam.translation()).norm();
}

IndexPairs ConsecutivePairs(const std::vector<size_t>& ids) {
  IndexPairs pairs;
  for (size_t k = 1; k < ids.size(); ++k) pairs.emplace_back(ids[k - 1], ids[k]);
  return pairs;
}

IndexPairs PairsByFrames(size_t n, size_t delta, bool all_pairs) {
  if (delta == 0 || delta >= n) return {};
  if (all_pairs) {
    IndexPairs pairs;
    for (size_t i = 0; i + delta < n; ++i) pairs.emplace_back(i, i + delta);
    return pairs;
  }
  std::vector<size_t> ids;
  for (size_t i = 0; i < n; i += delta) ids.push_back(i);
  return ConsecutivePairs(ids);
}

// Pairs (i, j) with frame_index[j] = frame_index[i] + delta; consecutive ones from the first
// pose's frame on (frames first, first + delta, ...), all pairs from every pose.
IndexPairs PairsByFrameIndex(const Trajectory& t, int64_t delta, bool all_pairs) {
  std::map<int64_t, size_t> entry_of;
  for (size_t i = 0; i < t.size(); ++i) entry_of.emplace(t[i].frame_index, i);
  IndexPairs pairs;
  if (t.empty()) return pairs;
  const int64_t first = t.front().frame_index;
  for (size_t i = 0; i < t.size(); ++i) {
    const int64_t f = t[i].frame_index;
    if (!all_pairs && (f - first) % delta != 0) continue;
    const auto it = entry_of.find(f + delta);
    if (it != entry_of.end() && it->second > i) pairs.emplace_back(i, it->second);
  }
  return pairs;
}

IndexPairs PairsByPath(const Trajectory& reference, double delta_m, bool all_pairs, double tol_m) {
  const size_t n = reference.size();
  if (n == 0) return {};
  if (!all_pairs) {
    std::vector<size_t> ids;
    double path_m = 0;
    for (size_t i = 0; i < n; ++i) {
      if (i > 0) path_m += Step(reference, i);
      if (path_m >= delta_m) {
        ids.push_back(i);
        path_m = 0;
      }
    }
    return ConsecutivePairs(ids);
  }
  std::vector<double> cumulative_m(n, 0.0);
  for (size_t i = 1; i < n; ++i) cumulative_m[i] = cumulative_m[i - 1] + Step(reference, i);
  IndexPairs pairs;
  for (size_t i = 0; i + 1 < n; ++i) {
    size_t best = n;
    double best_residual = 0;
    for (size_t j = i + 1; j < n; ++j) {
      const double residual = std::abs(cumulative_m[j] - cumulative_m[i] - delta_m);
      if (best == n || residual < best_residual) {
        best = j;
        best_residual = residual;
      }
      if (cumulative_m[j] - cumulative_m[i] > delta_m) break;  // residuals only grow from here
    }
    if (best < n && best_residual <= tol_m) pairs.emplace_back(i, best);
  }
  return pairs;
}

}  // namespace

std::string_view ToString(DeltaUnit unit) { return unit == DeltaUnit::kFrames ? "f" : "m"; }

bool ParseDeltaUnit(std::string_view text, DeltaUnit* unit) {
  if (text == "f" || text == "frames") {
    *unit = DeltaUnit::kFrames;
    return true;
  }
  if (text == "m" || text == "meters" || text == "metres") {
    *unit = DeltaUnit::kMeters;
    return true;
  }
  return false;
}

bool RpeOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  // Numbers as fmt's shortest exact text: "1e+300", "2.0000001", never 300 digits.
  if (!std::isfinite(delta) || delta <= 0)
    return fail(fmt::format("delta must be positive, got {}", delta));
  if (delta > kMaxRpeDelta)  // beyond it a frame count would not survive the cast to size_t
    return fail(fmt::format("delta must be at most {}, got {}", kMaxRpeDelta, delta));
  if (unit == DeltaUnit::kFrames && delta != std::floor(delta))
    return fail(fmt::format("delta in frames must be a whole number, got {}", delta));
  if (!std::isfinite(rel_tol) || rel_tol < 0)
    return fail(fmt::format("rel_tol must be >= 0, got {}", rel_tol));
  return true;
}

IndexPairs SelectRpePairs(const Trajectory& trajectory, const RpeOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  if (options.unit == DeltaUnit::kFrames && options.by_frame_index)
    return PairsByFrameIndex(trajectory, static_cast<int64_t>(options.delta), options.all_pairs);
  if (options.unit == DeltaUnit::kFrames)
    return PairsByFrames(trajectory.size(), static_cast<size_t>(options.delta), options.all_pairs);
  return PairsByPath(trajectory, options.delta, options.all_pairs, options.rel_tol * options.delta);
}

RpeResult ComputeRpe(const Trajectory& reference, const Trajectory& estimate,
                     const RpeOptions& options) {
  if (reference.size() != estimate.size())
    throw std::invalid_argument("ComputeRpe: " + std::to_string(reference.size()) +
                                " reference poses but " + std::to_string(estimate.size()) +
                                " estimate poses");
  RpeResult r;
  r.pairs = SelectRpePairs(options.pairs_from_reference ? reference : estimate, options);
  for (const auto& [i, j] : r.pairs) {
    const SE3 reference_delta = reference[i].world_from_cam.inverse() * reference[j].world_from_cam;
    const SE3 estimate_delta = estimate[i].world_from_cam.inverse() * estimate[j].world_from_cam;
    const SE3 error = reference_delta.inverse() * estimate_delta;
    r.trans_error_m.push_back(error.translation().norm());
    r.rot_error_deg.push_back(RotationAngleRad(error.linear()) * kDegPerRad);
  }
  r.trans_m = ComputeStatistics(r.trans_error_m);
  r.rot_deg = ComputeStatistics(r.rot_error_deg);
  return r;
}

}  // namespace pcr::eval
