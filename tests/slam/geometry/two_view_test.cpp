#include "slam/geometry/two_view.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <random>

#include "slam/common/error.h"
#include "slam/geometry/se3.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

using test::KittiCamera;

// Matched observations of a synthetic scene; the reference camera frame is the world frame.
struct Scene {
  SE3 cur_from_ref = SE3::Identity();
  std::vector<Eigen::Vector3d> points_in_ref;
  std::vector<Eigen::Vector2d> uv_ref, uv_cur;
  std::vector<bool> is_outlier;
};

SE3 MotionForward(const Eigen::Vector3d& omega_rad, const Eigen::Vector3d& centre_cur_in_ref) {
  SE3 cur_from_ref = SE3::Identity();
  cur_from_ref.linear() = ExpSO3(omega_rad);
  cur_from_ref.translation() = -cur_from_ref.linear() * centre_cur_in_ref;
  return cur_from_ref;
}

// Draws points from sample_point until n of them are seen in both images (10 px margin), then
// adds Gaussian pixel noise.
Scene MakeScene(const PinholeCamera& cam, const SE3& cur_from_ref, int n, double noise_px,
                uint32_t seed, const std::function<Eigen::Vector3d(std::mt19937&)>& sample) {
  Scene s;
  s.cur_from_ref = cur_from_ref;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_px);
  while (static_cast<int>(s.points_in_ref.size()) < n) {
    const Eigen::Vector3d p = sample(rng);
    const Eigen::Vector3d q = cur_from_ref * p;
    if (p.z() <= 0.5 || q.z() <= 0.5) continue;
    const Eigen::Vector2d a = cam.Project(p), b = cam.Project(q);
    if (!cam.InImage(a, 10) || !cam.InImage(b, 10)) continue;
    s.points_in_ref.push_back(p);
    s.uv_ref.push_back(a + Eigen::Vector2d(noise(rng), noise(rng)));
    s.uv_cur.push_back(b + Eigen::Vector2d(noise(rng), noise(rng)));
    s.is_outlier.push_back(false);
  }
  return s;
}

// General 3-D scene: pixels uniform over the reference image, depth uniform in [5, 50] m.
Scene GeneralScene(const SE3& cur_from_ref, int n, double noise_px, uint32_t seed) {
  const PinholeCamera cam = KittiCamera();
  return MakeScene(cam, cur_from_ref, n, noise_px, seed, [&cam](std::mt19937& rng) {
    std::uniform_real_distribution<double> u(0, cam.width_px - 1), v(0, cam.height_px - 1);
    std::uniform_real_distribution<double> z(5.0, 50.0);
    return cam.Unproject({u(rng), v(rng)}, z(rng));
  });
}

// KITTI-like forward motion: ~1 m ahead, small yaw/pitch/roll.
SE3 ForwardMotion() {
  return MotionForward({DegToRad(0.4), DegToRad(1.5), DegToRad(-0.3)}, {0.04, -0.02, 1.0});
}

void ExpectMotion(const TwoViewResult& r, const SE3& truth, double rot_tol_deg, double dir_tol_deg,
                  double* rot_err_deg = nullptr, double* dir_err_deg = nullptr) {
  ASSERT_TRUE(r.success) << r.failure_reason;
  const double rot = RadToDeg(RotationDistanceRad(r.cur_from_ref.linear(), truth.linear()));
  const double dir = RadToDeg(AngleBetweenRad(r.cur_from_ref.translation(), truth.translation()));
  EXPECT_LT(rot, rot_tol_deg);
  EXPECT_LT(dir, dir_tol_deg);
  EXPECT_NEAR(r.cur_from_ref.translation().norm(), 1.0, 1e-9);
  if (rot_err_deg) *rot_err_deg = rot;
  if (dir_err_deg) *dir_err_deg = dir;
  std::printf(
      "    H=%d ratio=%.3f inliers=%d triangulated=%d support=%d (runner-up %d) "
      "parallax=%.2f deg rot err %.4f deg, dir err %.4f deg\n",
      r.used_homography, r.homography_ratio, r.num_inliers, r.num_triangulated, r.best_support,
      r.runner_up_support, r.parallax_deg, rot, dir);
}

TEST(TwoView, GeneralSceneNoiseFreeIsExact) {
  const SE3 truth = ForwardMotion();
  const Scene s = GeneralScene(truth, 300, 0.0, 1);
  const TwoViewResult r = InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, TwoViewOptions{});
  ExpectMotion(r, truth, 1e-3, 1e-3);
  EXPECT_FALSE(r.used_homography);
  EXPECT_EQ(r.num_inliers, 300);
  // Points equal the truth once scaled by the true baseline length.
  const double scale = truth.translation().norm();
  int compared = 0;
  for (size_t i = 0; i < s.points_in_ref.size(); ++i) {
    if (!r.points_in_ref[i]) continue;
    ++compared;
    EXPECT_LT((scale * *r.points_in_ref[i] - s.points_in_ref[i]).norm(),
              1e-6 * s.points_in_ref[i].norm());
  }
  EXPECT_GT(compared, 200);
  EXPECT_EQ(compared, r.num_triangulated);
}

TEST(TwoView, GeneralSceneWithNoiseChoosesFundamental) {
  const SE3 truth = ForwardMotion();
  const Scene s = GeneralScene(truth, 400, 0.5, 2);
  const TwoViewResult r = InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, TwoViewOptions{});
  ExpectMotion(r, truth, 0.1, 1.0);
  EXPECT_FALSE(r.used_homography);
  EXPECT_LT(r.homography_ratio, 0.45);
  EXPECT_GT(r.parallax_deg, 1.0);
  EXPECT_LT(r.runner_up_support, r.best_support - 0.3 * r.num_triangulated);
  // Triangulated points match the truth up to scale. With 0.5 px noise, 1 m forward motion and
  // depths up to 50 m the depth of a typical point is only known to a few percent.
  const double scale = truth.translation().norm();
  std::vector<double> rel;
  for (size_t i = 0; i < s.points_in_ref.size(); ++i) {
    if (!r.points_in_ref[i]) continue;
    rel.push_back((scale * *r.points_in_ref[i] - s.points_in_ref[i]).norm() /
                  s.points_in_ref[i].norm());
  }
  ASSERT_GT(rel.size(), 200u);
  std::nth_element(rel.begin(), rel.begin() + rel.size() / 2, rel.end());
  EXPECT_LT(rel[rel.size() / 2], 0.05);
}

TEST(TwoView, DeterministicForSeed) {
  const Scene s = GeneralScene(ForwardMotion(), 300, 0.7, 3);
  TwoViewOptions opt;
  opt.seed = 99;
  const TwoViewResult a = InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, opt);
  const TwoViewResult b = InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, opt);
  ASSERT_TRUE(a.success) << a.failure_reason;
  EXPECT_EQ(a.cur_from_ref.matrix(), b.cur_from_ref.matrix());
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_EQ(a.score_fundamental, b.score_fundamental);
}

TEST(TwoView, WithTwentyPercentOutliers) {
  const SE3 truth = ForwardMotion();
  Scene s = GeneralScene(truth, 500, 0.5, 4);
  const PinholeCamera cam = KittiCamera();
  std::mt19937 rng(44);
  std::uniform_real_distribution<double> u(0, cam.width_px - 1), v(0, cam.height_px - 1);
  for (size_t i = 0; i < s.uv_cur.size(); i += 5) {  // every fifth match is wrong
    s.uv_cur[i] = {u(rng), v(rng)};
    s.is_outlier[i] = true;
  }
  const TwoViewResult r = InitializeTwoView(cam, s.uv_ref, s.uv_cur, TwoViewOptions{});
  ExpectMotion(r, truth, 0.1, 1.0);
  EXPECT_FALSE(r.used_homography);
  int outliers_kept = 0, outliers = 0, inliers_lost = 0;
  for (size_t i = 0; i < s.uv_cur.size(); ++i) {
    if (s.is_outlier[i]) {
      ++outliers;
      outliers_kept += r.inliers[i];
      EXPECT_FALSE(r.points_in_ref[i] && r.inliers[i] &&
                   (*r.points_in_ref[i] - s.points_in_ref[i] / truth.translation().norm()).norm() <
                       1e-3)
          << "an outlier cannot triangulate to the true point";
    } else {
      inliers_lost += !r.inliers[i];
    }
  }
  // A random match falls within ~2 px of its epipolar line a few percent of the time.
  EXPECT_LT(outliers_kept, outliers / 10);
  EXPECT_LT(inliers_lost, static_cast<int>(s.uv_cur.size()) / 50);
}

// Road surface 1.65 m below the camera (y down), 4-30 m ahead, 16 m wide.
Scene RoadScene(const SE3& cur_from_ref, double noise_px, uint32_t seed) {
  return MakeScene(KittiCamera(), cur_from_ref, 300, noise_px, seed, [](std::mt19937& rng) {
    std::uniform_real_distribution<double> x(-8.0, 8.0), z(4.0, 30.0);
    return Eigen::Vector3d(x(rng), 1.65, z(rng));
  });
}

TEST(TwoView, PlanarRoadSidewaysMotionChoosesHomography) {
  // A camera sliding 1 m sideways over the road: the second homography decomposition puts about
  // half of the points behind a camera, so the motion is unambiguous.
  const SE3 truth = MotionForward({DegToRad(0.3), DegToRad(-2.0), DegToRad(0.2)}, {1.0, 0.0, 0.0});
  const Scene s = RoadScene(truth, 0.5, 5);
  const TwoViewResult r = InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, TwoViewOptions{});
  ExpectMotion(r, truth, 0.1, 1.0);
  EXPECT_TRUE(r.used_homography);
  EXPECT_GT(r.homography_ratio, 0.45);
  // The reconstruction is the road: y = 1.65 m once scaled by the true baseline.
  const double scale = truth.translation().norm();
  int on_plane = 0;
  for (const auto& p : r.points_in_ref) {
    if (p && std::abs(scale * p->y() - 1.65) < 0.1) ++on_plane;  // ~6 %: depth noise at 30 m
  }
  EXPECT_GT(on_plane, 0.9 * r.num_triangulated);
}

TEST(TwoView, PlanarSceneNeverReturnsTheMirrorMotion) {
  // Driving forward over a plane (the road, or a facade beside it) the two homography
  // decompositions both keep every point in front of both cameras: two views cannot tell them
  // apart, and the initialisation must say so instead of picking one (an "ambiguous motion"
  // failure, two_view.h: the runner-up explains about as many correspondences as the best).
  const SE3 forward = MotionForward({DegToRad(0.3), DegToRad(-2.0), DegToRad(0.2)}, {0.1, 0, 1.2});
  const Scene road = RoadScene(forward, 0.5, 6);
  const Scene wall = MakeScene(KittiCamera(), forward, 300, 0.5, 7, [](std::mt19937& rng) {
    std::uniform_real_distribution<double> y(-4.0, 1.6), z(3.0, 40.0);
    return Eigen::Vector3d(6.0, y(rng), z(rng));  // facade 6 m to the right
  });
  for (const Scene* s : {&road, &wall}) {
    const TwoViewResult r =
        InitializeTwoView(KittiCamera(), s->uv_ref, s->uv_cur, TwoViewOptions{});
    std::printf("    planar, forward: H=%d ratio=%.3f support=%d runner-up=%d reason: %s\n",
                r.used_homography, r.homography_ratio, r.best_support, r.runner_up_support,
                r.failure_reason.c_str());
    EXPECT_TRUE(r.used_homography);
    EXPECT_FALSE(r.success);
    EXPECT_NE(r.failure_reason.find("ambiguous"), std::string::npos) << r.failure_reason;
    // Both decompositions explain (nearly) all 300 correspondences.
    EXPECT_GT(r.best_support, 280);
    EXPECT_GE(r.runner_up_support, 0.95 * r.best_support);
  }
}

TEST(TwoView, PureRotationFailsForLackOfParallax) {
  const SE3 truth = MotionForward({DegToRad(0.5), DegToRad(3.0), DegToRad(0.2)}, {0, 0, 0});
  const Scene s = GeneralScene(truth, 300, 0.5, 7);
  const TwoViewResult r = InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, TwoViewOptions{});
  std::printf("    pure rotation: H=%d ratio=%.3f reason: %s\n", r.used_homography,
              r.homography_ratio, r.failure_reason.c_str());
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.failure_reason.find("parallax"), std::string::npos) << r.failure_reason;
  EXPECT_TRUE(std::none_of(r.points_in_ref.begin(), r.points_in_ref.end(),
                           [](const auto& p) { return p.has_value(); }));
}

TEST(TwoView, TinyTranslationFailsForLackOfParallax) {
  const SE3 truth = MotionForward({DegToRad(0.2), DegToRad(1.0), 0.0}, {0.0, 0.0, 0.03});
  const Scene s = GeneralScene(truth, 300, 0.5, 8);
  const TwoViewResult r = InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, TwoViewOptions{});
  std::printf("    3 cm translation: H=%d ratio=%.3f reason: %s\n", r.used_homography,
              r.homography_ratio, r.failure_reason.c_str());
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.failure_reason.find("parallax"), std::string::npos) << r.failure_reason;
}

TEST(TwoView, TooFewMatchesAndBadInput) {
  const Scene s = GeneralScene(ForwardMotion(), 30, 0.5, 9);
  const TwoViewResult r = InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, TwoViewOptions{});
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.failure_reason.find("too few"), std::string::npos);
  std::vector<Eigen::Vector2d> shorter(s.uv_cur.begin(), s.uv_cur.end() - 1);
  EXPECT_THROW(InitializeTwoView(KittiCamera(), s.uv_ref, shorter, TwoViewOptions{}),
               std::invalid_argument);
  const Scene big = GeneralScene(ForwardMotion(), 100, 0.5, 9);
  std::vector<Eigen::Vector2d> with_nan = big.uv_cur;
  with_nan[5].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(InitializeTwoView(KittiCamera(), big.uv_ref, with_nan, TwoViewOptions{}),
               std::invalid_argument);
  TwoViewOptions bad;
  bad.min_parallax_deg = -1;
  EXPECT_THROW(InitializeTwoView(KittiCamera(), s.uv_ref, s.uv_cur, bad), ConfigError);
}

TEST(TwoView, EstimatorsSatisfyTheirConstraints) {
  const SE3 truth = ForwardMotion();
  const Scene s = GeneralScene(truth, 50, 0.0, 10);
  const auto F = EstimateFundamental(s.uv_ref, s.uv_cur);
  ASSERT_TRUE(F.has_value());
  EXPECT_NEAR(F->norm(), 1.0, 1e-12);
  EXPECT_LT(std::abs(F->determinant()), 1e-12);
  for (size_t i = 0; i < s.uv_ref.size(); ++i) {
    // Distance in pixels of the current point to the epipolar line.
    const Eigen::Vector3d line = *F * s.uv_ref[i].homogeneous();
    EXPECT_LT(std::abs(s.uv_cur[i].homogeneous().dot(line)) / line.head<2>().norm(), 1e-6);
  }
  // The essential matrix built from the true motion yields it among its four decompositions.
  const Eigen::Matrix3d E = Skew(truth.translation()) * truth.linear();
  const auto motions = DecomposeEssential(E);
  ASSERT_EQ(motions.size(), 4u);
  int matches = 0;
  for (const SE3& m : motions) {
    EXPECT_NEAR(m.linear().determinant(), 1.0, 1e-12);
    if (RotationDistanceRad(m.linear(), truth.linear()) < 1e-9 &&
        AngleBetweenRad(m.translation(), truth.translation()) < 1e-9) {
      ++matches;
    }
  }
  EXPECT_EQ(matches, 1);
  // Homography of 4+ points.
  const Eigen::Matrix3d H_true =
      (Eigen::Matrix3d() << 1.1, 0.02, 5, -0.03, 0.95, -7, 1e-5, 2e-5, 1).finished();
  std::vector<Eigen::Vector2d> from, to;
  for (int i = 0; i < 6; ++i) {
    from.emplace_back(100.0 + 150.0 * i, 50.0 + 37.0 * (i * i % 5));
    to.push_back((H_true * from.back().homogeneous()).hnormalized());
  }
  const auto H = EstimateHomography(from, to);
  ASSERT_TRUE(H.has_value());
  for (size_t i = 0; i < from.size(); ++i) {
    EXPECT_LT(((*H * from[i].homogeneous()).hnormalized() - to[i]).norm(), 1e-8);
  }
  // Collinear points are degenerate.
  std::vector<Eigen::Vector2d> line_pts = {{0, 0}, {1, 1}, {2, 2}, {3, 3}};
  EXPECT_FALSE(EstimateHomography(line_pts, line_pts).has_value());
}

}  // namespace
}  // namespace pcr
