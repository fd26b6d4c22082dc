#include "slam/dynamic/temporal_voting.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/validation.h"

namespace pcr {
bool TemporalVotingOptions::IsValid(std::string* why) const {
  if (window_frames < 1 || window_frames > kMaxTemporalWindow) {
    return Fail(why, "window_frames must be in [1, kMaxTemporalWindow]");
  }
  if (!(decay > 0.0 && decay <= 1.0)) return Fail(why, "decay must be in (0, 1]");
  if (!(max_evidence > 0.0)) return Fail(why, "max_evidence must be > 0");
  if (!(max_log_odds >= max_evidence)) return Fail(why, "max_log_odds must be >= max_evidence");
  if (!(dynamic_threshold > 0.0 && dynamic_threshold <= max_log_odds)) {
    return Fail(why, "dynamic_threshold must be in (0, max_log_odds]");
  }
  if (forget_after_frames < 1) return Fail(why, "forget_after_frames must be >= 1");
  return true;
}

TemporalVoting::TemporalVoting(const TemporalVotingOptions& options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("TemporalVotingOptions: " + why);
}

TrackVote TemporalVoting::Summarize(const TrackState& state, int64_t frame_index) const {
  TrackVote vote;
  if (!state.started) return vote;
  const int64_t elapsed = std::max<int64_t>(0, frame_index - state.last_frame);
  vote.log_odds = state.log_odds * std::pow(options_.decay, static_cast<double>(elapsed));
  vote.dynamic = vote.log_odds >= options_.dynamic_threshold;
  vote.total_observations = state.total_observations;
  double sum = 0.0, sum_obs_sq = 0.0;
  for (int k = 0; k < state.num_samples; ++k) {
    const TrackState::Sample& s = state.samples[k];
    if (frame_index - s.frame_index >= options_.window_frames) continue;
    sum += s.static_prob;
    sum_obs_sq += static_cast<double>(s.observability) * s.observability;
    ++vote.window_count;
  }
  if (vote.window_count > 0) vote.window_static_prob = sum / vote.window_count;
  vote.window_observability = std::min(1.0, std::sqrt(sum_obs_sq));
  return vote;
}

TrackVote TemporalVoting::Advance(TrackState* state, int64_t frame_index,
                                  const MotionEvidence* evidence) const {
  if (!state->started) {
    *state = TrackState{};
    state->started = true;
    state->last_frame = frame_index;
  } else if (frame_index < state->last_frame) {
    throw std::invalid_argument("TemporalVoting: frame index went backwards for a track");
  }
  const int64_t elapsed = frame_index - state->last_frame;
  if (elapsed > 0) state->log_odds *= std::pow(options_.decay, static_cast<double>(elapsed));
  state->last_frame = frame_index;
  if (evidence) {
    const double p = std::clamp(evidence->static_prob, 1e-4, 1.0 - 1e-4);
    double e = std::clamp(std::log((1.0 - p) / p), -options_.max_evidence, options_.max_evidence);
    if (e < 0.0) e *= std::clamp(evidence->observability, 0.0, 1.0);
    state->log_odds =
        std::clamp(state->log_odds + e, -options_.max_log_odds, options_.max_log_odds);
    if (state->num_samples == options_.window_frames) {
      for (int k = 1; k < state->num_samples; ++k) state->samples[k - 1] = state->samples[k];
      --state->num_samples;
    }
    state->samples[state->num_samples++] = {
        frame_index, static_cast<float>(std::clamp(evidence->static_prob, 0.0, 1.0)),
        static_cast<float>(std::clamp(evidence->observability, 0.0, 1.0))};
    ++state->total_observations;
  }
  return Summarize(*state, frame_index);
}

TrackVote TemporalVoting::Update(int64_t key, int64_t frame_index, const MotionEvidence* evidence) {
  return Advance(&tracks_[key], frame_index, evidence);
}

TrackVote TemporalVoting::Peek(int64_t key, int64_t frame_index) const {
  const auto it = tracks_.find(key);
  if (it == tracks_.end()) return {};
  return Summarize(it->second, frame_index);
}

const TrackState* TemporalVoting::Find(int64_t key) const {
  const auto it = tracks_.find(key);
  return it == tracks_.end() ? nullptr : &it->second;
}

void TemporalVoting::Inherit(int64_t from, int64_t to) {
  if (from == to || tracks_.count(to) > 0) return;
  const auto it = tracks_.find(from);
  if (it == tracks_.end()) return;
  const TrackState copy = it->second;
  tracks_.emplace(to, copy);
}

void TemporalVoting::Prune(int64_t frame_index) {
  for (auto it = tracks_.begin(); it != tracks_.end();) {
    if (frame_index - it->second.last_frame > options_.forget_after_frames) {
      it = tracks_.erase(it);
    } else {
      ++it;
    }
  }
}

}  // namespace pcr
