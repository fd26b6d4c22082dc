#include "slam/loop/sim3_ransac.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "slam/common/error.h"
#include "support/sim3_scene.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

using test::MatchScene;
using test::RotationErrorDeg;

// The shared two-camera scene (support/sim3_scene.h) with this file's similarity.
MatchScene MakeScene(uint64_t seed, int count, double outlier_fraction, double scale,
                     double noise_px) {
  return test::MakeMatchScene(Eigen::Vector3d(0.03, -0.12, 0.02), Eigen::Vector3d(0.4, 0.1, -1.5),
                              scale, seed, count, outlier_fraction, noise_px);
}

TEST(Sim3Ransac, RecoversAKnownSimilarityWithOutliers) {
  const MatchScene scene = MakeScene(11, 120, 0.4, 1.3, 0.5);
  Sim3RansacOptions options;
  options.seed = 5;
  const Sim3RansacResult result = EstimateSim3Ransac(test::KittiCamera(), scene.matches, options);
  ASSERT_TRUE(result.success);
  EXPECT_NEAR(result.cam1_from_cam2.scale, 1.3, 0.01);
  EXPECT_LT(RotationErrorDeg(result.cam1_from_cam2, scene.cam1_from_cam2), 0.2);
  EXPECT_LT((result.cam1_from_cam2.translation - scene.cam1_from_cam2.translation).norm(), 0.05);
  int true_inliers = 0, found = 0, false_inliers = 0;
  for (size_t i = 0; i < scene.matches.size(); ++i) {
    true_inliers += !scene.is_outlier[i];
    found += result.inliers[i] && !scene.is_outlier[i];
    false_inliers += result.inliers[i] && scene.is_outlier[i];
  }
  EXPECT_EQ(false_inliers, 0);
  EXPECT_GE(found, 0.9 * true_inliers);
  EXPECT_EQ(result.num_inliers, found + false_inliers);
  EXPECT_LE(result.iterations, options.max_iterations);

  // Deterministic for a seed.
  const Sim3RansacResult again = EstimateSim3Ransac(test::KittiCamera(), scene.matches, options);
  EXPECT_EQ(again.inliers, result.inliers);
  EXPECT_EQ(again.iterations, result.iterations);
  EXPECT_EQ(again.cam1_from_cam2.translation, result.cam1_from_cam2.translation);
}

TEST(Sim3Ransac, FixedScaleRecoversARigidMotion) {
  const MatchScene scene = MakeScene(12, 80, 0.4, 1.0, 0.5);
  Sim3RansacOptions options;
  options.fix_scale = true;
  const Sim3RansacResult result = EstimateSim3Ransac(test::KittiCamera(), scene.matches, options);
  ASSERT_TRUE(result.success);
  EXPECT_EQ(result.cam1_from_cam2.scale, 1.0);
  EXPECT_LT(RotationErrorDeg(result.cam1_from_cam2, scene.cam1_from_cam2), 0.2);
  EXPECT_LT((result.cam1_from_cam2.translation - scene.cam1_from_cam2.translation).norm(), 0.05);
}

TEST(Sim3Ransac, FailsWithTooFewInliers) {
  const PinholeCamera camera = test::KittiCamera();
  // Fewer matches than min_inliers.
  const MatchScene few = MakeScene(13, 15, 0.0, 1.0, 0.5);
  const Sim3RansacResult too_few = EstimateSim3Ransac(camera, few.matches, {});
  EXPECT_FALSE(too_few.success);
  EXPECT_EQ(too_few.iterations, 0);
  EXPECT_EQ(too_few.num_inliers, 0);
  EXPECT_EQ(too_few.inliers, std::vector<bool>(15, false));
  // Enough matches, but almost all wrong.
  const MatchScene wrong = MakeScene(14, 100, 0.9, 1.0, 0.5);
  const Sim3RansacResult failed = EstimateSim3Ransac(camera, wrong.matches, {});
  EXPECT_FALSE(failed.success);
  EXPECT_EQ(failed.num_inliers, 0);
  EXPECT_EQ(failed.iterations, Sim3RansacOptions{}.max_iterations);
}

TEST(Sim3Ransac, RejectsInvalidOptions) {
  Sim3RansacOptions options;
  options.probability = 1.0;
  EXPECT_THROW(EstimateSim3Ransac(test::KittiCamera(), {}, options), ConfigError);
}

}  // namespace
}  // namespace pcr
