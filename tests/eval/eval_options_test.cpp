// The eval option checks as the command line shows them: reasons that start with the field's name
// (which `pcr_orb eval` turns into its option's, slam/common/validation.h NamedAsOption) with
// numbers in their short form; repeated KITTI segment lengths refused; the no-segment note.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "eval/evaluation.h"
#include "eval/report.h"
#include "eval_test_util.h"

namespace pcr::eval {
namespace {

TEST(EvalOptionsTest, ARepeatedSegmentLengthIsRefused) {
  // Evaluated once per occurrence, a repeated length counted its segments twice: "10 segments"
  // for the 5 of --segments 10, two rows "10 10".
  KittiMetricsOptions options;
  options.lengths_m = {10, 20, 10};
  std::string why;
  ASSERT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why, "lengths_m must be distinct, got 10 more than once");
  const Trajectory line = test::FromPositions({{0, 0, 0}, {0, 0, 30}, {0, 0, 60}});
  EXPECT_THROW(ComputeKittiMetrics(line, line, options), std::invalid_argument);
}

TEST(EvalOptionsTest, ReasonsStartWithTheFieldAndShowShortNumbers) {
  std::string why;
  ASSERT_FALSE((RpeOptions{1e300, DeltaUnit::kFrames, false, 0.1}).IsValid(&why));
  EXPECT_EQ(why, "delta must be at most 1000000000, got 1e+300");  // not 300 digits
  ASSERT_FALSE((RpeOptions{0, DeltaUnit::kMeters, false, 0.1}).IsValid(&why));
  EXPECT_EQ(why, "delta must be positive, got 0");
  ASSERT_FALSE((RpeOptions{2.5, DeltaUnit::kFrames, false, 0.1}).IsValid(&why));
  EXPECT_EQ(why, "delta in frames must be a whole number, got 2.5");
  ASSERT_FALSE((AlignmentOptions{AlignMode::kSe3, 2}).IsValid(&why));
  EXPECT_EQ(why, "first_n must be -1 (all) or at least 3, got 2");
  ASSERT_FALSE((TimeAssociationOptions{-1, 0}).IsValid(&why));
  EXPECT_EQ(why, "max_diff_s must be in [0, 1000000000] s, got -1");
  ASSERT_FALSE((TimeAssociationOptions{0.01, 2e9}).IsValid(&why));
  EXPECT_EQ(why, "offset_s must be finite and at most 1000000000 s in magnitude, got 2000000000");
  KittiMetricsOptions kitti;
  kitti.lengths_m = {100, -5};
  ASSERT_FALSE(kitti.IsValid(&why));
  EXPECT_EQ(why, "lengths_m must be positive, got -5");
}

TEST(EvalOptionsTest, TheNoSegmentNotePointsToTheEvalCommand) {
  // The note is printed by `run` and `pipeline` too, which have no --segments option.
  const Trajectory line = test::FromPositions({{0, 0, 0}, {0, 0, 1}, {0, 0, 2}, {1, 0, 3}});
  EvalOptions options;
  options.alignment.mode = AlignMode::kNone;
  const EvalResult r = Evaluate(AssociateByFrameIndex(line, line), options);
  const std::string note = FormatKittiMetrics(r, options.kitti);
  EXPECT_NE(note.find("no segment fits"), std::string::npos) << note;
  EXPECT_NE(note.find("`pcr_orb eval --segments`"), std::string::npos) << note;
  EXPECT_EQ(note.find("set shorter lengths with --segments"), std::string::npos) << note;
}

}  // namespace
}  // namespace pcr::eval
