// Motion stage: the ego-motion-compensated test per point (depth, epipolar, rotation-only), its
// noise model (Monte Carlo calibration), observability, PnP RANSAC ego-motion and LK tracking.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>
#include <tuple>

#include "filter_test_scene.h"
#include "slam/common/error.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/motion_score.h"
#include "slam/geometry/se3.h"
#include "support/texture_images.h"

namespace pcr {
namespace {

const PinholeCamera& Camera() {
  static const PinholeCamera camera = test::KittiRig().left;
  return camera;
}
double Bf() { return test::KittiRig().Bf(); }

// The camera moves 1 m forward: p_in_cur = p_in_prev - (0, 0, 1).
SE3 ForwardOneMetre() {
  SE3 cur_from_prev = SE3::Identity();
  cur_from_prev.translation() = Eigen::Vector3d(0.0, 0.0, -1.0);
  return cur_from_prev;
}

Eigen::Vector2d Px(const Eigen::Vector3d& p) { return Camera().Project(p); }

PointMotion Score(const Eigen::Vector3d& p_cur, double depth_m, const Eigen::Vector2d& prev_uv,
                  const SE3& cur_from_prev, const PointNoise& noise = {}) {
  return ScorePointMotion(Camera(), Bf(), Px(p_cur), depth_m, prev_uv, cur_from_prev.inverse(),
                          PoseSigma{0.001, 0.01}, noise, 0.5, Eigen::Vector3d::UnitZ(),
                          MotionScoreOptions{});
}

TEST(FilterMotion, RawFlowIsNotMotion) {
  const SE3 cur_from_prev = ForwardOneMetre();
  const SE3 prev_from_cur = cur_from_prev.inverse();
  // A static point 3 m ahead, low and to the right: it flows over 100 px.
  const Eigen::Vector3d near_cur(2.0, 1.2, 3.0);
  const Eigen::Vector2d near_prev_uv = Px(prev_from_cur * near_cur);
  const double near_flow = (Px(near_cur) - near_prev_uv).norm();
  EXPECT_GT(near_flow, 100.0);
  const PointMotion near = Score(near_cur, near_cur.z(), near_prev_uv, cur_from_prev);
  EXPECT_EQ(near.test, MotionTest::kDepth);
  EXPECT_GT(near.static_prob, 0.95);
  EXPECT_LT(near.residual_px, 1e-6);

  // A far point that moved 0.5 m sideways: it flows about 12 px, but not as a static point would.
  const Eigen::Vector3d far_cur(0.5, -1.0, 30.0);
  const Eigen::Vector3d far_prev_true = prev_from_cur * (far_cur - Eigen::Vector3d(0.5, 0, 0));
  const Eigen::Vector2d far_prev_uv = Px(far_prev_true);
  const double far_flow = (Px(far_cur) - far_prev_uv).norm();
  EXPECT_LT(far_flow, near_flow / 5.0);
  const PointMotion far = Score(far_cur, far_cur.z(), far_prev_uv, cur_from_prev);
  EXPECT_LT(far.static_prob, 0.05);
  EXPECT_NEAR(far.residual_px, 718.856 * 0.5 / 31.0, 0.5);
}

// A van 4 m ahead that keeps its distance, near the focus of expansion: its pixel hardly moves
// either way, so the 2-D test calls it static; its disparity, which a static point would have
// changed by 7 px over the 0.3 m the camera drove, gives it away.
TEST(FilterMotion, LeadVehicleKeepingItsDistanceIsSeenByThePreviousDisparity) {
  SE3 cur_from_prev = SE3::Identity();
  cur_from_prev.translation() = Eigen::Vector3d(0.0, 0.0, -0.3);
  const Eigen::Vector3d van_cur(0.05, -0.03, 4.0);
  const Eigen::Vector2d prev_uv = Px(van_cur);  // same place in the previous image
  PointNoise noise;
  const PointMotion flat = Score(van_cur, van_cur.z(), prev_uv, cur_from_prev, noise);
  EXPECT_FALSE(flat.with_disparity);
  EXPECT_GT(flat.static_prob, 0.5);
  noise.prev_disparity_px = Bf() / van_cur.z();  // the same disparity as now
  const PointMotion with = Score(van_cur, van_cur.z(), prev_uv, cur_from_prev, noise);
  EXPECT_EQ(with.test, MotionTest::kDepth);
  EXPECT_TRUE(with.with_disparity);
  EXPECT_LT(with.static_prob, 0.01);
  EXPECT_DOUBLE_EQ(with.residual_px, flat.residual_px);  // the pixel residual is unchanged
  EXPECT_GE(with.observability, flat.observability);

  // A static point at the same place: 0.3 m further away in the previous frame.
  const Eigen::Vector3d static_prev = cur_from_prev.inverse() * van_cur;
  noise.prev_disparity_px = Bf() / static_prev.z();
  const PointMotion still = Score(van_cur, van_cur.z(), Px(static_prev), cur_from_prev, noise);
  EXPECT_TRUE(still.with_disparity);
  EXPECT_GT(still.static_prob, 0.99);
}

// Static points with noise drawn from the model the depth test assumes (pose, both positions,
// disparity; with_disparity: also the previous frame's disparity). Returns the mean squared
// Mahalanobis distance and the fraction flagged (static probability under 0.5).
struct Calibration {
  double mean_chi2 = 0.0;
  double flagged_fraction = 0.0;
};
Calibration StaticDepthTestCalibration(uint64_t seed, bool with_disparity) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const PoseSigma pose{0.002, 0.03};
  PointNoise noise;
  noise.cur_sigma_px = 1.0;
  noise.prev_sigma_px = 1.0;
  noise.disparity_sigma_px = 0.5;
  const MotionScoreOptions options;
  double sum_chi2 = 0.0;
  int flagged = 0;
  const int trials = 4000;
  for (int t = 0; t < trials; ++t) {
    const Eigen::Vector3d p_cur(u(rng) * 16 - 8, u(rng) * 3 - 1.5, 3.0 + u(rng) * 40.0);
    const SE3 cur_from_prev = ForwardOneMetre();
    // True previous position under a perturbed (true) motion; the test sees the nominal one.
    Vector6d twist;
    twist << pose.translation_m * g(rng), pose.translation_m * g(rng), pose.translation_m * g(rng),
        pose.rotation_rad * g(rng), pose.rotation_rad * g(rng), pose.rotation_rad * g(rng);
    const Eigen::Vector3d p_prev = ExpSE3(twist) * cur_from_prev.inverse() * p_cur;
    const Eigen::Vector2d prev_uv =
        Px(p_prev) + noise.prev_sigma_px * Eigen::Vector2d(g(rng), g(rng));
    const Eigen::Vector2d cur_uv = Px(p_cur) + noise.cur_sigma_px * Eigen::Vector2d(g(rng), g(rng));
    const double depth = Bf() / (Bf() / p_cur.z() + noise.disparity_sigma_px * g(rng));
    PointNoise used = noise;
    if (with_disparity)
      used.prev_disparity_px = Bf() / p_prev.z() + noise.disparity_sigma_px * g(rng);
    const PointMotion m =
        ScorePointMotion(Camera(), Bf(), cur_uv, depth, prev_uv, cur_from_prev.inverse(), pose,
                         used, 0.5, Eigen::Vector3d::UnitZ(), options);
    EXPECT_EQ(m.test, MotionTest::kDepth);
    EXPECT_EQ(m.with_disparity, with_disparity);
    sum_chi2 += m.chi2;
    flagged += m.static_prob < 0.5 ? 1 : 0;
  }
  return {sum_chi2 / trials, static_cast<double>(flagged) / trials};
}

// The 3-dof test under its own noise model: the squared Mahalanobis distance averages 3 and the
// 99% quantile flags about 1%.
TEST(FilterMotion, DisparityTestIsCalibratedOnStaticPoints) {
  const Calibration c = StaticDepthTestCalibration(11, true);
  EXPECT_GT(c.mean_chi2, 2.4);
  EXPECT_LT(c.mean_chi2, 3.6);
  EXPECT_LT(c.flagged_fraction, 0.02);
}

// The 2-dof test: the squared Mahalanobis distance averages 2, few static points flagged.
TEST(FilterMotion, NoiseModelIsCalibratedOnStaticPoints) {
  const Calibration c = StaticDepthTestCalibration(7, false);
  EXPECT_GT(c.mean_chi2, 1.6);
  EXPECT_LT(c.mean_chi2, 2.5);
  EXPECT_LT(c.flagged_fraction, 0.03);
}

TEST(FilterMotion, EpipolarTestWithoutDepth) {
  const SE3 cur_from_prev = ForwardOneMetre();
  const SE3 prev_from_cur = cur_from_prev.inverse();
  const Eigen::Vector3d p_cur(-3.0, -0.5, 12.0);
  const Eigen::Vector2d prev_static = Px(prev_from_cur * p_cur);
  const PointMotion still = Score(p_cur, -1.0, prev_static, cur_from_prev);
  EXPECT_EQ(still.test, MotionTest::kEpipolar);
  EXPECT_GT(still.static_prob, 0.9);
  EXPECT_EQ(still.observability, 0.0);
  EXPECT_EQ(GateByObservability(still.static_prob, still.observability), 0.5);

  // Off the epipolar line (it runs through the focus of expansion, the principal point): flagged.
  const Eigen::Vector2d radial =
      (Px(p_cur) - Eigen::Vector2d(Camera().cx, Camera().cy)).normalized();
  const Eigen::Vector2d across(-radial.y(), radial.x());
  const PointMotion off = Score(p_cur, -1.0, prev_static + 8.0 * across, cur_from_prev);
  EXPECT_LT(off.static_prob, 0.05);
  EXPECT_NEAR(off.residual_px, 8.0 / std::sqrt(2.0), 1.5);  // Sampson splits it over both views
  // Along the line: invisible without depth (it is the depth ambiguity itself).
  const PointMotion along = Score(p_cur, -1.0, prev_static + 8.0 * radial, cur_from_prev);
  EXPECT_GT(along.static_prob, 0.9);
  // With depth the same displacement is seen.
  const PointMotion along_depth =
      Score(p_cur, p_cur.z(), prev_static + 8.0 * radial, cur_from_prev);
  EXPECT_LT(along_depth.static_prob, 0.1);
}

TEST(FilterMotion, RotationOnlyMotionUsesTheInfiniteHomography) {
  SE3 cur_from_prev = SE3::Identity();
  cur_from_prev.linear() = ExpSO3(Eigen::Vector3d(0.0, DegToRad(2.0), 0.0));
  const Eigen::Vector3d p_cur(1.0, 0.5, 20.0);
  const Eigen::Vector2d prev_uv = Px(cur_from_prev.inverse() * p_cur);
  EXPECT_GT((prev_uv - Px(p_cur)).norm(), 20.0);  // the rotation alone moves it 25 px
  const PointMotion still = Score(p_cur, -1.0, prev_uv, cur_from_prev);
  EXPECT_EQ(still.test, MotionTest::kRotation);
  EXPECT_GT(still.static_prob, 0.95);
  const PointMotion moved = Score(p_cur, -1.0, prev_uv + Eigen::Vector2d(0.0, 15.0), cur_from_prev);
  EXPECT_LT(moved.static_prob, 0.05);
}

TEST(FilterMotion, ObservabilityOfMotionAlongTheTravelDirection) {
  const SE3 cur_from_prev = ForwardOneMetre();
  const SE3 prev_from_cur = cur_from_prev.inverse();
  // Far ahead, near the image centre: a car driving along the road there is invisible.
  const Eigen::Vector3d ahead(0.3, 0.5, 40.0);
  const PointMotion far = Score(ahead, ahead.z(), Px(prev_from_cur * ahead), cur_from_prev);
  EXPECT_LT(far.observability, 0.2);
  // Near and to the side: such a motion shifts it by many sigmas.
  const Eigen::Vector3d side(4.0, 0.5, 10.0);
  const PointMotion near = Score(side, side.z(), Px(prev_from_cur * side), cur_from_prev);
  EXPECT_EQ(near.observability, 1.0);
  EXPECT_EQ(GateByObservability(near.static_prob, near.observability), near.static_prob);
  // Motion evidence is never weakened by the gate.
  EXPECT_EQ(GateByObservability(0.1, 0.0), 0.1);
}

TEST(FilterMotion, StaticProbabilityIsAMonotoneLogistic) {
  MotionScoreOptions options;
  EXPECT_NEAR(StaticProbabilityFromChi2(options.chi2_mid_2dof, 2, options), 0.5, 1e-12);
  EXPECT_NEAR(StaticProbabilityFromChi2(options.chi2_mid_1dof, 1, options), 0.5, 1e-12);
  double last = 1.0;
  for (double chi2 = 0.0; chi2 < 40.0; chi2 += 0.5) {
    const double p = StaticProbabilityFromChi2(chi2, 2, options);
    EXPECT_LE(p, last);
    last = p;
  }
  EXPECT_GT(StaticProbabilityFromChi2(0.0, 2, options), 0.98);
  EXPECT_LT(StaticProbabilityFromChi2(25.0, 2, options), 0.001);
  EXPECT_EQ(StaticProbabilityFromChi2(1e6, 2, options), 0.0);
}

TEST(FilterMotion, PnpRansacRecoversTheCameraMotionDespiteMovingPoints) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 0.3);
  SE3 cur_from_prev = SE3::Identity();
  cur_from_prev.linear() = ExpSO3(Eigen::Vector3d(0.01, -0.02, 0.005));
  cur_from_prev.translation() = Eigen::Vector3d(0.05, -0.02, -1.1);
  const SE3 prev_from_cur = cur_from_prev.inverse();
  std::vector<cv::Point2f> cur_uv, prev_uv;
  std::vector<float> depth;
  std::vector<uint8_t> usable;
  std::vector<bool> outlier;
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d p(u(rng) * 20 - 10, u(rng) * 4 - 2.5, 4.0 + u(rng) * 30.0);
    Eigen::Vector2d prev = Px(prev_from_cur * p);
    const bool moving = i % 10 < 3;  // 30% on moving objects
    if (moving) prev += Eigen::Vector2d(15.0 + 20.0 * u(rng), 5.0 * u(rng));
    const Eigen::Vector2d cur = Px(p);
    cur_uv.emplace_back(static_cast<float>(cur.x() + g(rng)), static_cast<float>(cur.y() + g(rng)));
    prev_uv.emplace_back(static_cast<float>(prev.x() + g(rng)),
                         static_cast<float>(prev.y() + g(rng)));
    depth.push_back(static_cast<float>(p.z()));
    usable.push_back(1);
    outlier.push_back(moving);
  }
  const EgoMotionEstimate est =
      EstimateCurFromPrev(Camera(), cur_uv, depth, prev_uv, usable, nullptr, EgoMotionOptions{});
  ASSERT_TRUE(est.success) << est.failure_reason;
  const SE3 error = cur_from_prev.inverse() * est.cur_from_prev;
  EXPECT_LT(RadToDeg(RotationAngleRad(error.linear())), 0.03);
  EXPECT_LT(error.translation().norm(), 0.01);
  int wrong = 0;
  for (size_t i = 0; i < outlier.size(); ++i) wrong += (est.inliers[i] != 0) == outlier[i] ? 1 : 0;
  EXPECT_LE(wrong, 4);
  EXPECT_EQ(est.num_candidates, 400);

  // Too few usable points: a failure value, not an exception.
  std::fill(usable.begin() + 10, usable.end(), 0);
  const EgoMotionEstimate few =
      EstimateCurFromPrev(Camera(), cur_uv, depth, prev_uv, usable, nullptr, EgoMotionOptions{});
  EXPECT_FALSE(few.success);
  EXPECT_FALSE(few.failure_reason.empty());
  // Mismatched sizes: an error.
  depth.pop_back();
  EXPECT_THROW(
      EstimateCurFromPrev(Camera(), cur_uv, depth, prev_uv, usable, nullptr, EgoMotionOptions{}),
      std::invalid_argument);
}

TEST(FilterMotion, LucasKanadeTracksAShiftedTextureAndRejectsChangedPatches) {
  cv::Mat prev(376, 1241, CV_8U);
  cv::RNG rng(11);
  rng.fill(prev, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(prev, prev, cv::Size(0, 0), 2.0);
  cv::normalize(prev, prev, 0, 255, cv::NORM_MINMAX);
  // The current image is the previous one shifted by (7.3, -2.6) px: cur(x) = prev(x - shift).
  const cv::Point2f shift(7.3f, -2.6f);
  cv::Mat cur = test::Shifted(prev, shift.x, shift.y, cv::INTER_CUBIC);
  // A patch of the current image replaced by new texture (something moved in).
  const cv::Rect changed(800, 100, 120, 120);
  cv::Mat fresh(changed.size(), CV_8U);
  rng.fill(fresh, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(fresh, fresh, cv::Size(0, 0), 2.0);
  cv::normalize(fresh, fresh, 0, 255, cv::NORM_MINMAX);
  fresh.copyTo(cur(changed));

  std::vector<cv::Point2f> pts;
  for (int v = 40; v < 336; v += 24) {
    for (int u = 40; u < 1200; u += 24) pts.emplace_back(u + 0.25f, v + 0.5f);
  }
  const LkOptions options;
  const FlowTracks tracks =
      TrackIntoPrevious(BuildLkPyramid(prev, options), BuildLkPyramid(cur, options), pts, options);
  int inside_changed = 0, valid_changed = 0, outside = 0, valid_outside = 0;
  std::vector<double> errors;
  for (size_t i = 0; i < pts.size(); ++i) {
    const cv::Rect core(changed.x + 15, changed.y + 15, changed.width - 30, changed.height - 30);
    if (core.contains(pts[i])) {
      ++inside_changed;
      valid_changed += tracks.valid[i];
      continue;
    }
    if ((cv::Rect(changed.x - 15, changed.y - 15, changed.width + 30, changed.height + 30))
            .contains(pts[i])) {
      continue;  // windows straddling the border of the patch
    }
    ++outside;
    if (!tracks.valid[i]) continue;
    ++valid_outside;
    errors.push_back(cv::norm(tracks.prev_uv_px[i] - (pts[i] - shift)));
  }
  EXPECT_GE(valid_outside, 0.97 * outside);
  std::sort(errors.begin(), errors.end());
  ASSERT_FALSE(errors.empty());
  // (The cubic warp that made the current image contributes a few hundredths of a pixel.)
  EXPECT_LT(errors[errors.size() / 2], 0.1);
  EXPECT_LT(errors[errors.size() * 95 / 100], 0.25);
  EXPECT_GT(inside_changed, 10);
  EXPECT_LE(valid_changed, 0.2 * inside_changed);
  EXPECT_EQ(tracks.num_valid,
            static_cast<int>(std::count(tracks.valid.begin(), tracks.valid.end(), 1)));
}

TEST(FilterMotion, LucasKanadeGuessDoesNotBiasInformativeMatchesAndEdgesAreNotTracked) {
  const LkOptions options;
  // Textured image moved by (6, 2) px: from a guess 6 px off, LK still finds the true match, and
  // the guess search does not pull it anywhere else.
  const cv::Mat prev = test::RandomTexture({400, 200}, 5, 1.5, /*stretch=*/true);
  const cv::Mat cur = test::Shifted(prev, 6, 2);
  std::vector<cv::Point2f> pts, guess, bad_guess;
  for (int v = 50; v <= 150; v += 25) {
    for (int u = 80; u <= 320; u += 40) {
      pts.emplace_back(static_cast<float>(u), static_cast<float>(v));
      guess.push_back(pts.back());           // "static": no motion expected
      bad_guess.emplace_back(-1.0f, -1.0f);  // no guess for these
    }
  }
  const auto prev_pyr = BuildLkPyramid(prev, options), cur_pyr = BuildLkPyramid(cur, options);
  const FlowTracks with_guess = TrackIntoPrevious(prev_pyr, cur_pyr, pts, options, guess);
  const FlowTracks no_guess = TrackIntoPrevious(prev_pyr, cur_pyr, pts, options, bad_guess);
  for (size_t i = 0; i < pts.size(); ++i) {
    const cv::Point2f truth = pts[i] - cv::Point2f(6, 2);
    ASSERT_TRUE(with_guess.valid[i]);
    ASSERT_TRUE(no_guess.valid[i]);
    EXPECT_LT(cv::norm(with_guess.prev_uv_px[i] - truth), 0.2);
    EXPECT_LT(cv::norm(no_guess.prev_uv_px[i] - truth), 0.2);
    EXPECT_EQ(no_guess.from_guess[i], 0);
  }

  // A straight edge (no texture along it) is not tracked at all, from zero flow or from a
  // guess: the aperture problem yields no observation rather than a false motion.
  cv::Mat edge_prev(200, 400, CV_8U, cv::Scalar(60));
  edge_prev(cv::Rect(200, 0, 200, 200)).setTo(200);
  cv::GaussianBlur(edge_prev, edge_prev, cv::Size(0, 0), 1.0);
  cv::Mat edge_cur;
  cv::warpAffine(edge_prev, edge_cur, cv::Matx23d(1, 0, 5, 0, 1, 0), edge_prev.size(),
                 cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  const std::vector<cv::Point2f> on_edge = {{205.0f, 100.0f}};
  const auto ep = BuildLkPyramid(edge_prev, options), ec = BuildLkPyramid(edge_cur, options);
  EXPECT_EQ(TrackIntoPrevious(ep, ec, on_edge, options).num_valid, 0);
  EXPECT_EQ(TrackIntoPrevious(ep, ec, on_edge, options, {{200.0f, 103.0f}}).num_valid, 0);
  EXPECT_THROW(TrackIntoPrevious(ep, ec, on_edge, options, guess), std::invalid_argument);
}

// A FlowEngine that records each pass and runs it on OpenCV.
class RecordingFlowEngine final : public FlowEngine {
 public:
  struct Call {
    const std::vector<cv::Mat>* from;
    size_t points;
    LkPass pass;
  };
  void Track(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
             const std::vector<cv::Point2f>& from_pts, std::vector<cv::Point2f>& to_pts,
             std::vector<uint8_t>& status, std::vector<float>& error, const LkPass& pass) override {
    calls.push_back({&from, from_pts.size(), pass});
    opencv_->Track(from, to, from_pts, to_pts, status, error, pass);
  }
  std::string Name() const override { return "recording"; }
  std::vector<Call> calls;

 private:
  std::unique_ptr<FlowEngine> opencv_ = MakeOpenCvFlowEngine();
};

TEST(FilterMotion, TheLucasKanadePassesRunOnTheGivenEngine) {
  LkOptions options;
  options.guess_accept_error_factor = 0.0;  // the zero-flow search runs for every point
  const cv::Mat prev = test::RandomTexture({400, 200}, 9, 1.5, /*stretch=*/false);
  const cv::Mat cur = test::Shifted(prev, 4, 1);
  std::vector<cv::Point2f> pts, guess;
  for (int v = 40; v <= 160; v += 30) {
    for (int u = 60; u <= 340; u += 35) {
      pts.emplace_back(static_cast<float>(u), static_cast<float>(v));
      guess.push_back(pts.back() - cv::Point2f(3.5f, 1.0f));
    }
  }
  const auto prev_pyr = BuildLkPyramid(prev, options), cur_pyr = BuildLkPyramid(cur, options);
  RecordingFlowEngine engine;
  const FlowTracks on_engine = TrackIntoPrevious(prev_pyr, cur_pyr, pts, options, guess, &engine);
  const FlowTracks on_opencv = TrackIntoPrevious(prev_pyr, cur_pyr, pts, options, guess);
  EXPECT_EQ(on_engine.prev_uv_px, on_opencv.prev_uv_px);
  EXPECT_EQ(on_engine.valid, on_opencv.valid);
  EXPECT_EQ(on_engine.forward_backward_px, on_opencv.forward_backward_px);
  EXPECT_GT(on_engine.num_valid, static_cast<int>(pts.size()) / 2);
  // The guess on the fine levels, the search from zero flow over the pyramid, the round trip.
  ASSERT_EQ(engine.calls.size(), 3u);
  const auto& [guess_call, zero_call, back_call] =
      std::tie(engine.calls[0], engine.calls[1], engine.calls[2]);
  EXPECT_EQ(guess_call.from, &cur_pyr);
  EXPECT_TRUE(guess_call.pass.use_initial_flow);
  EXPECT_EQ(guess_call.pass.max_level, options.refine_max_level);
  EXPECT_EQ(zero_call.from, &cur_pyr);
  EXPECT_FALSE(zero_call.pass.use_initial_flow);
  EXPECT_EQ(zero_call.pass.max_level, options.max_level);
  EXPECT_EQ(zero_call.points, pts.size());
  EXPECT_EQ(back_call.from, &prev_pyr);
  EXPECT_TRUE(back_call.pass.use_initial_flow);
  EXPECT_EQ(back_call.pass.max_level, options.max_level);
  for (const auto& call : engine.calls) {
    EXPECT_EQ(call.pass.window_px, options.window_px);
    EXPECT_EQ(call.pass.max_iterations, options.max_iterations);
    EXPECT_EQ(call.pass.epsilon_px, options.epsilon_px);
    EXPECT_EQ(call.pass.min_eigen_threshold, options.min_eigen_threshold);
  }
  // A filter takes its engine from its options; a factory that makes none is a config error.
  DynamicFilterOptions filter_options;
  EXPECT_EQ(DynamicFilter(filter_options).flow_engine().Name(), "opencv");
  filter_options.flow_factory = [] { return std::make_unique<RecordingFlowEngine>(); };
  EXPECT_EQ(DynamicFilter(filter_options).flow_engine().Name(), "recording");
  filter_options.flow_factory = [] { return std::unique_ptr<FlowEngine>(); };
  EXPECT_THROW(DynamicFilter{filter_options}, ConfigError);
}

TEST(FilterMotion, InvalidOptionsAreRejected) {
  std::string why;
  LkOptions lk;
  lk.window_px = 20;
  EXPECT_FALSE(lk.IsValid(&why));
  EXPECT_NE(why.find("window_px"), std::string::npos);
  EgoMotionOptions ego;
  ego.min_depth_m = 50.0;
  EXPECT_FALSE(ego.IsValid(&why));
  MotionScoreOptions motion;
  motion.chi2_width = 0.0;
  EXPECT_FALSE(motion.IsValid(&why));
  EXPECT_TRUE(LkOptions{}.IsValid(&why));
  EXPECT_TRUE(EgoMotionOptions{}.IsValid(&why));
  EXPECT_TRUE(MotionScoreOptions{}.IsValid(&why));
  const std::vector<cv::Mat> none;
  EXPECT_THROW(TrackIntoPrevious(none, none, {}, lk), ConfigError);
  EXPECT_THROW(BuildLkPyramid(cv::Mat(), LkOptions{}), std::invalid_argument);
}

}  // namespace
}  // namespace pcr
