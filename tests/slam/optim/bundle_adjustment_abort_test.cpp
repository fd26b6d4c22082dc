// The abort flag of RunBundleAdjustment (BundleAdjustmentOptions::abort).
#include <gtest/gtest.h>

#include <atomic>
#include <random>

#include "optim_test_scene.h"
#include "slam/optim/bundle_adjustment.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

TEST(BundleAdjustmentAbortTest, SetBeforeTheSolveReturnsTheInput) {
  const StereoRig rig = optim_test::KittiRig();
  std::mt19937_64 rng(41);
  const optim_test::BaScene scene = optim_test::MakeBaScene(rig, {}, rng);
  std::atomic<bool> abort{true};
  BundleAdjustmentOptions options;
  options.abort = &abort;
  const BundleAdjustmentResult result =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, options);
  EXPECT_TRUE(result.aborted);
  EXPECT_EQ(result.iterations, 0);
  EXPECT_EQ(result.final_cost, result.initial_cost);
  ASSERT_EQ(result.cam_from_world.size(), scene.keyframes.size());
  ASSERT_EQ(result.p_in_world.size(), scene.points.size());
  ASSERT_EQ(result.observation_inlier.size(), scene.observations.size());
  for (size_t k = 0; k < scene.keyframes.size(); ++k)
    EXPECT_TRUE(test::BitwiseEqual(result.cam_from_world[k], scene.keyframes[k].cam_from_world));
  for (size_t j = 0; j < scene.points.size(); ++j)
    EXPECT_EQ(result.p_in_world[j], scene.points[j].p_in_world);
}

TEST(BundleAdjustmentAbortTest, ClearFlagIsBitwiseTheSameAsNoFlag) {
  const StereoRig rig = optim_test::KittiRig();
  std::mt19937_64 rng(42);
  const optim_test::BaScene scene = optim_test::MakeBaScene(rig, {}, rng);
  std::atomic<bool> abort{false};
  BundleAdjustmentOptions options;
  options.abort = &abort;
  const BundleAdjustmentResult with_flag =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, options);
  const BundleAdjustmentResult without =
      RunBundleAdjustment(rig, scene.keyframes, scene.points, scene.observations, {});
  EXPECT_FALSE(with_flag.aborted);
  EXPECT_FALSE(without.aborted);
  EXPECT_EQ(with_flag.iterations, without.iterations);
  EXPECT_EQ(with_flag.final_cost, without.final_cost);
  EXPECT_EQ(with_flag.observation_inlier, without.observation_inlier);
  for (size_t k = 0; k < scene.keyframes.size(); ++k)
    EXPECT_TRUE(test::BitwiseEqual(with_flag.cam_from_world[k], without.cam_from_world[k]));
  for (size_t j = 0; j < scene.points.size(); ++j)
    EXPECT_EQ(with_flag.p_in_world[j], without.p_in_world[j]);
}

}  // namespace
}  // namespace pcr
