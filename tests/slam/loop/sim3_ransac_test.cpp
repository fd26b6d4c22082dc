#include "slam/loop/sim3_ransac.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "slam/common/error.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

struct MatchScene {
  Sim3 cam1_from_cam2;
  std::vector<Sim3Correspondence> matches;
  std::vector<bool> is_outlier;
};

// A point seen by both cameras: in camera 1 at a pixel inside the image and a depth in [4, 30] m,
// and in front of camera 2 inside its image.
bool SamplePoint(const PinholeCamera& camera, const Sim3& cam1_from_cam2, std::mt19937_64& rng,
                 Eigen::Vector3d* p_in_cam1, Eigen::Vector3d* p_in_cam2) {
  std::uniform_real_distribution<double> u(0.0, camera.width_px - 1.0);
  std::uniform_real_distribution<double> v(0.0, camera.height_px - 1.0);
  std::uniform_real_distribution<double> depth(4.0, 30.0);
  for (int attempt = 0; attempt < 100; ++attempt) {
    *p_in_cam1 = camera.Unproject({u(rng), v(rng)}, depth(rng));
    *p_in_cam2 = cam1_from_cam2.Inverse().Map(*p_in_cam1);
    if (p_in_cam2->z() > 1.0 && camera.InImage(camera.Project(*p_in_cam2))) return true;
  }
  return false;
}

MatchScene MakeScene(uint64_t seed, int count, double outlier_fraction, double scale,
                     double noise_px) {
  const PinholeCamera camera = test::KittiCamera();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::uniform_int_distribution<int> octave(0, 3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  MatchScene scene;
  scene.cam1_from_cam2.scale = scale;
  scene.cam1_from_cam2.rotation = ExpSO3(Eigen::Vector3d(0.03, -0.12, 0.02));
  scene.cam1_from_cam2.translation = Eigen::Vector3d(0.4, 0.1, -1.5);
  for (int i = 0; i < count; ++i) {
    Sim3Correspondence m;
    EXPECT_TRUE(SamplePoint(camera, scene.cam1_from_cam2, rng, &m.p_in_cam1, &m.p_in_cam2));
    const double level1 = std::pow(1.2, octave(rng)), level2 = std::pow(1.2, octave(rng));
    m.sigma2_1 = level1 * level1;
    m.sigma2_2 = level2 * level2;
    m.uv1_px = camera.Project(m.p_in_cam1) + level1 * Eigen::Vector2d(noise(rng), noise(rng));
    const bool outlier = unit(rng) < outlier_fraction;
    if (outlier) {  // a wrong match: another point's 3-D position and keypoint in camera 2
      Eigen::Vector3d other_in_cam1;
      EXPECT_TRUE(SamplePoint(camera, scene.cam1_from_cam2, rng, &other_in_cam1, &m.p_in_cam2));
    }
    m.uv2_px = camera.Project(m.p_in_cam2) + level2 * Eigen::Vector2d(noise(rng), noise(rng));
    scene.matches.push_back(m);
    scene.is_outlier.push_back(outlier);
  }
  return scene;
}

double RotationErrorDeg(const Sim3& a, const Sim3& b) {
  return RotationDistanceRad(a.rotation, b.rotation) / test::kDegToRad;
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
