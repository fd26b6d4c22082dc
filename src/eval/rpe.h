#pragma once
// Relative pose error with evo's definitions (evo_rpe). For a pair (i, j) with reference poses
// Q and estimate poses P: E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j);
//   translation error ||t(E_ij)|| [m], rotation error angle(R(E_ij)) [deg].
// Pairs are chosen on the ESTIMATE trajectory, the aligned one (evo_rpe's default), or on the
// REFERENCE with pairs_from_reference (evo --pairs_from_reference); by frames they are the same.
// Both with evo's id_pairs_from_delta:
//   frames, consecutive (default, evo all_pairs=False): ids 0, d, 2d, ...; pairs (0,d), (d,2d), ...
//   frames, all pairs  (evo --all_pairs):               (i, i + d) for every i.
//   metres, consecutive (evo filter_pairs_by_path, all_pairs=False): the path length is
//     accumulated from pose 0; an id is recorded at the first pose where it reaches >= d, and the
//     accumulation restarts there. Pairs join consecutive ids, so each pair (i, j) has j = the
//     first pose after i whose path length from i is >= d, and the next pair starts at j. As in
//     evo, the first id is the first pose >= d from pose 0 (not pose 0 itself), so the stretch
//     before it is not scored.
//   metres, all pairs: for every i, the j > i whose path length from i is nearest to d (first
//     such j on ties), kept when within rel_tol * d of d (evo uses a bounded binary search for
//     the same target).
// Scale: evo_rpe -as aligns before computing RPE; rotation and translation of the alignment
// cancel in relative poses, only a sim3 scale changes them, so pass the aligned estimate.
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "eval/statistics.h"
#include "slam/common/pose.h"

namespace pcr::eval {

enum class DeltaUnit { kFrames, kMeters };
std::string_view ToString(DeltaUnit unit);                    // "f", "m"
bool ParseDeltaUnit(std::string_view text, DeltaUnit* unit);  // "f"/"frames", "m"/"meters"

// The largest RPE delta, in frames or metres.
inline constexpr double kMaxRpeDelta = 1e9;

struct RpeOptions {
  double delta = 1;  // frames (a whole number >= 1) or metres (> 0), at most kMaxRpeDelta
  DeltaUnit unit = DeltaUnit::kFrames;
  bool all_pairs = false;
  double rel_tol = 0.1;  // metres with all_pairs only: accepted |path - delta| <= rel_tol * delta
  bool pairs_from_reference = false;  // metres: pairs on the reference's path, not the estimate's
  // frames: pair the poses whose frame_index differ by delta, not the entries delta apart (a run
  // that dropped frames: its entries 3 and 4 may be frames 3 and 14). Not evo's.
  bool by_frame_index = false;

  bool IsValid(std::string* why) const;
};

using IndexPairs = std::vector<std::pair<size_t, size_t>>;

// Pairs (i, j), i < j, on `trajectory` (pairs_from_reference is not looked at). Throws
// std::invalid_argument on invalid options.
IndexPairs SelectRpePairs(const Trajectory& trajectory, const RpeOptions& options);

struct RpeResult {
  IndexPairs pairs;
  std::vector<double> trans_error_m;  // one per pair
  std::vector<double> rot_error_deg;  // one per pair
  ErrorStatistics trans_m;            // count 0 when no pair fits
  ErrorStatistics rot_deg;
};

// estimate[i] belongs to reference[i]; sizes must match (else std::invalid_argument).
RpeResult ComputeRpe(const Trajectory& reference, const Trajectory& estimate,
                     const RpeOptions& options);

}  // namespace pcr::eval
