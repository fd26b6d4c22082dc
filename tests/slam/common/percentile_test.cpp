// pcr::Percentile at the edges: no values, and infinite values.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "slam/common/timing.h"

namespace pcr {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(Percentile, OfNoValuesIsNaN) {
  // Not 0, which would read as a measured zero: the printers show NaN as "-".
  EXPECT_TRUE(std::isnan(Percentile({}, 50)));
  EXPECT_TRUE(std::isnan(Percentile({}, 0)));
}

TEST(Percentile, AnInfiniteValueStaysInfinite) {
  // On an infinite sample, and between a finite and an infinite one (numpy gives inf too);
  // inf + (inf - inf) * 0 was NaN.
  EXPECT_EQ(Percentile({1.0, kInf}, 100), kInf);
  EXPECT_EQ(Percentile({1.0, kInf}, 50), kInf);
  EXPECT_EQ(Percentile({1.0, kInf, kInf}, 50), kInf);
  EXPECT_EQ(Percentile({kInf, kInf, kInf}, 37), kInf);
  EXPECT_EQ(Percentile({-kInf, 1.0}, 0), -kInf);
  EXPECT_EQ(Percentile({-kInf, 1.0}, 50), -kInf);
  EXPECT_DOUBLE_EQ(Percentile({1.0, 3.0, kInf}, 25), 2.0);  // finite neighbours: as before
  // Between -inf and +inf there is no answer.
  EXPECT_TRUE(std::isnan(Percentile({-kInf, kInf}, 50)));
}

}  // namespace
}  // namespace pcr
