#include "graph/mask_board.h"

#include <cmath>
#include <vector>

#include "nodes/segment_node.h"

namespace pcr::graph {
namespace {

constexpr size_t kRecentResults = 8;

}  // namespace

MaskBoard::MaskBoard(double deadline_ms, Emit emit, std::function<void()> wake, bool wait_for_first)
    : deadline_ms_(deadline_ms),
      wait_for_first_(wait_for_first),
      emit_(std::move(emit)),
      wake_(std::move(wake)) {}

nodes::SegmentationPtr MaskBoard::WithFallback(const nodes::SegmentationMsg& msg) const {
  auto out = std::make_shared<nodes::SegmentationMsg>(msg);
  for (auto it = recent_.rbegin(); it != recent_.rend(); ++it) {
    if ((*it)->ticket.seq < msg.ticket.seq) {
      out->fallback = (*it)->segmentation;
      out->fallback_seq = (*it)->ticket.seq;
      break;
    }
  }
  return out;
}

nodes::SegmentationPtr MaskBoard::EmitLate(Entry& e) {
  e.emitted = true;
  ++late_;
  return WithFallback(*nodes::SegmentNode::NotRun(e.ticket, nodes::SegmentationOutcome::kLate));
}

nodes::SegmentationPtr MaskBoard::StartWait(Entry& e, bool* new_deadline) {
  if (e.wait_ms == 0) return EmitLate(e);
  e.deadline_ns = e.features_ns + std::llround(e.wait_ms * 1e6);
  *new_deadline = true;
  return nullptr;
}

void MaskBoard::EraseIfDone(std::map<int64_t, Entry>::iterator it) {
  if (it->second.emitted && it->second.features_ready && it->second.result_done) entries_.erase(it);
}

void MaskBoard::OnSegmentation(const nodes::SegmentationPtr& msg) {
  std::vector<nodes::SegmentationPtr> out;
  bool new_deadline = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const int64_t seq = msg->ticket.seq;
    auto it = entries_.try_emplace(seq).first;
    it->second.ticket = msg->ticket;
    it->second.result_done = true;
    const bool fresh = msg->outcome == nodes::SegmentationOutcome::kFresh;
    if (fresh) {
      auto pos = recent_.begin();
      while (pos != recent_.end() && (*pos)->ticket.seq < seq) ++pos;
      recent_.insert(pos, msg);
      while (recent_.size() > kRecentResults) recent_.pop_front();
    }
    if (it->second.emitted) {
      if (fresh) ++late_results_;
    } else {
      out.push_back(fresh ? msg : WithFallback(*msg));
      it->second.emitted = true;
    }
    EraseIfDone(it);
    if (fresh && !any_fresh_) {
      any_fresh_ = true;
      // The frames that waited for a first mask get their deadlines now.
      for (auto e = entries_.begin(); e != entries_.end();) {
        auto next = std::next(e);
        Entry& entry = e->second;
        if (entry.awaiting_first && !entry.emitted) {
          entry.awaiting_first = false;
          if (nodes::SegmentationPtr late = StartWait(entry, &new_deadline)) {
            out.push_back(std::move(late));
            EraseIfDone(e);
          }
        }
        e = next;
      }
    }
  }
  for (const auto& m : out) emit_(m);
  if (new_deadline && wake_) wake_();
}

void MaskBoard::OnFeaturesReady(const nodes::FrameTicket& ticket, int64_t now_ns) {
  nodes::SegmentationPtr out;
  bool new_deadline = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = entries_.try_emplace(ticket.seq).first;
    it->second.ticket = ticket;
    it->second.features_ready = true;
    const double wait_ms = deadline_ms_ >= 0 && ticket.settings.mask_wait_ms >= 0
                               ? ticket.settings.mask_wait_ms
                               : deadline_ms_;
    it->second.features_ns = now_ns;
    it->second.wait_ms = wait_ms;
    if (!it->second.emitted && wait_ms >= 0) {
      if (wait_for_first_ && !any_fresh_) {
        it->second.awaiting_first = true;  // nothing to carry to it yet: wait for its own result
      } else {
        out = StartWait(it->second, &new_deadline);
      }
    }
    EraseIfDone(it);
  }
  if (out) emit_(out);
  if (new_deadline && wake_) wake_();
}

void MaskBoard::ExpireDue(int64_t now_ns) {
  std::vector<nodes::SegmentationPtr> out;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = entries_.begin(); it != entries_.end();) {
      auto next = std::next(it);
      Entry& e = it->second;
      if (!e.emitted && e.features_ready && e.deadline_ns >= 0 && e.deadline_ns <= now_ns) {
        out.push_back(EmitLate(e));
        EraseIfDone(it);
      }
      it = next;
    }
  }
  for (const auto& msg : out) emit_(msg);
}

std::optional<int64_t> MaskBoard::NextDeadlineNs() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::optional<int64_t> next;
  for (const auto& [seq, e] : entries_) {
    if (!e.emitted && e.features_ready && e.deadline_ns >= 0 && (!next || e.deadline_ns < *next))
      next = e.deadline_ns;
  }
  return next;
}

size_t MaskBoard::late() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return late_;
}

size_t MaskBoard::late_results() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return late_results_;
}

}  // namespace pcr::graph
