// Temporal window (Eq. 4) and the decaying log-odds vote per track.
#include <gtest/gtest.h>

#include <cmath>

#include "slam/common/error.h"
#include "slam/dynamic/temporal_voting.h"

namespace pcr {
namespace {

const MotionEvidence kMoving{0.02, 1.0};
const MotionEvidence kStatic{0.98, 1.0};

TEST(FilterVoting, MovingTrackStaysVotedOutThroughMissingFrames) {
  TemporalVoting voting;
  const int64_t key = 7;
  EXPECT_FALSE(voting.Update(key, 0, &kMoving).dynamic);  // one frame is not enough
  EXPECT_TRUE(voting.Update(key, 1, &kMoving).dynamic);
  // Two frames without any observation: the vote decays but carries.
  const TrackVote gap1 = voting.Update(key, 2, nullptr);
  EXPECT_TRUE(gap1.dynamic);
  const TrackVote gap2 = voting.Update(key, 3, nullptr);
  EXPECT_TRUE(gap2.dynamic);
  EXPECT_LT(gap2.log_odds, gap1.log_odds);
  // Long without evidence it fades.
  EXPECT_FALSE(voting.Peek(key, 10).dynamic);
  EXPECT_GT(voting.Peek(key, 10).log_odds, 0.0);
  // The window average only holds observed frames within the last 3 frames.
  EXPECT_EQ(gap1.window_count, 2);
  EXPECT_NEAR(gap1.window_static_prob, 0.02, 1e-6);
  EXPECT_EQ(gap2.window_count, 1);
  const TrackVote gap3 = voting.Update(key, 4, nullptr);
  EXPECT_EQ(gap3.window_count, 0);
  EXPECT_EQ(gap3.window_static_prob, 0.5);
}

TEST(FilterVoting, SingleNoisyFrameDoesNotFlipAStaticTrack) {
  TemporalVoting voting;
  for (int f = 0; f < 5; ++f) voting.Update(1, f, &kStatic);
  const TrackVote spike = voting.Update(1, 5, &kMoving);
  EXPECT_FALSE(spike.dynamic);
  EXPECT_NEAR(spike.window_static_prob, (0.98 + 0.98 + 0.02) / 3.0, 1e-6);
  // A fresh track with one such frame is not voted out either.
  EXPECT_FALSE(voting.Update(2, 5, &kMoving).dynamic);
}

TEST(FilterVoting, StaticEvidenceCountsOnlyAsFarAsItIsObservable) {
  TemporalVoting voting;
  const MotionEvidence blind{0.98, 0.0};
  for (int f = 0; f < 5; ++f) voting.Update(1, f, &blind);
  EXPECT_EQ(voting.Peek(1, 4).log_odds, 0.0);  // could not have seen a motion: no evidence
  EXPECT_EQ(voting.Peek(1, 4).window_observability, 0.0);
  for (int f = 0; f < 5; ++f) voting.Update(2, f, &kStatic);
  EXPECT_LT(voting.Peek(2, 4).log_odds, -3.0);
  // Parked car that starts moving: the static history delays but does not prevent the vote.
  // (Bounded: a vote that never comes fails the checks below instead of hanging.)
  int frame = 5;
  while (frame < 20 && !voting.Update(2, frame, &kMoving).dynamic) ++frame;
  EXPECT_GT(frame, 6);
  EXPECT_LT(frame, 10);
}

TEST(FilterVoting, WindowObservabilityAddsInQuadrature) {
  TemporalVoting voting;
  const MotionEvidence weak{0.9, 0.4};
  voting.Update(3, 0, &weak);
  voting.Update(3, 1, &weak);
  const TrackVote v = voting.Update(3, 2, &weak);
  EXPECT_EQ(v.window_count, 3);
  EXPECT_NEAR(v.window_observability, std::sqrt(3.0) * 0.4, 1e-6);
  EXPECT_EQ(v.total_observations, 3);
  EXPECT_EQ(voting.Update(3, 3, &kStatic).window_observability, 1.0);
}

TEST(FilterVoting, StatesCarriedByValueAlongTracks) {
  // A state handed from keypoint to keypoint (as DynamicFilter does along LK tracks) behaves as
  // the keyed one; two keypoints continuing one track each get their own copy.
  const TemporalVoting voting;
  TrackState state;
  EXPECT_EQ(voting.Summarize(state, 0).log_odds, 0.0);
  voting.Advance(&state, 0, &kMoving);
  TrackState a = state, b = state;
  EXPECT_TRUE(voting.Advance(&a, 1, &kMoving).dynamic);
  EXPECT_FALSE(voting.Advance(&b, 1, &kStatic).dynamic);
  EXPECT_EQ(a.total_observations, 2);
  EXPECT_EQ(voting.Summarize(a, 1).window_count, 2);
  // The window keeps at most window_frames samples.
  for (int f = 2; f < 10; ++f) voting.Advance(&a, f, &kStatic);
  EXPECT_EQ(a.num_samples, voting.options().window_frames);
  EXPECT_NEAR(voting.Summarize(a, 9).window_static_prob, 0.98, 1e-6);
  EXPECT_THROW(voting.Advance(&a, 3, &kStatic), std::invalid_argument);
  TemporalVotingOptions too_long;
  too_long.window_frames = kMaxTemporalWindow + 1;
  std::string why;
  EXPECT_FALSE(too_long.IsValid(&why));
}

TEST(FilterVoting, InheritPruneAndOrder) {
  TemporalVoting voting;
  voting.Update(10, 0, &kMoving);
  voting.Update(10, 1, &kMoving);
  voting.Inherit(10, 20);  // the track became map point 20
  EXPECT_TRUE(voting.Contains(20));
  EXPECT_TRUE(voting.Peek(20, 1).dynamic);
  voting.Update(30, 1, &kStatic);
  voting.Inherit(10, 30);  // 30 has its own history: untouched
  EXPECT_FALSE(voting.Peek(30, 1).dynamic);
  EXPECT_THROW(voting.Update(10, 0, &kMoving), std::invalid_argument);
  EXPECT_EQ(voting.size(), 3u);
  voting.Prune(1 + voting.options().forget_after_frames);
  EXPECT_EQ(voting.size(), 3u);
  voting.Prune(2 + voting.options().forget_after_frames);
  EXPECT_EQ(voting.size(), 0u);
  TemporalVotingOptions bad;
  bad.decay = 0.0;
  EXPECT_THROW(TemporalVoting{bad}, ConfigError);
}

}  // namespace
}  // namespace pcr
