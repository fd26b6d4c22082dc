#include "nodes/frame_source.h"

#include <algorithm>

namespace pcr::nodes {

double FrameSource::NominalPeriodMs() const {
  if (t_ns.size() < 2) return 0.0;
  std::vector<int64_t> dt;
  dt.reserve(t_ns.size() - 1);
  for (size_t i = 1; i < t_ns.size(); ++i) dt.push_back(t_ns[i] - t_ns[i - 1]);
  std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
  return static_cast<double>(dt[dt.size() / 2]) * 1e-6;
}

bool FrameSource::IsValid(std::string* why, bool stereo) const {
  auto fail = [why](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (frame_indices.empty()) return fail("no frames");
  if (t_ns.size() != frame_indices.size()) return fail("t_ns and frame_indices differ in size");
  for (size_t i = 1; i < t_ns.size(); ++i) {
    if (t_ns[i] <= t_ns[i - 1]) return fail("timestamps must be strictly increasing");
  }
  if (!load_left || (stereo && !load_right)) return fail("image loaders must be set");
  std::string inner;
  if (!rig.IsValid(&inner)) return fail("rig: " + inner);
  if (stereo && !rig.IsStereo()) return fail("stereo runs need a stereo rig");
  return true;
}

}  // namespace pcr::nodes
