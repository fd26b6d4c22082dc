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
  EXPECT_DOUBLE_EQ(Percentile({}, 50), 0);
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

TEST(TimingSeries, SummarizeTimesIsTheSeriesSummary) {
  const std::vector<double> ms = {3.0, 1.0, 7.5, 2.25, 9.0};
  TimingSeries s;
  for (double t : ms) s.Add(t);
  const TimingSummary a = SummarizeTimes(ms), b = s.Summarize();
  EXPECT_EQ(a.count, 5u);
  EXPECT_EQ(a.mean_ms, b.mean_ms);
  EXPECT_EQ(a.p50_ms, 3.0);
  EXPECT_EQ(a.p99_ms, b.p99_ms);
  EXPECT_EQ(a.max_ms, 9.0);
  EXPECT_EQ(SummarizeTimes({}).count, 0u);
}

}  // namespace
}  // namespace pcr
