#include "nodes/source_node.h"

#include <algorithm>
#include <cmath>

#include "slam/common/error.h"

namespace pcr::nodes {

bool SourceOptions::IsValid(std::string* why) const {
  if (!(std::isfinite(rate) && rate >= 0)) {
    if (why) *why = "rate must be finite and >= 0";
    return false;
  }
  return true;
}

SourceNode::SourceNode(const FrameSource& source, const SourceOptions& options)
    : frame_indices_(source.frame_indices), t_ns_(source.t_ns), options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("SourceOptions: " + why);
  if (t_ns_.size() != frame_indices_.size())
    throw ConfigError("FrameSource: t_ns and frame_indices differ in size");
}

int64_t SourceNode::ReleaseTimeNs(size_t entry) const {
  if (!options_.paced) return 0;
  const double offset = static_cast<double>(t_ns_[entry] - t_ns_.front()) * options_.rate;
  return static_cast<int64_t>(std::llround(offset));
}

std::optional<int64_t> SourceNode::NextReleaseNs() const {
  if (AllReleased()) return std::nullopt;
  return ReleaseTimeNs(next_entry_);
}

std::vector<WaitingFrame> SourceNode::ReleaseDue(int64_t now_ns, size_t max_frames) {
  std::vector<WaitingFrame> dropped;
  for (size_t released = 0;
       released < max_frames && !AllReleased() && ReleaseTimeNs(next_entry_) <= now_ns;
       ++released) {
    waiting_.push_back({next_entry_, options_.paced ? ReleaseTimeNs(next_entry_) : now_ns});
    ++next_entry_;
    if (options_.waiting_capacity > 0 && waiting_.size() > options_.waiting_capacity) {
      dropped.push_back(waiting_.front());
      waiting_.pop_front();
      ++dropped_;
    }
  }
  return dropped;
}

FrameTicket SourceNode::PeekTicket(QualityLevel level, const QualitySettings& settings) const {
  const WaitingFrame& w = waiting_.front();
  FrameTicket t;
  t.seq = next_seq_;
  t.frame_index = frame_indices_[w.entry];
  t.t_ns = t_ns_[w.entry];
  t.quality = level;
  t.settings = settings;
  const int64_t count = cadence_level_ == level ? cadence_count_ : 0;
  t.run_inference = count % std::max(1, settings.inference_every) == 0;
  return t;
}

WaitingFrame SourceNode::Admit(const FrameTicket& ticket) {
  const WaitingFrame w = waiting_.front();
  waiting_.pop_front();
  ++next_seq_;
  if (cadence_level_ != ticket.quality) {
    cadence_level_ = ticket.quality;
    cadence_count_ = 0;
  }
  ++cadence_count_;
  return w;
}

}  // namespace pcr::nodes
