#include "slam/geometry/sim3.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "support/test_helpers.h"

namespace pcr {
namespace {

Sim3 RandomSim3(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Sim3 s;
  s.scale = std::exp(u(rng));
  s.rotation = ExpSO3(test::RandomAxis(rng) * 2.5 * std::abs(u(rng)));
  s.translation = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 10.0;
  return s;
}

std::vector<Eigen::Vector3d> RandomPoints(std::mt19937_64& rng, int count) {
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < count; ++i) points.emplace_back(u(rng), u(rng), u(rng) + 10.0);
  return points;
}

void ExpectNear(const Sim3& a, const Sim3& b, double tol) {
  EXPECT_NEAR(a.scale, b.scale, tol);
  EXPECT_LT((a.rotation - b.rotation).norm(), tol);
  EXPECT_LT((a.translation - b.translation).norm(), tol);
}

TEST(Sim3, CompositionInverseAndMap) {
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 20; ++trial) {
    const Sim3 a_from_b = RandomSim3(rng), b_from_c = RandomSim3(rng);
    const Eigen::Vector3d p_in_c = RandomPoints(rng, 1)[0];
    EXPECT_LT(((a_from_b * b_from_c).Map(p_in_c) - a_from_b.Map(b_from_c.Map(p_in_c))).norm(),
              1e-9);
    ExpectNear(a_from_b * a_from_b.Inverse(), Sim3::Identity(), 1e-12);
    ExpectNear(a_from_b.Inverse() * a_from_b, Sim3::Identity(), 1e-12);
    EXPECT_LT((a_from_b.Inverse().Map(a_from_b.Map(p_in_c)) - p_in_c).norm(), 1e-10);
    EXPECT_LT((a_from_b.ToMatrix() * b_from_c.ToMatrix() - (a_from_b * b_from_c).ToMatrix()).norm(),
              1e-9);
    // ToSE3 drops the scale: the same camera centre and orientation.
    const SE3 rigid = a_from_b.ToSE3();
    EXPECT_LT((rigid * p_in_c - a_from_b.Map(p_in_c) / a_from_b.scale).norm(), 1e-10);
    EXPECT_LT((rigid.inverse().translation() - a_from_b.Inverse().translation).norm(), 1e-9);
  }
  SE3 pose = SE3::Identity();
  pose.linear() = ExpSO3(Eigen::Vector3d(0.3, -0.2, 0.5));
  pose.translation() = Eigen::Vector3d(1.0, -2.0, 3.0);
  const Sim3 s = Sim3::FromSE3(pose);
  EXPECT_EQ(s.scale, 1.0);
  EXPECT_TRUE(test::BitwiseEqual(s.ToSE3(), pose));
}

TEST(Sim3, AlignPointsRecoversAKnownSimilarity) {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 20; ++trial) {
    const Sim3 a_from_b = RandomSim3(rng);
    const std::vector<Eigen::Vector3d> p_b = RandomPoints(rng, 3 + trial);
    std::vector<Eigen::Vector3d> p_a;
    for (const Eigen::Vector3d& p : p_b) p_a.push_back(a_from_b.Map(p));
    const std::optional<Sim3> estimate = AlignPoints(p_a, p_b, /*fix_scale=*/false);
    ASSERT_TRUE(estimate.has_value());
    ExpectNear(*estimate, a_from_b, 1e-9);
  }
}

TEST(Sim3, AlignPointsWithFixedScaleIsRigid) {
  std::mt19937_64 rng(3);
  Sim3 a_from_b = RandomSim3(rng);
  a_from_b.scale = 1.0;
  const std::vector<Eigen::Vector3d> p_b = RandomPoints(rng, 10);
  std::vector<Eigen::Vector3d> p_a;
  for (const Eigen::Vector3d& p : p_b) p_a.push_back(a_from_b.Map(p));
  const std::optional<Sim3> rigid = AlignPoints(p_a, p_b, /*fix_scale=*/true);
  ASSERT_TRUE(rigid.has_value());
  EXPECT_EQ(rigid->scale, 1.0);
  ExpectNear(*rigid, a_from_b, 1e-9);

  // Scaled data with fix_scale: still scale 1 and a proper rotation.
  Sim3 scaled = a_from_b;
  scaled.scale = 2.0;
  for (size_t i = 0; i < p_b.size(); ++i) p_a[i] = scaled.Map(p_b[i]);
  const std::optional<Sim3> forced = AlignPoints(p_a, p_b, /*fix_scale=*/true);
  ASSERT_TRUE(forced.has_value());
  EXPECT_EQ(forced->scale, 1.0);
  EXPECT_NEAR(forced->rotation.determinant(), 1.0, 1e-12);
  EXPECT_LT((forced->rotation - a_from_b.rotation).norm(), 1e-9);
}

TEST(Sim3, AlignPointsRejectsDegenerateInput) {
  std::vector<Eigen::Vector3d> two = {{0, 0, 1}, {1, 0, 1}};
  EXPECT_FALSE(AlignPoints(two, two, false).has_value());
  std::vector<Eigen::Vector3d> collinear = {{0, 0, 1}, {1, 1, 2}, {2, 2, 3}, {-1, -1, 0}};
  EXPECT_FALSE(AlignPoints(collinear, collinear, false).has_value());
  EXPECT_FALSE(AlignPoints(collinear, collinear, true).has_value());
  std::vector<Eigen::Vector3d> same(4, Eigen::Vector3d(1, 2, 3));
  EXPECT_FALSE(AlignPoints(same, same, false).has_value());
  std::vector<Eigen::Vector3d> triangle = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  EXPECT_TRUE(AlignPoints(triangle, triangle, false).has_value());
  std::vector<Eigen::Vector3d> shorter(triangle.begin(), triangle.end() - 1);
  shorter.push_back({5, 5, 5});
  shorter.push_back({6, 5, 5});
  EXPECT_FALSE(AlignPoints(triangle, shorter, false).has_value());
  std::vector<Eigen::Vector3d> with_nan = triangle;
  with_nan[1].x() = std::nan("");
  EXPECT_FALSE(AlignPoints(with_nan, triangle, false).has_value());
}

}  // namespace
}  // namespace pcr
