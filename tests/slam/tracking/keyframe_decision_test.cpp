#include "slam/tracking/keyframe_decision.h"

#include <gtest/gtest.h>

namespace pcr {
namespace {

// A frame that tracks well: many points, half the reference's close points still tracked.
KeyframeDecisionInput Healthy() {
  KeyframeDecisionInput in;
  in.tracked_points = 400;
  in.reference_tracked_points = 450;
  in.tracked_close = 250;
  in.untracked_close = 50;
  in.filtered_points = 0;
  in.total_points = 2000;
  in.seconds_since_last_keyframe = 0.3;
  in.motion_quality = 0.9;
  in.keyframes_in_map = 5;
  in.stereo = true;
  return in;
}

struct Row {
  const char* name;
  void (*edit)(KeyframeDecisionInput*);
  bool insert;
  const char* reason;
};

TEST(KeyframeDecision, Table) {
  const Row rows[] = {
      {"healthy", [](KeyframeDecisionInput*) {}, false, "tracking well"},
      {"no map", [](KeyframeDecisionInput* in) { in->keyframes_in_map = 0; }, false, "no map"},
      {"few vs reference (< 75%)", [](KeyframeDecisionInput* in) { in->tracked_points = 330; },
       true, "few points tracked vs reference"},
      {"75.1% is still enough", [](KeyframeDecisionInput* in) { in->tracked_points = 338; }, false,
       "tracking well"},
      {"needs close points",
       [](KeyframeDecisionInput* in) {
         in->tracked_close = 99;
         in->untracked_close = 71;
       },
       true, "needs close points"},
      {"few close but nothing to gain",
       [](KeyframeDecisionInput* in) {
         in->tracked_close = 99;
         in->untracked_close = 70;
       },
       false, "tracking well"},
      {"monocular ignores close points",
       [](KeyframeDecisionInput* in) {
         in->stereo = false;
         in->tracked_close = 0;
         in->untracked_close = 500;
         in->tracked_points = 420;
       },
       false, "tracking well"},
      {"monocular ratio 0.9",
       [](KeyframeDecisionInput* in) {
         in->stereo = false;
         in->tracked_points = 400;
       },
       true, "few points tracked vs reference"},
      {"weak tracking", [](KeyframeDecisionInput* in) { in->tracked_points = 100; }, true,
       "weak tracking"},
      {"max interval", [](KeyframeDecisionInput* in) { in->seconds_since_last_keyframe = 1.0; },
       true, "max interval"},
      {"low motion quality", [](KeyframeDecisionInput* in) { in->motion_quality = 0.4; }, true,
       "low motion quality"},
      {"too few tracked overall",
       [](KeyframeDecisionInput* in) {
         in->tracked_points = 15;
         in->seconds_since_last_keyframe = 5;
       },
       false, "too few tracked points"},
      {"recently relocalised",
       [](KeyframeDecisionInput* in) {
         in->recently_relocalised = true;
         in->tracked_points = 200;
       },
       false, "recently relocalised"},
      // Relocalised at the edge of a map: its points are leaving the view. In stereo a keyframe
      // from the frame's own depth is made anyway; a monocular frame waits.
      {"recently relocalised but weak",
       [](KeyframeDecisionInput* in) {
         in->recently_relocalised = true;
         in->tracked_points = 100;
       },
       true, "weak tracking"},
      {"recently relocalised but needs close points",
       [](KeyframeDecisionInput* in) {
         in->recently_relocalised = true;
         in->tracked_points = 200;
         in->tracked_close = 99;
         in->untracked_close = 71;
       },
       true, "needs close points"},
      {"monocular recently relocalised waits",
       [](KeyframeDecisionInput* in) {
         in->recently_relocalised = true;
         in->stereo = false;
         in->tracked_points = 100;
       },
       false, "recently relocalised"},
      {"first keyframes use ratio 0.4",
       [](KeyframeDecisionInput* in) {
         in->keyframes_in_map = 1;
         in->tracked_points = 190;
         in->tracked_close = 150;
       },
       false, "tracking well"},
      {"first keyframes below 0.4",
       [](KeyframeDecisionInput* in) {
         in->keyframes_in_map = 1;
         in->tracked_points = 170;
         in->tracked_close = 150;
       },
       true, "few points tracked vs reference"},
      // Filtering (Eq. 7): 25% filtered raises the ratio to 0.75 + 0.2 * 0.25 = 0.8, so 350 of
      // 450 (77.8%) now inserts.
      {"filtered points raise the ratio",
       [](KeyframeDecisionInput* in) {
         in->filtered_points = 500;
         in->tracked_points = 350;
       },
       true, "few points tracked vs reference"},
      {"same count without filtering", [](KeyframeDecisionInput* in) { in->tracked_points = 350; },
       false, "tracking well"},
      {"mostly dynamic frame is not a keyframe",
       [](KeyframeDecisionInput* in) {
         in->filtered_points = 1300;
         in->tracked_points = 300;
       },
       false, "too much dynamic content"},
      {"mostly dynamic but weak tracking still inserts",
       [](KeyframeDecisionInput* in) {
         in->filtered_points = 1300;
         in->tracked_points = 100;
       },
       true, "weak tracking"},
  };
  for (const Row& row : rows) {
    KeyframeDecisionInput in = Healthy();
    row.edit(&in);
    const KeyframeDecision d = ShouldInsertKeyframe(in);
    EXPECT_EQ(d.insert, row.insert) << row.name;
    EXPECT_EQ(d.reason, row.reason) << row.name;
  }
}

TEST(KeyframeDecision, MinIntervalHoldsBackUnlessWeak) {
  KeyframeDecisionOptions opt;
  opt.min_interval_s = 0.5;
  KeyframeDecisionInput in = Healthy();
  in.tracked_points = 300;
  in.seconds_since_last_keyframe = 0.2;
  EXPECT_FALSE(ShouldInsertKeyframe(in, opt).insert);
  in.tracked_points = 100;
  EXPECT_TRUE(ShouldInsertKeyframe(in, opt).insert);
}

TEST(KeyframeDecision, OptionsValidation) {
  std::string why;
  EXPECT_TRUE(KeyframeDecisionOptions{}.IsValid(&why)) << why;
  KeyframeDecisionOptions bad;
  bad.reference_ratio = 1.5;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_FALSE(why.empty());
  bad = {};
  bad.min_interval_s = 2.0;
  EXPECT_FALSE(bad.IsValid(&why));
  bad = {};
  bad.max_filtered_fraction = -0.1;
  EXPECT_FALSE(bad.IsValid(&why));
}

}  // namespace
}  // namespace pcr
