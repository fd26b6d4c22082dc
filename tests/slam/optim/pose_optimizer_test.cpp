#include "slam/optim/pose_optimizer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "optim_test_scene.h"
#include "slam/common/error.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

using optim_test::CentreErrorM;
using optim_test::KittiRig;
using optim_test::MakePoseScene;
using optim_test::PerturbPose;
using optim_test::PoseScene;
using optim_test::PoseSceneOptions;
using optim_test::RotationErrorRad;

using test::kDegToRad;

using test::BitwiseEqual;

TEST(PoseOptimizerTest, NoiseFreeRecoversExactPose) {
  const StereoRig rig = KittiRig();
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    std::mt19937_64 rng(seed);
    PoseSceneOptions scene_options;
    scene_options.num_points = 150;
    const PoseScene scene = MakePoseScene(rig, scene_options, rng);
    const SE3 start = PerturbPose(scene.cam_from_world_true, rng, 0.3, 2.0 * kDegToRad);
    ASSERT_GT(CentreErrorM(start, scene.cam_from_world_true), 0.1);

    const PoseOptimizationResult result = OptimizePose(rig, start, scene.observations);
    EXPECT_LT(CentreErrorM(result.cam_from_world, scene.cam_from_world_true), 1e-6) << seed;
    EXPECT_LT(RotationErrorRad(result.cam_from_world, scene.cam_from_world_true), 1e-6) << seed;
    EXPECT_EQ(result.num_inliers, 150);
    ASSERT_EQ(result.inlier.size(), 150u);
    for (bool inlier : result.inlier) EXPECT_TRUE(inlier);
    EXPECT_LT(result.final_cost, 1e-10);
    EXPECT_GT(result.iterations, 0);
  }
}

TEST(PoseOptimizerTest, GaussianNoiseGivesSmallError) {
  const StereoRig rig = KittiRig();
  for (uint64_t seed = 10; seed < 16; ++seed) {
    std::mt19937_64 rng(seed);
    PoseSceneOptions scene_options;
    scene_options.num_points = 300;
    scene_options.noise_px = 1.0;
    const PoseScene scene = MakePoseScene(rig, scene_options, rng);
    const SE3 start = PerturbPose(scene.cam_from_world_true, rng, 0.3, 2.0 * kDegToRad);
    const PoseOptimizationResult result = OptimizePose(rig, start, scene.observations);
    EXPECT_LT(CentreErrorM(result.cam_from_world, scene.cam_from_world_true), 0.02) << seed;
    EXPECT_LT(RotationErrorRad(result.cam_from_world, scene.cam_from_world_true), 0.1 * kDegToRad)
        << seed;
    // With unit information and 1-px noise about 5% of the observations exceed the 95% bounds.
    EXPECT_GT(result.num_inliers, 0.88 * 300) << seed;
    // final_cost is half the chi2 sum over the inliers: about half a degree of freedom each.
    EXPECT_LT(result.final_cost, 1.5 * result.num_inliers) << seed;
  }
}

TEST(PoseOptimizerTest, GrossOutliersAreFlaggedAndPoseStaysAccurate) {
  const StereoRig rig = KittiRig();
  for (uint64_t seed = 20; seed < 26; ++seed) {
    std::mt19937_64 rng(seed);
    PoseSceneOptions scene_options;
    scene_options.num_points = 300;
    scene_options.noise_px = 1.0;
    scene_options.outlier_fraction = seed % 2 == 0 ? 0.2 : 0.3;
    const PoseScene scene = MakePoseScene(rig, scene_options, rng);
    const SE3 start = PerturbPose(scene.cam_from_world_true, rng, 0.3, 2.0 * kDegToRad);
    const PoseOptimizationResult result = OptimizePose(rig, start, scene.observations);

    int num_outliers = 0, inliers_kept = 0, num_good = 0;
    for (size_t i = 0; i < scene.observations.size(); ++i) {
      if (scene.is_gross_outlier[i]) {
        ++num_outliers;
        EXPECT_FALSE(result.inlier[i]) << "gross outlier " << i << " accepted, seed " << seed;
      } else {
        ++num_good;
        inliers_kept += result.inlier[i] ? 1 : 0;
      }
    }
    EXPECT_GT(num_outliers, 0.1 * 300) << seed;
    EXPECT_GT(inliers_kept, 0.88 * num_good) << seed;
    EXPECT_LT(CentreErrorM(result.cam_from_world, scene.cam_from_world_true), 0.03) << seed;
    EXPECT_LT(RotationErrorRad(result.cam_from_world, scene.cam_from_world_true), 0.15 * kDegToRad)
        << seed;
  }
}

// The filter's weight scales a point's pull, not its noise: a down-weighted observation 5 px off
// (chi2 about 25 > 7.8) is still an outlier. Folding the weight into the information would
// have scaled its chi2 by 0.1 and accepted exactly the points the filter suspects.
TEST(PoseOptimizerTest, DownWeightedOutliersAreStillFlagged) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(31);
  PoseSceneOptions scene_options;
  scene_options.num_points = 200;
  scene_options.noise_px = 0.3;
  PoseScene scene = MakePoseScene(rig, scene_options, rng);
  std::vector<size_t> shifted;
  for (size_t i = 0; i < scene.observations.size(); i += 10) {
    scene.observations[i].uv_px += Eigen::Vector2d(5.0, 0.0);
    if (scene.observations[i].u_right_px >= 0) scene.observations[i].u_right_px += 5.0;
    scene.observations[i].weight = 0.1;
    shifted.push_back(i);
  }
  const PoseOptimizationResult result =
      OptimizePose(rig, scene.cam_from_world_true, scene.observations);
  for (size_t i : shifted) EXPECT_FALSE(result.inlier[i]) << "observation " << i;
  EXPECT_GT(result.num_inliers,
            static_cast<int>(0.85 * (scene.observations.size() - shifted.size())));
  EXPECT_LT(CentreErrorM(result.cam_from_world, scene.cam_from_world_true), 0.02);
}

TEST(PoseOptimizerTest, ExcludedObservationsAreIgnored) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(30);
  PoseSceneOptions scene_options;
  scene_options.num_points = 250;
  scene_options.noise_px = 1.0;
  scene_options.outlier_fraction = 0.3;
  const PoseScene scene = MakePoseScene(rig, scene_options, rng);
  const SE3 start = PerturbPose(scene.cam_from_world_true, rng, 0.3, 2.0 * kDegToRad);

  std::vector<PoseObservation> with_excluded = scene.observations;
  std::vector<PoseObservation> clean;
  for (size_t i = 0; i < with_excluded.size(); ++i) {
    if (scene.is_gross_outlier[i]) {
      with_excluded[i].excluded = true;
      // Garbage in excluded observations must not matter either.
      if (i % 2 == 0) with_excluded[i].p_in_world.x() = std::nan("");
    } else {
      clean.push_back(scene.observations[i]);
    }
  }
  const PoseOptimizationResult a = OptimizePose(rig, start, with_excluded);
  const PoseOptimizationResult b = OptimizePose(rig, start, clean);
  EXPECT_TRUE(BitwiseEqual(a.cam_from_world, b.cam_from_world)) << a.cam_from_world.matrix() << "\n"
                                                                << b.cam_from_world.matrix();
  EXPECT_EQ(a.num_inliers, b.num_inliers);
  EXPECT_EQ(a.final_cost, b.final_cost);
  size_t j = 0;
  for (size_t i = 0; i < with_excluded.size(); ++i) {
    if (scene.is_gross_outlier[i]) {
      EXPECT_FALSE(a.inlier[i]);
    } else {
      EXPECT_EQ(a.inlier[i], b.inlier[j++]);
    }
  }
  // Without the exclusion the outliers do enter (and are then rejected): a different problem.
  const PoseOptimizationResult c = OptimizePose(rig, start, scene.observations);
  EXPECT_FALSE(BitwiseEqual(a.cam_from_world, c.cam_from_world));
}

// Two groups of observations generated from poses 4 cm apart along x (all within the chi2
// bounds): the estimate lies between them, and down-weighting one group moves it toward the other.
TEST(PoseOptimizerTest, WeightsShiftTheSolution) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(40);
  PoseSceneOptions scene_options;
  scene_options.num_points = 200;
  scene_options.min_depth_m = 20.0;
  scene_options.max_depth_m = 60.0;
  scene_options.stereo_max_depth_m = 100.0;
  const PoseScene scene_a = MakePoseScene(rig, scene_options, rng);
  // Group B: same world points, observed from a camera shifted by 4 cm along its x axis.
  SE3 shift = SE3::Identity();
  shift.translation() = Eigen::Vector3d(-0.04, 0, 0);  // camera centre moves +4 cm along x
  const SE3 cam_b_from_world = shift * scene_a.cam_from_world_true;
  std::vector<PoseObservation> observations = scene_a.observations;
  for (size_t i = 0; i < observations.size(); i += 2) {
    const Eigen::Vector3d p_in_cam = cam_b_from_world * observations[i].p_in_world;
    observations[i].uv_px = rig.left.Project(p_in_cam);
    observations[i].u_right_px = rig.ProjectRightX(p_in_cam);
  }
  const Eigen::Vector3d centre_a = scene_a.cam_from_world_true.inverse().translation();
  const Eigen::Vector3d x_axis = scene_a.cam_from_world_true.linear().row(0).transpose();
  // Position of the estimated camera centre along the shift, 0 = pose A, 1 = pose B.
  auto along = [&](const SE3& cam_from_world) {
    return (cam_from_world.inverse().translation() - centre_a).dot(x_axis) / 0.04;
  };
  const SE3 start = scene_a.cam_from_world_true;
  const PoseOptimizationResult equal = OptimizePose(rig, start, observations);
  EXPECT_EQ(equal.num_inliers, 200) << "the conflict must stay within the chi2 bounds";
  for (size_t i = 0; i < observations.size(); i += 2) observations[i].weight = 0.1;
  const PoseOptimizationResult b_light = OptimizePose(rig, start, observations);
  for (size_t i = 0; i < observations.size(); ++i) observations[i].weight = i % 2 ? 0.1 : 1.0;
  const PoseOptimizationResult a_light = OptimizePose(rig, start, observations);

  const double s_equal = along(equal.cam_from_world);
  const double s_b_light = along(b_light.cam_from_world);
  const double s_a_light = along(a_light.cam_from_world);
  EXPECT_NEAR(s_equal, 0.5, 0.1);
  EXPECT_LT(s_b_light, s_equal - 0.2);      // toward A
  EXPECT_GT(s_a_light, s_equal + 0.2);      // toward B
  EXPECT_NEAR(s_b_light, 1.0 / 11.0, 0.1);  // weighted mean 0.1 / 1.1
  EXPECT_NEAR(s_a_light, 10.0 / 11.0, 0.1);
}

TEST(PoseOptimizerTest, MonocularOnly) {
  for (bool mono_rig : {true, false}) {
    const StereoRig rig = mono_rig ? optim_test::MonoRig() : KittiRig();
    std::mt19937_64 rng(50);
    PoseSceneOptions scene_options;
    scene_options.num_points = 300;
    scene_options.stereo_max_depth_m = 0.0;  // all monocular
    PoseScene scene = MakePoseScene(rig, scene_options, rng);
    if (!mono_rig) {
      // A stereo rig with u_right_px < 0 everywhere must behave as monocular; so must a mono
      // rig that is given u_right values (ignored).
      for (const PoseObservation& obs : scene.observations) ASSERT_LT(obs.u_right_px, 0);
    } else {
      for (PoseObservation& obs : scene.observations)
        obs.u_right_px = obs.uv_px.x() - 10.0;  // >= 0: would be used on a stereo rig
    }
    const SE3 start = PerturbPose(scene.cam_from_world_true, rng, 0.2, 1.0 * kDegToRad);
    const PoseOptimizationResult exact = OptimizePose(rig, start, scene.observations);
    EXPECT_LT(CentreErrorM(exact.cam_from_world, scene.cam_from_world_true), 1e-6);
    EXPECT_LT(RotationErrorRad(exact.cam_from_world, scene.cam_from_world_true), 1e-6);
    EXPECT_EQ(exact.num_inliers, 300);

    std::normal_distribution<double> noise(0.0, 1.0);
    for (PoseObservation& obs : scene.observations)
      obs.uv_px += Eigen::Vector2d(noise(rng), noise(rng));
    const PoseOptimizationResult noisy = OptimizePose(rig, start, scene.observations);
    EXPECT_LT(CentreErrorM(noisy.cam_from_world, scene.cam_from_world_true), 0.05);
    EXPECT_LT(RotationErrorRad(noisy.cam_from_world, scene.cam_from_world_true), 0.1 * kDegToRad);
  }
}

// A point behind the initial camera starts as an outlier, is re-checked after the first round
// and comes back once the pose has converged; points behind the true camera stay outliers.
TEST(PoseOptimizerTest, PointsBehindCameraAreOutliersAndMayComeBack) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(60);
  PoseSceneOptions scene_options;
  scene_options.num_points = 150;
  PoseScene scene = MakePoseScene(rig, scene_options, rng);
  const SE3 world_from_cam = scene.cam_from_world_true.inverse();

  PoseObservation near;  // 1.2 m ahead of the true camera, monocular
  near.p_in_world = world_from_cam * Eigen::Vector3d(0.1, 0.05, 1.2);
  near.uv_px = rig.left.Project(Eigen::Vector3d(0.1, 0.05, 1.2));
  scene.observations.push_back(near);
  PoseObservation behind;  // behind the true camera, with a plausible-looking pixel
  behind.p_in_world = world_from_cam * Eigen::Vector3d(1.0, 0.5, -10.0);
  behind.uv_px = Eigen::Vector2d(500, 200);
  scene.observations.push_back(behind);

  // Start 1.5 m ahead of the truth: the near point is behind the initial camera.
  SE3 forward = SE3::Identity();
  forward.translation() = Eigen::Vector3d(0, 0, -1.5);
  const SE3 start = forward * scene.cam_from_world_true;
  ASSERT_LT((start * near.p_in_world).z(), 0.0);

  const PoseOptimizationResult result = OptimizePose(rig, start, scene.observations);
  EXPECT_LT(CentreErrorM(result.cam_from_world, scene.cam_from_world_true), 1e-6);
  EXPECT_TRUE(result.inlier[150]) << "near point should come back";
  EXPECT_FALSE(result.inlier[151]) << "point behind the camera";
  EXPECT_EQ(result.num_inliers, 151);
}

TEST(PoseOptimizerTest, Deterministic) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(70);
  PoseSceneOptions scene_options;
  scene_options.num_points = 300;
  scene_options.noise_px = 1.0;
  scene_options.outlier_fraction = 0.25;
  const PoseScene scene = MakePoseScene(rig, scene_options, rng);
  const SE3 start = PerturbPose(scene.cam_from_world_true, rng, 0.3, 2.0 * kDegToRad);
  const PoseOptimizationResult a = OptimizePose(rig, start, scene.observations);
  const PoseOptimizationResult b = OptimizePose(rig, start, scene.observations);
  EXPECT_TRUE(BitwiseEqual(a.cam_from_world, b.cam_from_world));
  EXPECT_EQ(a.inlier, b.inlier);
  EXPECT_EQ(a.final_cost, b.final_cost);
  EXPECT_EQ(a.iterations, b.iterations);
}

TEST(PoseOptimizerTest, RoundsAndKernelOptions) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(80);
  PoseSceneOptions scene_options;
  scene_options.num_points = 200;
  scene_options.noise_px = 1.0;
  scene_options.outlier_fraction = 0.25;
  const PoseScene scene = MakePoseScene(rig, scene_options, rng);
  const SE3 start = PerturbPose(scene.cam_from_world_true, rng, 0.2, 1.0 * kDegToRad);
  // A single robust round still rejects the gross outliers; more rounds do not hurt.
  PoseOptimizerOptions one_round;
  one_round.rounds = 1;
  const PoseOptimizationResult one = OptimizePose(rig, start, scene.observations, one_round);
  const PoseOptimizationResult four = OptimizePose(rig, start, scene.observations);
  for (size_t i = 0; i < scene.observations.size(); ++i) {
    if (scene.is_gross_outlier[i]) {
      EXPECT_FALSE(one.inlier[i]);
      EXPECT_FALSE(four.inlier[i]);
    }
  }
  EXPECT_LT(CentreErrorM(one.cam_from_world, scene.cam_from_world_true), 0.05);
  EXPECT_LT(CentreErrorM(four.cam_from_world, scene.cam_from_world_true), 0.03);
  // Tighter thresholds flag more observations.
  PoseOptimizerOptions strict;
  strict.chi2_mono = 1.0;
  strict.chi2_stereo = 1.5;
  const PoseOptimizationResult tight = OptimizePose(rig, start, scene.observations, strict);
  EXPECT_LT(tight.num_inliers, four.num_inliers);
}

TEST(PoseOptimizerTest, TooFewObservationsKeepThePose) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(90);
  PoseSceneOptions scene_options;
  scene_options.num_points = 2;
  const PoseScene scene = MakePoseScene(rig, scene_options, rng);
  const SE3 start = PerturbPose(scene.cam_from_world_true, rng, 0.3, 2.0 * kDegToRad);
  const PoseOptimizationResult result = OptimizePose(rig, start, scene.observations);
  EXPECT_TRUE(BitwiseEqual(result.cam_from_world, start));
  EXPECT_EQ(result.iterations, 0);
  const PoseOptimizationResult empty = OptimizePose(rig, start, {});
  EXPECT_TRUE(BitwiseEqual(empty.cam_from_world, start));
  EXPECT_EQ(empty.num_inliers, 0);
  EXPECT_TRUE(empty.inlier.empty());
}

TEST(PoseOptimizerTest, InvalidConfigurationThrows) {
  std::string why;
  PoseOptimizerOptions options;
  EXPECT_TRUE(options.IsValid(&why));
  options.rounds = 0;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("rounds"), std::string::npos);
  EXPECT_THROW(OptimizePose(KittiRig(), SE3::Identity(), {}, options), ConfigError);
  options = {};
  options.chi2_stereo = -1;
  EXPECT_FALSE(options.IsValid(&why));
  options = {};
  options.iterations_per_round = 0;
  EXPECT_FALSE(options.IsValid(nullptr));
  StereoRig bad_rig = KittiRig();
  bad_rig.left.fx = 0;
  EXPECT_THROW(OptimizePose(bad_rig, SE3::Identity(), {}), ConfigError);
}

}  // namespace
}  // namespace pcr
