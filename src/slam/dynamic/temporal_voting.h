#pragma once
// Per-track temporal evidence: the window average of the per-frame static probability (paper
// Eq. 4, averaged over the last window_frames frames that observed the track) and a decaying
// log-odds vote for "moving". Each frame that observes a track adds
// e = clamp(log((1 - p) / p), -max_evidence, max_evidence), where p is that frame's static
// probability; evidence for "static" (e < 0) only counts as far as the test could have seen a
// motion (times the observability). Between updates the vote decays by `decay` per frame, so a
// moving object stays voted out through a frame with no mask and no observation, while a single
// noisy frame does not reach the threshold. A parked car (dynamic class, no motion) gathers
// static evidence and is never voted out: the vote knows nothing about classes.
//
// States are plain values (TrackState): the keyed table holds them per map point; DynamicFilter
// also carries them per keypoint along LK tracks. Thread-compatible: one caller at a time.
#include <array>
#include <cstdint>
#include <string>
#include <unordered_map>

namespace pcr {

inline constexpr int kMaxTemporalWindow = 8;

struct TemporalVotingOptions {
  int window_frames = 3;           // Eq. 4 window (frames), at most kMaxTemporalWindow
  double decay = 0.9;              // log-odds factor per elapsed frame, in (0, 1]
  double max_evidence = 2.0;       // |log-odds| one frame can add
  double max_log_odds = 8.0;       // the vote is clamped to [-max, max]
  double dynamic_threshold = 2.2;  // log-odds at or above this: moving
  int forget_after_frames = 30;    // keyed tracks not updated for longer are dropped by Prune()
  bool IsValid(std::string* why) const;
};

// One frame's motion observation of a track.
struct MotionEvidence {
  double static_prob = 0.5;    // in [0, 1]
  double observability = 1.0;  // in [0, 1]
};

// The temporal state of one track: a plain value, so that it can live in the keyed table or be
// carried by the caller (e.g. per keypoint from one frame to the next along LK tracks).
struct TrackState {
  struct Sample {
    int64_t frame_index = 0;
    float static_prob = 0.5f;
    float observability = 0.0f;
  };
  bool started = false;
  double log_odds = 0.0;
  int64_t last_frame = 0;
  int total_observations = 0;
  int num_samples = 0;  // the last num_samples observations, oldest first
  std::array<Sample, kMaxTemporalWindow> samples{};
};

struct TrackVote {
  double log_odds = 0.0;            // > 0: evidence for "moving"
  bool dynamic = false;             // log_odds >= dynamic_threshold
  int window_count = 0;             // observations inside the window (0: no temporal M)
  double window_static_prob = 0.5;  // Eq. 4 mean over the window (0.5 when window_count == 0)
  // Combined over the window: min(1, sqrt(sum of squares)), as independent frames' signal-to-
  // noise ratios add in quadrature (each frame has its own stereo depth noise).
  double window_observability = 0.0;
  int total_observations = 0;
};

class TemporalVoting {
 public:
  explicit TemporalVoting(const TemporalVotingOptions& options = {});  // ConfigError if invalid

  // Advances a state to frame_index with that frame's evidence (null: not observed, the vote
  // only decays) and returns the vote. Frames must not decrease (std::invalid_argument); a second
  // update in the same frame adds its evidence undecayed.
  TrackVote Advance(TrackState* state, int64_t frame_index, const MotionEvidence* evidence) const;
  // The vote of a state at frame_index (decayed to that frame), without changing it.
  TrackVote Summarize(const TrackState& state, int64_t frame_index) const;

  // Keyed table (e.g. map-point ids): Advance on the key's state.
  TrackVote Update(int64_t key, int64_t frame_index, const MotionEvidence* evidence);
  // Vote of key at frame_index without changing it (zero if unknown).
  TrackVote Peek(int64_t key, int64_t frame_index) const;
  bool Contains(int64_t key) const { return tracks_.count(key) > 0; }
  const TrackState* Find(int64_t key) const;
  void Store(int64_t key, const TrackState& state) { tracks_[key] = state; }
  // Copies from's history to `to` when `to` has none (a track that became a map point).
  void Inherit(int64_t from, int64_t to);
  // Drops keys last updated more than forget_after_frames before frame_index.
  void Prune(int64_t frame_index);
  void Clear() { tracks_.clear(); }
  size_t size() const { return tracks_.size(); }
  const TemporalVotingOptions& options() const { return options_; }

 private:
  TemporalVotingOptions options_;
  std::unordered_map<int64_t, TrackState> tracks_;
};

}  // namespace pcr
