#include "slam/optim/bundle_adjustment.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "optim_test_scene.h"
#include "slam/common/error.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

using optim_test::BaScene;
using optim_test::BaSceneOptions;
using optim_test::CentreErrorM;
using optim_test::KittiRig;
using optim_test::MakeBaScene;
using optim_test::RotationErrorRad;

using test::kDegToRad;

using test::BitwiseEqual;

// Root mean square of the whitened residual per degree of freedom over the given observations.
double WhitenedRms(const StereoRig& rig, const std::vector<SE3>& cam_from_world,
                   const std::vector<Eigen::Vector3d>& p_in_world,
                   const std::vector<BaObservation>& observations, const std::vector<bool>& use) {
  double sum = 0;
  int dof = 0;
  for (size_t i = 0; i < observations.size(); ++i) {
    if (!use[i]) continue;
    const BaObservation& obs = observations[i];
    const Eigen::Vector3d p = cam_from_world[obs.keyframe] * p_in_world[obs.point];
    const double info = obs.information * obs.weight;
    sum += info * (obs.uv_px - rig.left.Project(p)).squaredNorm();
    dof += 2;
    if (obs.u_right_px >= 0 && rig.IsStereo()) {
      sum += info * std::pow(obs.u_right_px - rig.ProjectRightX(p), 2);
      dof += 1;
    }
  }
  return std::sqrt(sum / dof);
}

std::vector<SE3> Poses(const std::vector<BaKeyframe>& keyframes) {
  std::vector<SE3> poses;
  for (const BaKeyframe& kf : keyframes) poses.push_back(kf.cam_from_world);
  return poses;
}

std::vector<Eigen::Vector3d> Points(const std::vector<BaPoint>& points) {
  std::vector<Eigen::Vector3d> out;
  for (const BaPoint& p : points) out.push_back(p.p_in_world);
  return out;
}

double MedianPointError(const std::vector<Eigen::Vector3d>& estimate,
                        const std::vector<Eigen::Vector3d>& truth) {
  std::vector<double> errors;
  for (size_t j = 0; j < truth.size(); ++j) errors.push_back((estimate[j] - truth[j]).norm());
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  return errors[errors.size() / 2];
}

void ExpectBitwiseEqual(const BundleAdjustmentResult& a, const BundleAdjustmentResult& b) {
  ASSERT_EQ(a.cam_from_world.size(), b.cam_from_world.size());
  for (size_t k = 0; k < a.cam_from_world.size(); ++k)
    EXPECT_TRUE(BitwiseEqual(a.cam_from_world[k], b.cam_from_world[k])) << k;
  ASSERT_EQ(a.p_in_world.size(), b.p_in_world.size());
  for (size_t j = 0; j < a.p_in_world.size(); ++j) EXPECT_EQ(a.p_in_world[j], b.p_in_world[j]);
  EXPECT_EQ(a.observation_inlier, b.observation_inlier);
  EXPECT_EQ(a.initial_cost, b.initial_cost);
  EXPECT_EQ(a.final_cost, b.final_cost);
  EXPECT_EQ(a.iterations, b.iterations);
}

TEST(BundleAdjustmentTest, ConvergesToTruthWithFixedKeyframesUntouched) {
  const StereoRig rig = KittiRig();
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    SCOPED_TRACE(seed);
    std::mt19937_64 rng(seed);
    BaSceneOptions scene_options;
    scene_options.num_keyframes = 6 + static_cast<int>(seed);  // 7..9
    const BaScene scene = MakeBaScene(rig, scene_options, rng);
    const std::vector<bool> all(scene.observations.size(), true);
    const double initial_rms =
        WhitenedRms(rig, Poses(scene.keyframes), Points(scene.points), scene.observations, all);
    ASSERT_GT(initial_rms, 5.0);

    BundleAdjustmentOptions options;
    options.function_tolerance = 1e-10;  // converge fully: compared with a second run below
    const BundleAdjustmentResult result =
        RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, options);
    ASSERT_EQ(result.cam_from_world.size(), scene.keyframes.size());
    ASSERT_EQ(result.p_in_world.size(), scene.points.size());
    ASSERT_EQ(result.observation_inlier.size(), scene.observations.size());

    // Started at the truth, BA lands on the same optimum as from the perturbed start: what is
    // left is the statistical error of the noisy data, not a convergence error.
    std::vector<BaKeyframe> keyframes_at_truth = scene.keyframes;
    for (size_t k = 0; k < scene.keyframes.size(); ++k)
      keyframes_at_truth[k].cam_from_world = scene.cam_from_world_true[k];
    std::vector<BaPoint> points_at_truth = scene.points;
    for (size_t j = 0; j < scene.points.size(); ++j)
      points_at_truth[j].p_in_world = scene.p_in_world_true[j];
    const BundleAdjustmentResult reference =
        RunBundleAdjustment(rig, keyframes_at_truth, points_at_truth, scene.observations, options);
    // With the default tolerance the solve stops a little earlier, within a millimetre.
    const BundleAdjustmentResult loose =
        RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations);

    for (size_t k = 0; k < scene.keyframes.size(); ++k) {
      if (scene.keyframes[k].fixed) {
        EXPECT_TRUE(BitwiseEqual(result.cam_from_world[k], scene.keyframes[k].cam_from_world));
        continue;
      }
      const SE3& truth = scene.cam_from_world_true[k];
      EXPECT_GT(CentreErrorM(scene.keyframes[k].cam_from_world, truth), 0.05);
      EXPECT_LT(CentreErrorM(result.cam_from_world[k], reference.cam_from_world[k]), 1e-4)
          << "keyframe " << k;
      EXPECT_LT(RotationErrorRad(result.cam_from_world[k], reference.cam_from_world[k]), 1e-5)
          << "keyframe " << k;
      EXPECT_LT(CentreErrorM(loose.cam_from_world[k], reference.cam_from_world[k]), 1e-3)
          << "keyframe " << k;
      // Up to 8 m from the fixed keyframes; 30 seeds gave at most 2.9 cm and 0.07 deg.
      EXPECT_LT(CentreErrorM(result.cam_from_world[k], truth), 0.035) << "keyframe " << k;
      EXPECT_LT(RotationErrorRad(result.cam_from_world[k], truth), 0.1 * kDegToRad)
          << "keyframe " << k;
    }
    const double final_rms = WhitenedRms(rig, result.cam_from_world, result.p_in_world,
                                         scene.observations, result.observation_inlier);
    EXPECT_LT(final_rms, 1.0);  // about 1 before the 95% bounds trim the tails
    EXPECT_LT(result.final_cost, 0.1 * result.initial_cost);
    const long inliers =
        std::count(result.observation_inlier.begin(), result.observation_inlier.end(), true);
    EXPECT_GT(inliers, 0.9 * scene.observations.size());
    EXPECT_GT(result.iterations, 0);
  }
}

TEST(BundleAdjustmentTest, NoiseFreeRecoversTruth) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(5);
  BaSceneOptions scene_options;
  scene_options.noise_px = 0.0;
  const BaScene scene = MakeBaScene(rig, scene_options, rng);
  ASSERT_GT(MedianPointError(Points(scene.points), scene.p_in_world_true), 0.1);
  BundleAdjustmentOptions options;
  options.max_iterations = 20;
  const BundleAdjustmentResult result =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, options);
  for (size_t k = 0; k < scene.keyframes.size(); ++k) {
    EXPECT_LT(CentreErrorM(result.cam_from_world[k], scene.cam_from_world_true[k]), 1e-6) << k;
    EXPECT_LT(RotationErrorRad(result.cam_from_world[k], scene.cam_from_world_true[k]), 1e-7) << k;
  }
  for (size_t j = 0; j < scene.points.size(); ++j) {
    const double depth_m = (scene.cam_from_world_true[0] * scene.p_in_world_true[j]).z();
    EXPECT_LT((result.p_in_world[j] - scene.p_in_world_true[j]).norm(), 1e-6 * depth_m) << j;
  }
  EXPECT_EQ(std::count(result.observation_inlier.begin(), result.observation_inlier.end(), true),
            static_cast<long>(scene.observations.size()));
  EXPECT_LT(result.final_cost, 1e-12);
}

TEST(BundleAdjustmentTest, GrossOutliersAreFlagged) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(10);
  BaSceneOptions scene_options;
  scene_options.outlier_fraction = 0.1;
  const BaScene scene = MakeBaScene(rig, scene_options, rng);
  for (bool twice : {true, false}) {
    SCOPED_TRACE(twice);
    BundleAdjustmentOptions options;
    options.optimise_twice = twice;
    const BundleAdjustmentResult result =
        RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, options);
    // A point seen once fits its only observation whatever it is: those cannot be detected.
    std::vector<int> num_observations(scene.points.size(), 0);
    for (const BaObservation& obs : scene.observations) ++num_observations[obs.point];
    int outliers = 0, good = 0, good_kept = 0;
    for (size_t i = 0; i < scene.observations.size(); ++i) {
      if (scene.is_gross_outlier[i]) {
        ++outliers;
        if (num_observations[scene.observations[i].point] > 1) {
          EXPECT_FALSE(result.observation_inlier[i]) << i;
        }
      } else {
        ++good;
        good_kept += result.observation_inlier[i] ? 1 : 0;
      }
    }
    EXPECT_GT(outliers, 50);
    EXPECT_GT(good_kept, 0.88 * good);
    for (size_t k = 2; k < scene.keyframes.size(); ++k) {
      EXPECT_LT(CentreErrorM(result.cam_from_world[k], scene.cam_from_world_true[k]), 0.04);
      EXPECT_LT(RotationErrorRad(result.cam_from_world[k], scene.cam_from_world_true[k]),
                0.15 * kDegToRad);
    }
  }
}

TEST(BundleAdjustmentTest, DeterministicOnRepeatedRuns) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(20);
  BaSceneOptions scene_options;
  scene_options.outlier_fraction = 0.05;
  const BaScene scene = MakeBaScene(rig, scene_options, rng);
  for (int dense_max : {40, 0}) {  // dense and sparse Schur
    BundleAdjustmentOptions options;
    options.dense_schur_max_keyframes = dense_max;
    const BundleAdjustmentResult a =
        RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, options);
    const BundleAdjustmentResult b =
        RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, options);
    ExpectBitwiseEqual(a, b);
  }
}

TEST(BundleAdjustmentTest, SolverChoiceAndThreadsAgree) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(30);
  const BaScene scene = MakeBaScene(rig, BaSceneOptions{}, rng);
  const BundleAdjustmentResult dense =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations);
  BundleAdjustmentOptions sparse_options;
  sparse_options.dense_schur_max_keyframes = 0;
  const BundleAdjustmentResult sparse =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, sparse_options);
  BundleAdjustmentOptions threaded_options;
  threaded_options.num_threads = 2;
  const BundleAdjustmentResult threaded =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, threaded_options);
  for (const BundleAdjustmentResult* other : {&sparse, &threaded}) {
    for (size_t k = 0; k < scene.keyframes.size(); ++k) {
      EXPECT_LT((other->cam_from_world[k].matrix() - dense.cam_from_world[k].matrix()).norm(),
                1e-6);
    }
    for (size_t j = 0; j < scene.points.size(); ++j)
      EXPECT_LT((other->p_in_world[j] - dense.p_in_world[j]).norm(), 1e-5);
    EXPECT_EQ(other->observation_inlier, dense.observation_inlier);
  }
}

TEST(BundleAdjustmentTest, MonocularWithTwoFixedKeyframes) {
  const StereoRig rig = optim_test::MonoRig();
  std::mt19937_64 rng(40);
  BaSceneOptions scene_options;
  scene_options.pose_perturbation_m = 0.05;
  scene_options.pose_perturbation_rad = 0.005;
  scene_options.point_perturbation_fraction = 0.01;
  const BaScene scene = MakeBaScene(rig, scene_options, rng);
  for (const BaObservation& obs : scene.observations) ASSERT_LT(obs.u_right_px, 0);
  BundleAdjustmentOptions options;
  options.max_iterations = 20;
  const BundleAdjustmentResult result =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, options);
  for (size_t k = 2; k < scene.keyframes.size(); ++k) {
    EXPECT_LT(CentreErrorM(result.cam_from_world[k], scene.cam_from_world_true[k]), 0.03) << k;
    EXPECT_LT(RotationErrorRad(result.cam_from_world[k], scene.cam_from_world_true[k]),
              0.1 * kDegToRad)
        << k;
  }
  EXPECT_LT(result.final_cost, 0.1 * result.initial_cost);
}

// As in the pose optimiser: the weight scales the cost, so an observation 6 px off stays an
// outlier however little the filter trusts it.
TEST(BundleAdjustmentTest, DownWeightedOutliersAreStillFlagged) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(51);
  BaSceneOptions scene_options;
  scene_options.num_points = 150;
  scene_options.noise_px = 0.3;
  BaScene scene = MakeBaScene(rig, scene_options, rng);
  std::vector<size_t> shifted;
  for (size_t i = 0; i < scene.observations.size(); i += 15) {
    BaObservation& obs = scene.observations[i];
    obs.uv_px += Eigen::Vector2d(0.0, 6.0);
    obs.weight = 0.1;
    shifted.push_back(i);
  }
  const BundleAdjustmentResult result =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations);
  for (size_t i : shifted) EXPECT_FALSE(result.observation_inlier[i]) << "observation " << i;
  int inliers = 0;
  for (bool in : result.observation_inlier) inliers += in ? 1 : 0;
  EXPECT_GT(inliers, static_cast<int>(0.85 * (scene.observations.size() - shifted.size())));
}

TEST(BundleAdjustmentTest, UnobservedBlocksAreReturnedUnchanged) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(50);
  BaSceneOptions scene_options;
  scene_options.num_points = 100;
  BaScene scene = MakeBaScene(rig, scene_options, rng);
  // An extra free keyframe and an extra point with no observations, and an observation with zero
  // weight (never used).
  BaKeyframe lonely;
  lonely.cam_from_world = optim_test::RandomPose(rng, 5.0, 1.0);
  scene.keyframes.push_back(lonely);
  BaPoint orphan;
  orphan.p_in_world = Eigen::Vector3d(1.0 / 3.0, 2.0 / 7.0, 30.0);
  scene.points.push_back(orphan);
  BaObservation zero_weight = scene.observations.front();
  zero_weight.weight = 0.0;
  scene.observations.push_back(zero_weight);

  const BundleAdjustmentResult result =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations);
  EXPECT_TRUE(BitwiseEqual(result.cam_from_world.back(), lonely.cam_from_world));
  EXPECT_EQ(result.p_in_world.back(), orphan.p_in_world);
  EXPECT_FALSE(result.observation_inlier.back());
}

// Two parts that share no point: the first held by its fixed keyframe, the second with none (a
// part of the map started after a tracking loss). The second part's oldest keyframe is held where
// it is, and the rest of that part lands where the truth puts it relative to that keyframe.
TEST(BundleAdjustmentTest, APartWithoutAFixedKeyframeIsHeldByItsOldest) {
  const StereoRig rig = KittiRig();
  std::mt19937_64 rng(5);
  BaSceneOptions held_options;
  held_options.noise_px = 0.0;
  held_options.num_fixed = 1;
  const BaScene held = MakeBaScene(rig, held_options, rng);
  BaSceneOptions free_options = held_options;
  free_options.num_fixed = 0;  // every keyframe free and perturbed, the first one included
  const BaScene free = MakeBaScene(rig, free_options, rng);

  std::vector<BaKeyframe> keyframes = held.keyframes;
  std::vector<BaPoint> points = held.points;
  std::vector<BaObservation> observations = held.observations;
  const int kf_offset = static_cast<int>(keyframes.size());
  const int point_offset = static_cast<int>(points.size());
  // The free part's keyframes come first in the vector but have the larger ids: the anchor is
  // picked by id, not by position.
  std::vector<BaKeyframe> free_keyframes = free.keyframes;
  for (BaKeyframe& kf : free_keyframes) kf.id += 1000;
  std::reverse(free_keyframes.begin(), free_keyframes.end());
  const int n_free = static_cast<int>(free_keyframes.size());
  keyframes.insert(keyframes.end(), free_keyframes.begin(), free_keyframes.end());
  for (BaPoint p : free.points) {
    p.id += 1000000;
    points.push_back(p);
  }
  for (BaObservation o : free.observations) {
    o.keyframe = kf_offset + (n_free - 1 - o.keyframe);  // reversed
    o.point += point_offset;
    observations.push_back(o);
  }
  const int anchor = kf_offset + n_free - 1;  // the free part's smallest id
  ASSERT_FALSE(keyframes[anchor].fixed);
  ASSERT_GT(CentreErrorM(keyframes[anchor].cam_from_world, free.cam_from_world_true[0]), 0.01);

  BundleAdjustmentOptions options;
  options.max_iterations = 30;
  options.function_tolerance = 1e-12;
  const BundleAdjustmentResult result =
      RunBundleAdjustment(rig, keyframes, points, observations, options);
  EXPECT_EQ(result.gauge_anchors, 1);
  EXPECT_TRUE(BitwiseEqual(result.cam_from_world[anchor], keyframes[anchor].cam_from_world));
  EXPECT_TRUE(BitwiseEqual(result.cam_from_world[0], held.keyframes[0].cam_from_world));
  for (int k = 1; k < kf_offset; ++k)
    EXPECT_LT(CentreErrorM(result.cam_from_world[k], held.cam_from_world_true[k]), 1e-6) << k;
  // The free part: the truth moved rigidly onto its held keyframe.
  const SE3 world_shift =
      keyframes[anchor].cam_from_world.inverse() * free.cam_from_world_true[0];  // est <- true
  for (int i = 0; i < n_free; ++i) {
    const int k = kf_offset + (n_free - 1 - i);
    const SE3 expected = free.cam_from_world_true[i] * world_shift.inverse();
    EXPECT_LT(CentreErrorM(result.cam_from_world[k], expected), 1e-6) << i;
    EXPECT_LT(RotationErrorRad(result.cam_from_world[k], expected), 1e-7) << i;
  }
  EXPECT_LT(result.final_cost, 1e-12);

  // With the free part's first keyframe fixed by the caller, nothing more is held.
  keyframes[anchor].fixed = true;
  EXPECT_EQ(RunBundleAdjustment(rig, keyframes, points, observations, options).gauge_anchors, 0);
}

TEST(BundleAdjustmentTest, EmptyProblemAndBadInput) {
  const StereoRig rig = KittiRig();
  std::vector<BaKeyframe> keyframes(2);
  keyframes[1].cam_from_world.translation() = Eigen::Vector3d(0.1, 0.2, 0.3);
  std::vector<BaPoint> points(1);
  const BundleAdjustmentResult empty = RunBundleAdjustment(rig, keyframes, points, {});
  EXPECT_TRUE(BitwiseEqual(empty.cam_from_world[1], keyframes[1].cam_from_world));
  EXPECT_EQ(empty.iterations, 0);

  BaObservation bad;
  bad.keyframe = 2;
  bad.point = 0;
  EXPECT_THROW(RunBundleAdjustment(rig, keyframes, points, {bad}), std::out_of_range);
  bad.keyframe = 0;
  bad.point = -1;
  EXPECT_THROW(RunBundleAdjustment(rig, keyframes, points, {bad}), std::out_of_range);

  BundleAdjustmentOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why));
  options.num_threads = 0;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("num_threads"), std::string::npos);
  EXPECT_THROW(RunBundleAdjustment(rig, keyframes, points, {}, options), ConfigError);
  options = {};
  options.max_iterations = 0;
  EXPECT_FALSE(options.IsValid(nullptr));
  options = {};
  options.chi2_mono = std::nan("");
  EXPECT_FALSE(options.IsValid(nullptr));
  options = {};
  options.function_tolerance = -1;
  EXPECT_FALSE(options.IsValid(nullptr));
}

}  // namespace
}  // namespace pcr
