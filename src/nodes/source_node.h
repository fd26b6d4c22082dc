#pragma once
// The source stage: releases frames (all at once, or at their timestamps scaled by a rate like a
// camera), keeps released frames waiting for a free in-flight slot, drops the oldest waiting frame
// when the waiting room is full, and stamps each admitted frame with its ticket (contiguous seq,
// quality level and settings, whether the segmentation branch runs on it).
// Pure and thread-compatible: the graph's clock owns it; times are nanoseconds since the start
// of the run.
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <vector>

#include "nodes/frame_source.h"
#include "nodes/messages.h"
#include "nodes/quality.h"

namespace pcr::nodes {

struct SourceOptions {
  // false: every frame is released at time 0 (the pipeline takes them as fast as it can).
  // true: frame i is released at (t_ns[i] - t_ns[0]) * rate.
  bool paced = false;
  double rate = 1.0;  // >= 0; 1 = real time, 0.5 = twice as fast
  // Released frames waiting for an in-flight slot; when a release finds it full the oldest
  // waiting frame is dropped. 0 = unbounded (nothing is dropped).
  size_t waiting_capacity = 0;
  bool IsValid(std::string* why) const;
};

struct WaitingFrame {
  size_t entry = 0;        // index into the FrameSource vectors
  int64_t release_ns = 0;  // when it was released
};

class SourceNode {
 public:
  // Throws ConfigError for invalid options or source.
  SourceNode(const FrameSource& source, const SourceOptions& options);

  int64_t ReleaseTimeNs(size_t entry) const;
  // Release time of the next frame not yet released; nullopt when all are.
  std::optional<int64_t> NextReleaseNs() const;
  bool AllReleased() const { return next_entry_ >= frame_indices_.size(); }

  // Releases the frames due at now_ns (at most max_frames of them, oldest first) into the
  // waiting room; returns the frames dropped. A caller admitting frames releases one at a time,
  // so that a frame is dropped only when no in-flight slot was free for the one before it.
  std::vector<WaitingFrame> ReleaseDue(int64_t now_ns,
                                       size_t max_frames = std::numeric_limits<size_t>::max());

  bool HasWaiting() const { return !waiting_.empty(); }
  size_t num_waiting() const { return waiting_.size(); }

  // The ticket the oldest waiting frame gets when admitted now at this level and settings
  // (requires HasWaiting()). Low-cadence inference counts frames admitted since the level last
  // changed: with inference_every = n, the first of every n frames runs the segmenter.
  FrameTicket PeekTicket(QualityLevel level, const QualitySettings& settings) const;
  // Admits the oldest waiting frame with that ticket (from PeekTicket) and returns it.
  WaitingFrame Admit(const FrameTicket& ticket);

  int64_t admitted() const { return next_seq_; }
  size_t dropped() const { return dropped_; }

 private:
  std::vector<int64_t> frame_indices_, t_ns_;
  SourceOptions options_;
  size_t next_entry_ = 0;
  std::deque<WaitingFrame> waiting_;
  int64_t next_seq_ = 0;
  size_t dropped_ = 0;
  std::optional<QualityLevel> cadence_level_;
  int64_t cadence_count_ = 0;  // frames admitted at cadence_level_
};

}  // namespace pcr::nodes
