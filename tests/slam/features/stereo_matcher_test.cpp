#include "slam/features/stereo_matcher.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "feature_test_images.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

// Rig of the brief for synthetic pairs (KITTI 00-02 intrinsics).
StereoRig SyntheticRig(cv::Size size) {
  StereoRig rig;
  rig.left = {718.856, 718.856, size.width / 2.0, size.height / 2.0, size.width, size.height};
  rig.baseline_m = 0.537;
  return rig;
}

// KITTI sequence 06 (recorded 2011-09-30): P0/P1 of its calib.txt, baseline 379.8145 / fx.
StereoRig KittiSeq06Rig() {
  StereoRig rig;
  rig.left = {707.0912, 707.0912, 601.8873, 183.1104, 1226, 370};
  rig.baseline_m = 379.8145 / 707.0912;
  return rig;
}

// The matcher is measured on the extractor setting that re-detects the same corners in both
// images most often (quadtree_oversplit 2); the SLAM default (1) spreads corners more evenly and
// matches fewer of them (KittiDefaultExtractorStillMatchesHalf below).
const OrbExtractor& Extractor() {
  static const OrbExtractor extractor{[] {
    OrbOptions o;
    o.quadtree_oversplit = 2.0;
    return o;
  }()};
  return extractor;
}

// right(x, y) = left(x + disparity, y): a fronto-parallel scene at depth Bf / disparity.
cv::Mat ShiftLeft(const cv::Mat& left, double disparity_px) {
  const cv::Mat m = (cv::Mat_<double>(2, 3) << 1, 0, disparity_px, 0, 1, 0);
  cv::Mat right;
  cv::warpAffine(left, right, m, left.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                 cv::BORDER_REFLECT_101);
  return right;
}

struct SyntheticResult {
  int n_left = 0;
  int matched = 0;
  std::vector<double> abs_errors_px;  // |disparity - true disparity| per match, ascending

  int WithinPx(double tolerance) const {
    return static_cast<int>(
        std::lower_bound(abs_errors_px.begin(), abs_errors_px.end(), tolerance) -
        abs_errors_px.begin());
  }
  double Median() const { return abs_errors_px[abs_errors_px.size() / 2]; }
};

// right(x, y) = left(x + d0 + g (y - y0), y): a plane whose disparity grows by g per row, as a
// road's does (~0.33 px per row at KITTI geometry); d0 at row y0.
cv::Mat ShearLeft(const cv::Mat& left, double d0, double g, double y0) {
  const cv::Mat m = (cv::Mat_<double>(2, 3) << 1, g, d0 - g * y0, 0, 1, 0);
  cv::Mat right;
  cv::warpAffine(left, right, m, left.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                 cv::BORDER_REFLECT_101);
  return right;
}

// truth_px: the true disparity at a left keypoint.
SyntheticResult RunSynthetic(const cv::Mat& left, const cv::Mat& right,
                             const std::function<double(const cv::Point2f&)>& truth_px,
                             const StereoMatchOptions& options = {}) {
  const StereoRig rig = SyntheticRig(left.size());
  const OrbFeatures fl = Extractor().Extract(left);
  const OrbFeatures fr = Extractor().Extract(right);
  const StereoMatches m = MatchStereo(rig, fl, fr, Extractor().scale_factors(), options);
  SyntheticResult r;
  r.n_left = static_cast<int>(fl.keypoints.size());
  EXPECT_EQ(m.u_right_px.size(), fl.keypoints.size());
  EXPECT_EQ(m.depth_m.size(), fl.keypoints.size());
  for (size_t i = 0; i < fl.keypoints.size(); ++i) {
    if (m.u_right_px[i] < 0) {
      EXPECT_EQ(m.depth_m[i], -1.0f);
      continue;
    }
    const double disparity = fl.keypoints[i].pt.x - m.u_right_px[i];
    EXPECT_NEAR(m.depth_m[i], rig.Bf() / disparity, 1e-3 * m.depth_m[i]);
    r.abs_errors_px.push_back(std::abs(disparity - truth_px(fl.keypoints[i].pt)));
  }
  std::sort(r.abs_errors_px.begin(), r.abs_errors_px.end());
  r.matched = m.num_matched;
  EXPECT_EQ(static_cast<int>(r.abs_errors_px.size()), m.num_matched);
  return r;
}

SyntheticResult RunSynthetic(const cv::Mat& left, const cv::Mat& right, double disparity_px,
                             const StereoMatchOptions& options = {}) {
  return RunSynthetic(
      left, right, [disparity_px](const cv::Point2f&) { return disparity_px; }, options);
}

TEST(StereoMatchOptions, DefaultsAreValidAndBadValuesAreRejected) {
  std::string why;
  EXPECT_TRUE(StereoMatchOptions{}.IsValid(&why)) << why;
  auto expect_invalid = [](StereoMatchOptions o, const std::string& word) {
    std::string why;
    EXPECT_FALSE(o.IsValid(&why));
    EXPECT_NE(why.find(word), std::string::npos) << why;
  };
  StereoMatchOptions o;
  o.max_descriptor_distance = 0;
  expect_invalid(o, "max_descriptor_distance");
  o = {};
  o.min_depth_m = -1;
  expect_invalid(o, "min_depth_m");
  o = {};
  o.min_depth_m = 5;
  o.max_depth_m = 4;
  expect_invalid(o, "max_depth_m");
  o = {};
  o.sad_window_half_px = 0;
  expect_invalid(o, "sad_window_half_px");
  o = {};
  o.sad_search_half_px = 1;
  expect_invalid(o, "sad_search_half_px");
  o = {};
  o.outlier_sad_factor = 0;
  expect_invalid(o, "outlier_sad_factor");
}

TEST(MatchStereo, RejectsBadInput) {
  const cv::Mat img = test::SyntheticTexture({320, 240}, 1);
  const OrbFeatures f = Extractor().Extract(img);
  ASSERT_FALSE(f.keypoints.empty());
  const std::vector<double>& scales = Extractor().scale_factors();
  StereoRig mono = SyntheticRig(img.size());
  mono.baseline_m = 0;
  EXPECT_THROW(MatchStereo(mono, f, f, scales), std::invalid_argument);
  StereoMatchOptions bad;
  bad.sad_search_half_px = 0;
  EXPECT_THROW(MatchStereo(SyntheticRig(img.size()), f, f, scales, bad), ConfigError);
  OrbFeatures no_descriptors = f;
  no_descriptors.descriptors = cv::Mat();
  EXPECT_THROW(MatchStereo(SyntheticRig(img.size()), no_descriptors, f, scales),
               std::invalid_argument);
  OrbFeatures no_pyramid = f;
  no_pyramid.pyramid.resize(2);
  EXPECT_THROW(MatchStereo(SyntheticRig(img.size()), f, no_pyramid, scales), std::invalid_argument);
  EXPECT_THROW(MatchStereo(SyntheticRig(img.size()), f, f, {1.0, 1.2}), std::invalid_argument);
  // Nothing on one side: every left keypoint unmatched.
  const StereoMatches none = MatchStereo(SyntheticRig(img.size()), f, OrbFeatures{}, scales);
  EXPECT_EQ(none.num_matched, 0);
  EXPECT_EQ(none.u_right_px.size(), f.keypoints.size());
  EXPECT_TRUE(
      std::all_of(none.depth_m.begin(), none.depth_m.end(), [](float d) { return d == -1.0f; }));
}

TEST(MatchStereo, SubPixelDisparityOfAShiftedTexture) {
  const cv::Mat left = test::SyntheticTexture({752, 480}, 7);
  const SyntheticResult r = RunSynthetic(left, ShiftLeft(left, 12.4), 12.4);
  ASSERT_GE(r.matched, 0.7 * r.n_left) << r.matched << " of " << r.n_left;
  EXPECT_GE(r.WithinPx(0.15), 0.95 * r.matched) << r.WithinPx(0.15) << " of " << r.matched;
  EXPECT_LT(r.Median(), 0.04);
  EXPECT_LT(r.abs_errors_px.back(), 0.5);
}

TEST(MatchStereo, EquiangularFitBeatsTheParabolaOnSad) {
  const cv::Mat left = test::SyntheticTexture({752, 480}, 7);
  const cv::Mat right = ShiftLeft(left, 7.7);
  StereoMatchOptions parabola;
  parabola.subpixel_fit = SubpixelFit::kParabola;
  const SyntheticResult p = RunSynthetic(left, right, 7.7, parabola);
  const SyntheticResult e = RunSynthetic(left, right, 7.7);
  ASSERT_GT(p.matched, 1000);
  EXPECT_EQ(p.matched, e.matched);  // the fit moves matches, it does not pick them
  EXPECT_GE(e.WithinPx(0.15), 0.9 * e.matched) << e.WithinPx(0.15) << " of " << e.matched;
  EXPECT_LT(p.WithinPx(0.15), e.WithinPx(0.15) - 0.1 * e.matched);
  EXPECT_GE(p.WithinPx(0.5), 0.97 * p.matched);  // biased, not wrong
}

// A square SAD window on a road averages the disparities of its rows; the slanted refinement
// fits their gradient. Measured: 703 of 2000 keypoints matched (the shear costs descriptor
// matches), median error 0.014 px and 677 within 0.15 px; with the square window 713, 0.28 px, 214.
TEST(MatchStereo, SlantedRefinementFollowsARoadLikeDisparityGradient) {
  const cv::Mat left = test::SyntheticTexture({752, 480}, 9);
  constexpr double kD0 = 20.3, kGradient = 0.33, kRow0 = 240.0;
  const cv::Mat right = ShearLeft(left, kD0, kGradient, kRow0);
  const auto truth = [&](const cv::Point2f& p) { return kD0 + kGradient * (p.y - kRow0); };
  StereoMatchOptions slanted;
  slanted.slant_refinement = true;
  const SyntheticResult s = RunSynthetic(left, right, truth);
  const SyntheticResult r = RunSynthetic(left, right, truth, slanted);
  ASSERT_GE(r.matched, 0.3 * r.n_left) << r.matched << " of " << r.n_left;
  EXPECT_GE(r.matched, 0.95 * s.matched) << r.matched << " vs " << s.matched;
  EXPECT_GE(r.WithinPx(0.15), 0.95 * r.matched) << r.WithinPx(0.15) << " of " << r.matched;
  EXPECT_LT(r.Median(), 0.03);
  EXPECT_LT(r.Median(), 0.2 * s.Median()) << r.Median() << " vs " << s.Median();
  EXPECT_LT(s.WithinPx(0.15), 0.5 * r.WithinPx(0.15));
}

TEST(MatchStereo, IntegerDisparity) {
  const cv::Mat left = test::SyntheticTexture({752, 480}, 8);
  cv::Mat right;
  cv::copyMakeBorder(left.colRange(9, left.cols), right, 0, 0, 0, 9, cv::BORDER_REFLECT_101);
  const SyntheticResult r = RunSynthetic(left, right, 9.0);
  ASSERT_GE(r.matched, 0.7 * r.n_left) << r.matched << " of " << r.n_left;
  EXPECT_GE(r.WithinPx(0.15), 0.95 * r.matched) << r.WithinPx(0.15) << " of " << r.matched;
  EXPECT_LT(r.Median(), 0.04);
}

TEST(MatchStereo, BrightnessOffsetBetweenCamerasDoesNotMatter) {
  const cv::Mat left = test::SyntheticTexture({752, 480}, 7);
  const cv::Mat right = ShiftLeft(left, 12.4);
  cv::Mat brighter;
  right.convertTo(brighter, CV_8U, 1.0, 15.0);  // texture is in [20, 235]: no saturation
  const SyntheticResult same = RunSynthetic(left, right, 12.4);
  const SyntheticResult r = RunSynthetic(left, brighter, 12.4);
  EXPECT_GE(r.matched, 0.97 * same.matched) << r.matched << " vs " << same.matched;
  EXPECT_GE(r.WithinPx(0.15), 0.9 * r.matched) << r.WithinPx(0.15) << " of " << r.matched;
}

const OrbFeatures& KittiLeft() {
  static const OrbFeatures f = Extractor().Extract(test::KittiSeq06(0, 0));
  return f;
}
const OrbFeatures& KittiRight() {
  static const OrbFeatures f = Extractor().Extract(test::KittiSeq06(1, 0));
  return f;
}

// Dense semi-global matching of the same pair (disparity x 16), computed once.
const cv::Mat& KittiSgbmDisparityX16() {
  static const cv::Mat disparity_x16 = [] {
    cv::Ptr<cv::StereoSGBM> sgbm = cv::StereoSGBM::create(0, 128, 5, 8 * 25, 32 * 25, 1, 0, 10, 100,
                                                          2, cv::StereoSGBM::MODE_SGBM);
    cv::Mat d;
    sgbm->compute(test::KittiSeq06(0, 0), test::KittiSeq06(1, 0), d);
    return d;
  }();
  return disparity_x16;
}

// Matches of KITTI 06 frame 0 and how many of them agree (within 1 px) with dense semi-global
// matching, an independent reference.
struct SgbmAgreement {
  int matched = 0, compared = 0, agree = 0;
};
SgbmAgreement KittiAgreementWithSgbm(const StereoMatchOptions& options) {
  const StereoRig rig = KittiSeq06Rig();
  const OrbFeatures& fl = KittiLeft();
  const StereoMatches m = MatchStereo(rig, fl, KittiRight(), Extractor().scale_factors(), options);
  const cv::Mat& disparity_x16 = KittiSgbmDisparityX16();
  SgbmAgreement a;
  a.matched = m.num_matched;
  for (size_t i = 0; i < fl.keypoints.size(); ++i) {
    if (m.u_right_px[i] < 0) continue;
    const double disparity = fl.keypoints[i].pt.x - m.u_right_px[i];
    EXPECT_GT(disparity, 0.0);
    EXPECT_LE(disparity, rig.left.fx);
    EXPECT_NEAR(m.depth_m[i], rig.Bf() / disparity, 1e-3 * m.depth_m[i]);
    const int x = static_cast<int>(std::lround(fl.keypoints[i].pt.x));
    const int y = static_cast<int>(std::lround(fl.keypoints[i].pt.y));
    const short d16 = disparity_x16.at<short>(y, x);
    if (d16 <= 0) continue;  // no SGBM value here
    ++a.compared;
    a.agree += std::abs(disparity - d16 / 16.0) < 1.0 ? 1 : 0;
  }
  return a;
}

TEST(MatchStereo, KittiMatchesMostKeypointsConsistentlyWithSgbm) {
  const size_t n = KittiLeft().keypoints.size();
  StereoMatchOptions slanted;
  slanted.slant_refinement = true;
  const SgbmAgreement s = KittiAgreementWithSgbm({});
  const SgbmAgreement a = KittiAgreementWithSgbm(slanted);
  // Measured: 1184 of 2000 matched, 999 of 1106 agree; with the square window 1227, 1028 of 1144.
  // The slanted refinement drops the matches whose fit leaves the SAD minimum by a pixel; the
  // default square window keeps the bound it had before the option.
  EXPECT_GE(s.matched, 0.6 * n) << s.matched << " of " << n;
  EXPECT_GE(a.matched, 0.55 * n) << a.matched << " of " << n;
  for (const SgbmAgreement& r : {s, a}) {
    ASSERT_GE(r.compared, 0.5 * r.matched);
    EXPECT_GE(r.agree, 0.85 * r.compared) << r.agree << " of " << r.compared;
  }
  EXPECT_GE(a.matched, 0.95 * s.matched) << a.matched << " vs " << s.matched;
}

TEST(MatchStereo, KittiDepthLimitsAndOutlierFactorAreApplied) {
  const StereoRig rig = KittiSeq06Rig();
  const OrbFeatures& fl = KittiLeft();
  const std::vector<double>& scales = Extractor().scale_factors();
  StereoMatchOptions o;
  o.min_depth_m = 4.0;
  o.max_depth_m = 20.0;
  const StereoMatches limited = MatchStereo(rig, fl, KittiRight(), scales, o);
  const StereoMatches all = MatchStereo(rig, fl, KittiRight(), scales);
  ASSERT_GT(limited.num_matched, 100);
  EXPECT_LT(limited.num_matched, all.num_matched);
  for (float d : limited.depth_m) {
    if (d < 0) continue;
    EXPECT_GE(d, 4.0f * 0.999f);
    EXPECT_LE(d, 20.0f * 1.001f);
  }
  // A tighter SAD factor keeps fewer matches, each of which the default also keeps.
  StereoMatchOptions strict;
  strict.outlier_sad_factor = 1.0;
  const StereoMatches tight = MatchStereo(rig, fl, KittiRight(), scales, strict);
  EXPECT_LT(tight.num_matched, all.num_matched);
  EXPECT_GT(tight.num_matched, 0.4 * all.num_matched);
  for (size_t i = 0; i < fl.keypoints.size(); ++i) {
    if (tight.u_right_px[i] >= 0) {
      EXPECT_EQ(tight.u_right_px[i], all.u_right_px[i]);
    }
  }
  // The descriptor gate is applied: closed down to a Hamming distance of 1, almost nothing
  // passes it.
  StereoMatchOptions tight_gate;
  tight_gate.max_descriptor_distance = 1;
  EXPECT_LT(MatchStereo(rig, fl, KittiRight(), scales, tight_gate).num_matched,
            0.05 * all.num_matched);
}

}  // namespace
}  // namespace pcr

namespace pcr {
namespace {

// With the SLAM default (quadtree_oversplit 1) about half of the keypoints find their partner.
TEST(MatchStereo, KittiDefaultExtractorStillMatchesHalf) {
  const OrbExtractor extractor{OrbOptions{}};
  const OrbFeatures fl = extractor.Extract(test::KittiSeq06(0, 0));
  const OrbFeatures fr = extractor.Extract(test::KittiSeq06(1, 0));
  const StereoMatches m = MatchStereo(KittiSeq06Rig(), fl, fr, extractor.scale_factors());
  EXPECT_GE(m.num_matched, 0.45 * fl.keypoints.size())
      << m.num_matched << " of " << fl.keypoints.size();
}

}  // namespace
}  // namespace pcr
