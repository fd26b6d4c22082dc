// Adaptive quality controller (paper Eq. 9) with hysteresis, dwell and smoothing.
#include "nodes/quality.h"

#include <gtest/gtest.h>

#include <limits>
#include <vector>

#include "slam/common/error.h"

namespace pcr::nodes {
namespace {

using L = QualityLevel;

TEST(QualityControllerTest, ClassifyFollowsEquationNine) {
  const double threshold = 30;
  struct Case {
    double available;
    L expected;
  };
  const std::vector<Case> cases = {{100, L::kHigh},     {30.01, L::kHigh}, {30, L::kMedium},
                                   {15.01, L::kMedium}, {15, L::kLow},     {0, L::kLow},
                                   {-50, L::kLow}};
  for (const Case& c : cases)
    EXPECT_EQ(QualityController::Classify(c.available, threshold), c.expected) << c.available;
}

// No smoothing, no dwell: the table shows the hysteresis band alone. Period 100 ms,
// T_threshold = 30 ms (High above 30 ms available, Medium above 15 ms), band 0.2 * 30 = 6 ms.
TEST(QualityControllerTest, HysteresisTable) {
  QualityControllerOptions o;
  o.threshold_fraction = 0.3;
  o.hysteresis_fraction = 0.2;
  o.min_dwell_frames = 0;
  o.smoothing = 1.0;
  o.initial = L::kHigh;
  QualityController c(o);
  struct Step {
    double busy_ms;  // available = 100 - busy
    L expected;
  };
  const std::vector<Step> table = {
      {50, L::kHigh},    // 50 available
      {75, L::kHigh},    // 25: below the boundary, inside the band -> stays
      {77, L::kMedium},  // 23 < 30 - 6 -> down
      {68, L::kMedium},  // 32: above 30 but not above 36 -> stays
      {65, L::kMedium},  // 35: still inside the band
      {63, L::kHigh},    // 37 > 36 -> up
      {80, L::kMedium},  // 20: below 24 -> medium (not below 15 - 6 = 9 -> not low)
      {88, L::kMedium},  // 12: inside the band around 15
      {92, L::kLow},     // 8 < 9 -> low
      {82, L::kLow},     // 18: not above 21
      {78, L::kMedium},  // 22 > 21 -> up one level
      {10, L::kHigh},    // 90 available: up one more
      {98, L::kLow},     // 2: down two levels at once
      {0, L::kMedium},   // 100 available: up one step at a time
      {0, L::kHigh},
  };
  for (size_t i = 0; i < table.size(); ++i) {
    EXPECT_EQ(c.Update(100, table[i].busy_ms), table[i].expected) << "step " << i;
    EXPECT_DOUBLE_EQ(c.available_ms(), 100 - table[i].busy_ms);
    EXPECT_DOUBLE_EQ(c.threshold_ms(), 30);
  }
  EXPECT_EQ(c.changes(), 9);
}

TEST(QualityControllerTest, DwellDelaysUpgradesOnly) {
  QualityControllerOptions o;
  o.hysteresis_fraction = 0;
  o.min_dwell_frames = 3;
  o.smoothing = 1.0;
  o.initial = L::kHigh;
  QualityController c(o);
  EXPECT_EQ(c.Update(100, 95), L::kLow);    // down at once, dwell or not
  EXPECT_EQ(c.Update(100, 0), L::kLow);     // 1 frame at low
  EXPECT_EQ(c.Update(100, 0), L::kLow);     // 2
  EXPECT_EQ(c.Update(100, 0), L::kMedium);  // 3: allowed, one step
  EXPECT_EQ(c.Update(100, 0), L::kMedium);
  EXPECT_EQ(c.Update(100, 0), L::kMedium);
  EXPECT_EQ(c.Update(100, 0), L::kHigh);
  EXPECT_EQ(c.Update(100, 90), L::kLow);  // and straight down again
  EXPECT_EQ(c.changes(), 4);
}

TEST(QualityControllerTest, SmoothingIgnoresOneSlowFrame) {
  QualityControllerOptions o;
  o.smoothing = 0.2;
  o.hysteresis_fraction = 0.1;
  o.initial = L::kHigh;
  QualityController c(o);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(c.Update(100, 40), L::kHigh);
  // One 120 ms frame: average 40 + 0.2 * 80 = 56 -> 44 available, still high.
  EXPECT_EQ(c.Update(100, 120), L::kHigh);
  EXPECT_NEAR(c.available_ms(), 44, 1e-9);
  // A sustained overload brings it down.
  L level = L::kHigh;
  for (int i = 0; i < 20; ++i) level = c.Update(100, 120);
  EXPECT_EQ(level, L::kLow);
}

TEST(QualityControllerTest, IgnoresMeaninglessSamplesAndRejectsBadOptions) {
  QualityController c;
  EXPECT_EQ(c.level(), L::kMedium);        // the default first level: the fast network
  EXPECT_EQ(c.Update(0, 10), L::kMedium);  // no period (e.g. rate 0): no decision
  EXPECT_EQ(c.Update(100, std::numeric_limits<double>::quiet_NaN()), L::kMedium);
  EXPECT_EQ(c.changes(), 0);
  QualityControllerOptions bad;
  bad.smoothing = 0;
  EXPECT_THROW(QualityController{bad}, ConfigError);
  bad = {};
  bad.threshold_fraction = 1.5;
  EXPECT_THROW(QualityController{bad}, ConfigError);
  bad = {};
  bad.hysteresis_fraction = 0.5;
  EXPECT_THROW(QualityController{bad}, ConfigError);
}

TEST(QualityLevelsTest, DefaultsMatchTheIssue) {
  const QualityLevels levels;
  EXPECT_EQ(levels.At(L::kHigh).segmenter, SegmenterSlot::kAccurate);
  EXPECT_EQ(levels.At(L::kHigh).orb_features, 2000);
  EXPECT_TRUE(levels.At(L::kHigh).optical_flow);
  EXPECT_EQ(levels.At(L::kMedium).segmenter, SegmenterSlot::kFast);
  EXPECT_EQ(levels.At(L::kLow).inference_every, 2);  // every frame with a light network
  EXPECT_EQ(levels.At(L::kLow).segmenter, SegmenterSlot::kLight);
  EXPECT_TRUE(levels.At(L::kLow).propagate_masks);
  EXPECT_LT(levels.At(L::kLow).mask_wait_ms, 0);  // the pipeline's deadline
  EXPECT_EQ(levels.At(L::kLow).orb_features, 1200);
  EXPECT_LT(levels.At(L::kLow).ba_max_iterations, levels.At(L::kHigh).ba_max_iterations);
  EXPECT_TRUE(levels.At(L::kLow).optical_flow);
  EXPECT_GT(levels.At(L::kLow).min_keyframe_interval_s, 0.1);
  EXPECT_EQ(levels.At(L::kMedium).min_keyframe_interval_s, 0.0);
  std::string why;
  EXPECT_TRUE(levels.IsValid(&why)) << why;
  QualityLevels bad;
  bad.low.inference_every = 0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("low"), std::string::npos);
  bad = {};
  bad.medium.min_keyframe_interval_s = -1;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("min_keyframe_interval_s"), std::string::npos) << why;
  QualityLevel parsed;
  EXPECT_TRUE(ParseQualityLevel("medium", &parsed));
  EXPECT_EQ(parsed, L::kMedium);
  EXPECT_FALSE(ParseQualityLevel("Medium", &parsed));
}

}  // namespace
}  // namespace pcr::nodes
