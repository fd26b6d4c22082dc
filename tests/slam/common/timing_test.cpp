#include "slam/common/timing.h"

#include <gtest/gtest.h>

namespace pcr {
namespace {

TEST(Percentile, MatchesLinearInterpolation) {
  // numpy.percentile([1,2,3,4], 50) = 2.5, 95 -> 3.85, 0 -> 1, 100 -> 4
  const std::vector<double> v = {4, 1, 3, 2};
  EXPECT_DOUBLE_EQ(Percentile(v, 50), 2.5);
  EXPECT_NEAR(Percentile(v, 95), 3.85, 1e-12);
  EXPECT_DOUBLE_EQ(Percentile(v, 0), 1);
  EXPECT_DOUBLE_EQ(Percentile(v, 100), 4);
}

TEST(TimingSeries, Summarizes) {
  TimingSeries s;
  for (int i = 1; i <= 100; ++i) s.Add(i);
  const TimingSummary sum = s.Summarize();
  EXPECT_EQ(sum.count, 100u);
  EXPECT_DOUBLE_EQ(sum.mean_ms, 50.5);
  EXPECT_DOUBLE_EQ(sum.p50_ms, 50.5);
  EXPECT_NEAR(sum.p99_ms, 99.01, 1e-9);
  EXPECT_DOUBLE_EQ(sum.max_ms, 100);
  EXPECT_DOUBLE_EQ(sum.total_ms, 5050);
}

TEST(TimingSeries, SummarizeTimesOfAnUnsortedVector) {
  // Sorted: 1, 2.25, 3, 7.5, 9 (sum 22.75). Percentiles by linear interpolation at q/100 * 4:
  // p95 at 3.8 -> 7.5 + 0.8 * 1.5 = 8.7, p99 at 3.96 -> 7.5 + 0.96 * 1.5 = 8.94.
  const std::vector<double> ms = {3.0, 1.0, 7.5, 2.25, 9.0};
  const TimingSummary a = SummarizeTimes(ms);
  EXPECT_EQ(a.count, 5u);
  EXPECT_DOUBLE_EQ(a.total_ms, 22.75);
  EXPECT_DOUBLE_EQ(a.mean_ms, 4.55);
  EXPECT_DOUBLE_EQ(a.p50_ms, 3.0);
  EXPECT_NEAR(a.p95_ms, 8.7, 1e-12);
  EXPECT_NEAR(a.p99_ms, 8.94, 1e-12);
  EXPECT_DOUBLE_EQ(a.max_ms, 9.0);
  const TimingSummary none = SummarizeTimes({});
  EXPECT_EQ(none.count, 0u);
  EXPECT_EQ(none.mean_ms, 0.0);
  EXPECT_EQ(none.max_ms, 0.0);
  EXPECT_EQ(none.total_ms, 0.0);
}

}  // namespace
}  // namespace pcr
