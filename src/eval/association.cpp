#include "eval/association.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <vector>

namespace pcr::eval {
namespace {

std::map<int64_t, size_t> IndexByFrame(const Trajectory& t, const char* which) {
  std::map<int64_t, size_t> by_frame;
  for (size_t i = 0; i < t.size(); ++i) {
    const int64_t f = t[i].frame_index;
    if (f < 0)
      throw std::invalid_argument(std::string(which) + " pose " + std::to_string(i) +
                                  " has no frame index");
    if (!by_frame.emplace(f, i).second)
      throw std::invalid_argument(std::string(which) + " repeats frame index " + std::to_string(f));
  }
  return by_frame;
}

void RequireIncreasing(const std::vector<int64_t>& stamps_ns, const char* which) {
  for (size_t i = 1; i < stamps_ns.size(); ++i)
    if (stamps_ns[i] <= stamps_ns[i - 1])
      throw std::invalid_argument(std::string(which) +
                                  " timestamps are not strictly increasing at pose " +
                                  std::to_string(i));
}

}  // namespace

AssociatedTrajectories AssociateByFrameIndex(const Trajectory& reference,
                                             const Trajectory& estimate) {
  const std::map<int64_t, size_t> ref_by_frame = IndexByFrame(reference, "ground truth");
  const std::map<int64_t, size_t> est_by_frame = IndexByFrame(estimate, "estimate");
  AssociatedTrajectories out;
  out.reference_count = reference.size();
  out.estimate_count = estimate.size();
  out.method = "frame_index";
  for (const auto& [frame, ref_i] : ref_by_frame) {
    const auto it = est_by_frame.find(frame);
    if (it == est_by_frame.end()) continue;
    out.reference.push_back(reference[ref_i]);
    out.estimate.push_back(estimate[it->second]);
  }
  return out;
}

bool TimeAssociationOptions::IsValid(std::string* why) const {
  // Bounded so that both fit int64 nanoseconds (1e9 s = 1e18 ns; 9.2e18 is the limit).
  if (!std::isfinite(max_diff_s) || max_diff_s < 0 || max_diff_s > kMaxTimeAssociationS) {
    if (why)
      *why =
          fmt::format("max_diff_s must be in [0, {}] s, got {}", kMaxTimeAssociationS, max_diff_s);
    return false;
  }
  if (!std::isfinite(offset_s) || std::abs(offset_s) > kMaxTimeAssociationS) {
    if (why)
      *why = fmt::format(
          "offset_s must be finite and at most {} s in magnitude, "
          "got {}",
          kMaxTimeAssociationS, offset_s);
    return false;
  }
  return true;
}

AssociatedTrajectories AssociateByTimestamp(const Trajectory& reference, const Trajectory& estimate,
                                            const TimeAssociationOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  const int64_t offset_ns = SecondsToNs(options.offset_s);
  const int64_t max_diff_ns = SecondsToNs(options.max_diff_s);
  std::vector<int64_t> ref_ns, est_ns;
  for (const StampedPose& p : reference) ref_ns.push_back(p.t_ns);
  for (const StampedPose& p : estimate) {
    int64_t t_ns = 0;
    if (__builtin_add_overflow(p.t_ns, offset_ns, &t_ns))
      throw std::invalid_argument("estimate stamp " + std::to_string(p.t_ns) + " ns plus the " +
                                  "time offset is beyond the int64 nanosecond range");
    est_ns.push_back(t_ns);
  }
  RequireIncreasing(ref_ns, "ground truth");
  RequireIncreasing(est_ns, "estimate");

  // As evo: the shorter trajectory looks up its nearest partner in the longer one.
  const bool estimate_longer = est_ns.size() > ref_ns.size();
  const std::vector<int64_t>& short_ns = estimate_longer ? ref_ns : est_ns;
  const std::vector<int64_t>& long_ns = estimate_longer ? est_ns : ref_ns;

  constexpr size_t kNone = static_cast<size_t>(-1);
  std::vector<size_t> partner(short_ns.size(), kNone);    // short index -> long index
  std::vector<size_t> claimed_by(long_ns.size(), kNone);  // long index -> short index
  // |a - b| of two int64 stamps always fits a uint64 (a signed difference can overflow).
  auto distance = [&](size_t s, size_t l) {
    const uint64_t a = static_cast<uint64_t>(short_ns[s]), b = static_cast<uint64_t>(long_ns[l]);
    return short_ns[s] >= long_ns[l] ? a - b : b - a;
  };
  const uint64_t max_diff = static_cast<uint64_t>(max_diff_ns);
  for (size_t s = 0; s < short_ns.size(); ++s) {
    if (long_ns.empty()) break;
    const auto it = std::lower_bound(long_ns.begin(), long_ns.end(), short_ns[s]);
    size_t l = static_cast<size_t>(it - long_ns.begin());
    if (l == long_ns.size() || (l > 0 && distance(s, l - 1) <= distance(s, l))) l = l - 1;
    if (distance(s, l) > max_diff) continue;
    const size_t rival = claimed_by[l];
    if (rival != kNone) {
      if (distance(rival, l) <= distance(s, l)) continue;  // the earlier, closer claim stays
      partner[rival] = kNone;
    }
    claimed_by[l] = s;
    partner[s] = l;
  }

  AssociatedTrajectories out;
  out.reference_count = reference.size();
  out.estimate_count = estimate.size();
  out.method = "timestamp";
  for (size_t s = 0; s < short_ns.size(); ++s) {
    if (partner[s] == kNone) continue;
    const size_t ref_i = estimate_longer ? s : partner[s];
    const size_t est_i = estimate_longer ? partner[s] : s;
    out.reference.push_back(reference[ref_i]);
    out.estimate.push_back(estimate[est_i]);
  }
  return out;
}

}  // namespace pcr::eval
