// driver/map_floor.h on its edges: invalid solve options are a ConfigError, and a map with too
// few keyframes gets no figures (NaN) instead of a solve. Its figures on a real loop are checked
// in loop_closing_test.cpp.
#include "driver/map_floor.h"

#include <gtest/gtest.h>

#include <cmath>

#include "slam/common/error.h"

namespace pcr::driver {
namespace {

TEST(MapFloor, InvalidOptionsAreAConfigError) {
  const Map map;
  const Trajectory truth;
  MapFloorOptions none;
  none.iterations = 0;
  EXPECT_THROW(MapEstimateFloor(map, truth, LoopClosingOptions{}, none), ConfigError);
  MapFloorOptions no_tolerance;
  no_tolerance.function_tolerance = 0;
  EXPECT_THROW(MapEstimateFloor(map, truth, LoopClosingOptions{}, no_tolerance), ConfigError);
}

TEST(MapFloor, AMapWithoutKeyframesHasNoFigures) {
  const MapFloor f = MapEstimateFloor(Map{}, Trajectory{}, LoopClosingOptions{});
  EXPECT_EQ(f.keyframes, 0);
  EXPECT_TRUE(std::isnan(f.map_m));
  EXPECT_TRUE(std::isnan(f.from_truth_m));
  EXPECT_TRUE(std::isnan(KeyframeAte(Map{}, Trajectory{})));
  EXPECT_TRUE(f.converged_residuals.empty());
  EXPECT_TRUE(ResidualsByLevel(Map{}).empty());
}

}  // namespace
}  // namespace pcr::driver
