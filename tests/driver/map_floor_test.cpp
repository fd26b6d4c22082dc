// driver/map_floor.h on its edges: invalid solve options are a ConfigError, and a map with too
// few keyframes gets no figures (NaN) instead of a solve. Its figures on a real loop are checked
// in loop_closing_test.cpp.
#include "driver/map_floor.h"

#include <gtest/gtest.h>

#include <cmath>

#include "slam/common/error.h"
#include "slam/map/synthetic_scene.h"

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

// Two keyframes of a noise-free synthetic scene with their points at the true positions: every
// mean residual is zero, except where the test moved the keypoints. Those of level 7 in the
// second keyframe are moved 0.3 px toward the image's centre row, so level 7's mean vertical
// residual is -0.3 px times their share of its observations, and nothing else changes.
TEST(MapFloor, ResidualsByLevelFindABiasOfOneLevel) {
  using test::RenderedFrame;
  using test::SyntheticScene;
  using test::TruePose;
  SyntheticScene::Options o;
  o.pixel_noise_px = 0;
  o.u_right_noise_px = 0;
  o.num_clutter = 0;
  SyntheticScene scene(7, o);
  const SE3 poses[2] = {TruePose(0), TruePose(1)};
  Map map;
  std::map<int, std::vector<KeyframeObservation>> observations_of_point;
  int moved = 0;
  for (int k = 0; k < 2; ++k) {
    RenderedFrame r = scene.Render(poses[k]);
    if (k == 1)
      for (cv::KeyPoint& kp : r.features.keypoints)
        if (kp.octave == 7) {
          kp.pt.y += kp.pt.y > scene.rig().left.cy ? -0.3f : 0.3f;
          ++moved;
        }
    MapDelta d;
    NewKeyframe kf;
    kf.frame = Frame::Create(k, k * 100'000'000, scene.rig(), scene.scale(), r.features, r.stereo);
    kf.cam_from_world = poses[k];
    if (k == 1) kf.parent_hint = KeyframeId(0);
    d.new_keyframe = kf;
    map.Apply(d);
    for (size_t i = 0; i < r.point_of_keypoint.size(); ++i)
      if (r.point_of_keypoint[i] >= 0)
        observations_of_point[r.point_of_keypoint[i]].push_back(
            {KeyframeId(k), static_cast<int>(i)});
  }
  ASSERT_GT(moved, 10);
  MapDelta points;
  for (const auto& [i, obs] : observations_of_point)
    points.new_points.push_back({scene.point(i), obs});
  map.Apply(points);
  ASSERT_GT(map.num_points(), 500u);

  const std::vector<LevelResidual> residuals = ResidualsByLevel(map);
  ASSERT_EQ(residuals.size(), 8u);
  int level7_observations_moved = 0;
  for (const auto& [pid, mp] : map.points())
    for (const auto& [kid, kp] : mp.observations)
      if (kid == KeyframeId(1) && map.keyframe(kid)->frame->octave(kp) == 7)
        ++level7_observations_moved;
  for (const LevelResidual& l : residuals) {
    SCOPED_TRACE(l.level);
    EXPECT_GT(l.observations, 0);
    EXPECT_GT(l.stereo, 0);
    EXPECT_NEAR(l.radial_u_px, 0, 1e-3);
    EXPECT_NEAR(l.disparity_px, 0, 1e-3);
    const double expected = l.level == 7 ? -0.3 * level7_observations_moved / l.observations : 0;
    EXPECT_NEAR(l.radial_v_px, expected, 1e-3);
  }
  EXPECT_LT(residuals.back().radial_v_px, -0.1);
}

}  // namespace
}  // namespace pcr::driver
