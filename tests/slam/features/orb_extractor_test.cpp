#include "slam/features/orb_extractor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <thread>

#include "feature_test_images.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

const cv::Mat& KittiFrame(int index) {
  static const cv::Mat frames[2] = {test::KittiSeq06(0, 0), test::KittiSeq06(0, 1)};
  return frames[index];
}

const OrbExtractor& DefaultExtractor() {
  static const OrbExtractor extractor{OrbOptions{}};
  return extractor;
}

const OrbFeatures& KittiFeatures() {
  static const OrbFeatures features = DefaultExtractor().Extract(KittiFrame(0));
  return features;
}

using test::SyntheticTexture;

// Index of the keypoint of `features` nearest to p at `octave` within max_px, or -1.
int FindKeypoint(const std::vector<cv::KeyPoint>& keypoints, cv::Point2f p, int octave,
                 float max_px) {
  int best = -1;
  float best_d2 = max_px * max_px;
  for (size_t i = 0; i < keypoints.size(); ++i) {
    if (keypoints[i].octave != octave) continue;
    const cv::Point2f d = keypoints[i].pt - p;
    const float d2 = d.dot(d);
    if (d2 <= best_d2) {
      best_d2 = d2;
      best = static_cast<int>(i);
    }
  }
  return best;
}

float AngleDiffDeg(float a, float b) {
  float d = std::fmod(a - b + 540.0f, 360.0f) - 180.0f;
  return std::abs(d);
}

TEST(OrbOptions, DefaultsAreValid) {
  std::string why;
  EXPECT_TRUE(OrbOptions{}.IsValid(&why)) << why;
}

TEST(OrbOptions, RejectsBadValuesWithAMessage) {
  auto expect_invalid = [](OrbOptions o, const std::string& word) {
    std::string why;
    EXPECT_FALSE(o.IsValid(&why));
    EXPECT_NE(why.find(word), std::string::npos) << why;
    EXPECT_FALSE(o.IsValid(nullptr));
    EXPECT_THROW(OrbExtractor{o}, ConfigError);
  };
  OrbOptions o;
  o.num_features = -5;
  expect_invalid(o, "num_features");
  o = {};
  o.num_features = 0;
  expect_invalid(o, "num_features");
  o = {};
  o.num_levels = 0;
  expect_invalid(o, "num_levels");
  o = {};
  o.scale_factor = 1.0;
  expect_invalid(o, "scale_factor");
  o = {};
  o.scale_factor = 0.8;
  expect_invalid(o, "scale_factor");
  o = {};
  o.scale_factor = std::nan("");
  expect_invalid(o, "scale_factor");
  o = {};
  o.fast_threshold_low = 30;  // above the high one
  expect_invalid(o, "fast_threshold_low");
  o = {};
  o.fast_threshold_high = -1;
  expect_invalid(o, "fast_threshold_high");
  o = {};
  o.quadtree_oversplit = 0.5;
  expect_invalid(o, "quadtree_oversplit");
  o = {};
  o.edge_threshold_px = 10;  // the orientation disc would leave the image
  expect_invalid(o, "edge_threshold_px");
}

TEST(OrbExtractor, LevelBudgetsAreGeometricAndSumToTheRequest) {
  OrbOptions o;
  o.num_features = 2000;
  const OrbExtractor ex(o);
  const std::vector<int>& n = ex.features_per_level();
  ASSERT_EQ(n.size(), 8u);
  EXPECT_EQ(std::accumulate(n.begin(), n.end(), 0), 2000);
  const double s = 1.2;
  const double n0 = 2000 * (1 - 1 / s) / (1 - std::pow(1 / s, 8));
  EXPECT_NEAR(n[0], n0, 0.5);
  for (int i = 1; i < 7; ++i) EXPECT_NEAR(n[i], n[i - 1] / s, 1.0) << "level " << i;
  ASSERT_EQ(ex.scale_factors().size(), 8u);
  for (int i = 0; i < 8; ++i) {
    EXPECT_NEAR(ex.scale_factors()[i], std::pow(1.2, i), 1e-12);
    EXPECT_NEAR(ex.level_sigma2()[i] * ex.inv_level_sigma2()[i], 1.0, 1e-12);
  }
  // One level takes everything.
  o.num_levels = 1;
  EXPECT_EQ(OrbExtractor(o).features_per_level(), std::vector<int>{2000});
}

TEST(OrbExtractor, RejectsEmptyAndNonGreyImages) {
  const OrbExtractor& ex = DefaultExtractor();
  EXPECT_THROW(ex.Extract(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(ex.Extract(cv::Mat(100, 100, CV_8UC3, cv::Scalar::all(7))), std::invalid_argument);
  EXPECT_THROW(ex.Extract(cv::Mat(100, 100, CV_16UC1, cv::Scalar::all(7))), std::invalid_argument);
  EXPECT_THROW(ex.Extract(cv::Mat(100, 100, CV_32FC1, cv::Scalar::all(7))), std::invalid_argument);
}

TEST(OrbExtractor, TinyAndFlatImagesGiveNoKeypointsButDoNotFail) {
  const OrbExtractor& ex = DefaultExtractor();
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(30, 20), cv::Size(38, 400)}) {
    const OrbFeatures f = ex.Extract(SyntheticTexture(size, 3));
    EXPECT_TRUE(f.keypoints.empty()) << size;
    EXPECT_EQ(f.descriptors.rows, 0);
    EXPECT_EQ(f.pyramid.size(), 8u);
  }
  const OrbFeatures flat = ex.Extract(cv::Mat(200, 300, CV_8UC1, cv::Scalar::all(128)));
  EXPECT_TRUE(flat.keypoints.empty());
}

TEST(OrbExtractor, SyntheticTextureFillsTheBudgetInsideTheBorder) {
  OrbOptions o;
  o.num_features = 600;
  o.num_levels = 4;
  const OrbExtractor ex(o);
  const cv::Mat img = SyntheticTexture({480, 320}, 11);
  const OrbFeatures f = ex.Extract(img);
  EXPECT_GE(f.keypoints.size(), 570u);
  EXPECT_LE(f.keypoints.size(), 600u);
  ASSERT_EQ(f.descriptors.rows, static_cast<int>(f.keypoints.size()));
  EXPECT_EQ(f.descriptors.cols, 32);
  EXPECT_EQ(f.descriptors.type(), CV_8UC1);
  for (const cv::KeyPoint& kp : f.keypoints) {
    ASSERT_GE(kp.octave, 0);
    ASSERT_LT(kp.octave, 4);
    const cv::Point2f p = f.LevelFromBase(kp.octave, kp.pt);
    // Corners sit on integer pixels of their level, at least edge_threshold_px from its border.
    EXPECT_NEAR(p.x, std::round(p.x), 1e-3);
    EXPECT_NEAR(p.y, std::round(p.y), 1e-3);
    const cv::Mat& level = f.pyramid[kp.octave];
    EXPECT_GE(std::round(p.x), o.edge_threshold_px);
    EXPECT_GE(std::round(p.y), o.edge_threshold_px);
    EXPECT_LT(std::round(p.x), level.cols - o.edge_threshold_px);
    EXPECT_LT(std::round(p.y), level.rows - o.edge_threshold_px);
    EXPECT_GE(kp.angle, 0.0f);
    EXPECT_LT(kp.angle, 360.0f);
    EXPECT_NEAR(kp.size, 31 * ex.scale_factors()[kp.octave], 1e-3);
    EXPECT_GE(kp.response, o.fast_threshold_low);
  }
}

TEST(OrbExtractor, LevelCoordinatesRoundTrip) {
  const OrbFeatures& f = KittiFeatures();
  ASSERT_EQ(f.pyramid.size(), 8u);
  EXPECT_EQ(f.pyramid[0].size(), KittiFrame(0).size());
  for (int level = 0; level < 8; ++level) {
    const cv::Point2f p(123.25f, 77.5f);
    const cv::Point2f back = f.BaseFromLevel(level, f.LevelFromBase(level, p));
    EXPECT_NEAR(back.x, p.x, 1e-3);
    EXPECT_NEAR(back.y, p.y, 1e-3);
    // Pixel-centre convention: the outer edge of the image maps onto itself.
    const cv::Point2f corner = f.BaseFromLevel(level, {-0.5f, -0.5f});
    EXPECT_NEAR(corner.x, -0.5f, 1e-4);
    EXPECT_NEAR(corner.y, -0.5f, 1e-4);
  }
}

TEST(OrbExtractor, KittiCountAndEveryLevelPopulated) {
  const OrbFeatures& f = KittiFeatures();
  const OrbExtractor& ex = DefaultExtractor();
  EXPECT_GE(f.keypoints.size(), 1800u);
  EXPECT_LE(f.keypoints.size(), 2000u);
  std::vector<int> per_level(8, 0);
  for (const cv::KeyPoint& kp : f.keypoints) ++per_level[kp.octave];
  for (int level = 0; level < 8; ++level) {
    EXPECT_GE(per_level[level], 0.8 * ex.features_per_level()[level]) << "level " << level;
    EXPECT_LE(per_level[level], ex.features_per_level()[level]) << "level " << level;
  }
}

// Per-cell keypoint counts on a cols x rows grid over the image.
std::vector<int> CellCounts(const std::vector<cv::KeyPoint>& kps, cv::Size size, int cols,
                            int rows) {
  std::vector<int> counts(cols * rows, 0);
  for (const cv::KeyPoint& kp : kps) {
    const int c = std::min(cols - 1, static_cast<int>(kp.pt.x * cols / size.width));
    const int r = std::min(rows - 1, static_cast<int>(kp.pt.y * rows / size.height));
    ++counts[r * cols + c];
  }
  return counts;
}

double CoefficientOfVariation(const std::vector<int>& counts) {
  const double mean = std::accumulate(counts.begin(), counts.end(), 0.0) / counts.size();
  double var = 0;
  for (int c : counts) var += (c - mean) * (c - mean);
  return std::sqrt(var / counts.size()) / mean;
}

TEST(OrbExtractor, KittiKeypointsCoverTheTexturedCells) {
  const cv::Mat& img = KittiFrame(0);
  const OrbFeatures& f = KittiFeatures();
  // A cell is textured when FAST with the low threshold finds at least 10 corners in it.
  std::vector<cv::KeyPoint> corners;
  cv::FAST(img, corners, 7, true);
  const std::vector<int> texture = CellCounts(corners, img.size(), 8, 4);
  const std::vector<int> ours = CellCounts(f.keypoints, img.size(), 8, 4);
  int textured = 0, covered = 0;
  for (size_t i = 0; i < texture.size(); ++i) {
    if (texture[i] < 10) continue;
    ++textured;
    covered += ours[i] > 0 ? 1 : 0;
  }
  ASSERT_GE(textured, 16);
  EXPECT_GE(covered, 0.7 * textured) << covered << " of " << textured;
}

TEST(OrbExtractor, KittiSpreadBeatsOpenCvOrb) {
  const cv::Mat& img = KittiFrame(0);
  const OrbFeatures& f = KittiFeatures();
  cv::Ptr<cv::ORB> orb = cv::ORB::create(2000, 1.2f, 8, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31, 20);
  std::vector<cv::KeyPoint> cv_kps;
  orb->detect(img, cv_kps);
  ASSERT_GT(cv_kps.size(), 1000u);
  const std::vector<int> ours = CellCounts(f.keypoints, img.size(), 24, 8);
  const std::vector<int> theirs = CellCounts(cv_kps, img.size(), 24, 8);
  const auto occupied = [](const std::vector<int>& c) {
    return std::count_if(c.begin(), c.end(), [](int n) { return n > 0; });
  };
  EXPECT_GT(occupied(ours), occupied(theirs) + 40)
      << "ours " << occupied(ours) << " cv::ORB " << occupied(theirs);
  EXPECT_LT(CoefficientOfVariation(ours), 0.6 * CoefficientOfVariation(theirs));
}

TEST(OrbExtractor, OversplitOneIsTheMostEven) {
  OrbOptions o;
  o.quadtree_oversplit = 1.0;
  const OrbFeatures even = OrbExtractor(o).Extract(KittiFrame(0));
  const cv::Size size = KittiFrame(0).size();
  const std::vector<int> one = CellCounts(even.keypoints, size, 24, 8);
  OrbOptions o2;
  o2.quadtree_oversplit = 2.0;
  const std::vector<int> two =
      CellCounts(OrbExtractor(o2).Extract(KittiFrame(0)).keypoints, size, 24, 8);
  EXPECT_GE(even.keypoints.size(), 1800u);
  EXPECT_LT(CoefficientOfVariation(one), CoefficientOfVariation(two));
}

TEST(OrbExtractor, Deterministic) {
  const OrbFeatures a = DefaultExtractor().Extract(KittiFrame(0));
  const OrbFeatures b = OrbExtractor(OrbOptions{}).Extract(KittiFrame(0));
  ASSERT_EQ(a.keypoints.size(), b.keypoints.size());
  for (size_t i = 0; i < a.keypoints.size(); ++i) {
    EXPECT_EQ(a.keypoints[i].pt, b.keypoints[i].pt);
    EXPECT_EQ(a.keypoints[i].angle, b.keypoints[i].angle);
    EXPECT_EQ(a.keypoints[i].octave, b.keypoints[i].octave);
    EXPECT_EQ(a.keypoints[i].response, b.keypoints[i].response);
  }
  EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_L1), 0.0);
}

TEST(OrbExtractor, ConcurrentCallsGiveTheSameResult) {
  const OrbExtractor& ex = DefaultExtractor();
  OrbFeatures r1, r2;
  std::thread t1([&] { r1 = ex.Extract(KittiFrame(0)); });
  std::thread t2([&] { r2 = ex.Extract(KittiFrame(0)); });
  t1.join();
  t2.join();
  const OrbFeatures& ref = KittiFeatures();
  for (const OrbFeatures* r : {&r1, &r2}) {
    ASSERT_EQ(r->keypoints.size(), ref.keypoints.size());
    EXPECT_EQ(cv::norm(r->descriptors, ref.descriptors, cv::NORM_L1), 0.0);
  }
}

TEST(OrbExtractor, OutputDoesNotAliasTheInput) {
  cv::Mat img = KittiFrame(0).clone();
  const OrbFeatures f = DefaultExtractor().Extract(img);
  img.setTo(0);
  EXPECT_EQ(cv::norm(f.pyramid[0], KittiFrame(0), cv::NORM_L1), 0.0);
}

// Rotating the image by 90 degrees maps FAST corners onto each other exactly; the same corner
// must get an angle 90 degrees larger and (nearly) the same descriptor.
void CheckQuarterTurn(const cv::Mat& img, const OrbExtractor& ex, double min_found_fraction) {
  const OrbFeatures f = ex.Extract(img);
  cv::Mat rotated;
  cv::rotate(img, rotated, cv::ROTATE_90_CLOCKWISE);
  const OrbFeatures g = ex.Extract(rotated);
  // Clockwise quarter turn: (x, y) -> (H - 1 - y, x); direction angles grow by 90 degrees.
  const float h = static_cast<float>(img.rows);
  int found = 0, close_descriptor = 0, close_angle = 0;
  for (size_t i = 0; i < f.keypoints.size(); ++i) {
    const cv::KeyPoint& kp = f.keypoints[i];
    const cv::Point2f q(h - 1 - kp.pt.y, kp.pt.x);
    const int j = FindKeypoint(g.keypoints, q, kp.octave, 0.6f);
    if (j < 0) continue;
    ++found;
    const float expected = std::fmod(kp.angle + 90.0f, 360.0f);
    close_angle += AngleDiffDeg(g.keypoints[j].angle, expected) < 2.0f ? 1 : 0;
    close_descriptor +=
        DescriptorDistance(f.descriptors.row(static_cast<int>(i)), g.descriptors.row(j)) <= 25 ? 1
                                                                                               : 0;
  }
  ASSERT_GE(found, min_found_fraction * f.keypoints.size());
  EXPECT_GE(close_angle, 0.97 * found) << close_angle << " of " << found;
  EXPECT_GE(close_descriptor, 0.9 * found) << close_descriptor << " of " << found;
}

TEST(OrbExtractor, QuarterTurnSyntheticTexture) {
  OrbOptions o;
  o.num_features = 500;
  o.num_levels = 3;
  CheckQuarterTurn(SyntheticTexture({400, 400}, 5), OrbExtractor(o), 0.3);
}

TEST(OrbExtractor, QuarterTurnKitti) { CheckQuarterTurn(KittiFrame(0), DefaultExtractor(), 0.2); }

TEST(OrbExtractor, ArbitraryRotationKeepsDescriptorsClose) {
  // Rotate a central crop of the KITTI frame by 30 degrees about its centre.
  const cv::Mat crop = KittiFrame(0)(cv::Rect(380, 0, 470, 370)).clone();
  const double angle_deg = 30.0;
  const cv::Point2f centre((crop.cols - 1) * 0.5f, (crop.rows - 1) * 0.5f);
  const cv::Mat rot = cv::getRotationMatrix2D(centre, angle_deg, 1.0);  // counter-clockwise
  cv::Mat rotated;
  cv::warpAffine(crop, rotated, rot, crop.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT_101);
  OrbOptions o;
  o.num_features = 800;
  const OrbExtractor ex(o);
  const OrbFeatures f = ex.Extract(crop);
  const OrbFeatures g = ex.Extract(rotated);
  int found = 0, close_angle = 0, close_descriptor = 0;
  for (size_t i = 0; i < f.keypoints.size(); ++i) {
    const cv::KeyPoint& kp = f.keypoints[i];
    const cv::Point2f d = kp.pt - centre;
    if (d.dot(d) > 130.0f * 130.0f) continue;  // stays clear of the reflected corners
    const cv::Point2f q(static_cast<float>(rot.at<double>(0, 0) * kp.pt.x +
                                           rot.at<double>(0, 1) * kp.pt.y + rot.at<double>(0, 2)),
                        static_cast<float>(rot.at<double>(1, 0) * kp.pt.x +
                                           rot.at<double>(1, 1) * kp.pt.y + rot.at<double>(1, 2)));
    const int j = FindKeypoint(g.keypoints, q, kp.octave, 1.5f * ex.scale_factors()[kp.octave]);
    if (j < 0) continue;
    ++found;
    // Counter-clockwise on screen (y down) lowers the direction angle.
    const float expected = std::fmod(kp.angle - static_cast<float>(angle_deg) + 360.0f, 360.0f);
    close_angle += AngleDiffDeg(g.keypoints[j].angle, expected) < 10.0f ? 1 : 0;
    close_descriptor +=
        DescriptorDistance(f.descriptors.row(static_cast<int>(i)), g.descriptors.row(j)) <= 64 ? 1
                                                                                               : 0;
  }
  ASSERT_GE(found, 60);
  EXPECT_GE(close_angle, 0.75 * found) << close_angle << " of " << found;
  EXPECT_GE(close_descriptor, 0.75 * found) << close_descriptor << " of " << found;
}

TEST(OrbExtractor, BrightnessOffsetBarelyMatters) {
  // Compress the range first so that the offset saturates no pixel. FAST, the intensity
  // centroid and the smoothing are then exactly offset-invariant, so level 0 must not change at
  // all; cv::resize rounds its fixed-point weights, so the upper levels move by 1-2 grey levels
  // here and there.
  cv::Mat dim, bright;
  KittiFrame(0).convertTo(dim, CV_8U, 0.7);
  dim.convertTo(bright, CV_8U, 1.0, 40.0);
  const OrbFeatures f = DefaultExtractor().Extract(dim);
  const OrbFeatures g = DefaultExtractor().Extract(bright);
  ASSERT_GT(f.keypoints.size(), 1500u);
  int level0 = 0, level0_same = 0, close = 0;
  for (size_t i = 0; i < f.keypoints.size(); ++i) {
    const cv::KeyPoint& kp = f.keypoints[i];
    level0 += kp.octave == 0 ? 1 : 0;
    const int j = FindKeypoint(g.keypoints, kp.pt, kp.octave, 0.01f);
    if (j < 0) continue;
    const int d = DescriptorDistance(f.descriptors.row(static_cast<int>(i)), g.descriptors.row(j));
    close += d <= 16 ? 1 : 0;
    level0_same += (kp.octave == 0 && d == 0 && g.keypoints[j].angle == kp.angle) ? 1 : 0;
  }
  EXPECT_GT(level0, 300);
  EXPECT_EQ(level0_same, level0);
  EXPECT_GE(close, 0.9 * f.keypoints.size()) << close << " of " << f.keypoints.size();
}

// Ratio-test matches between two feature sets and the fraction of them that a fundamental
// matrix (RANSAC, 2 px) explains.
struct MatchQuality {
  int matches = 0;
  int inliers = 0;
};

MatchQuality MatchFrames(const std::vector<cv::KeyPoint>& k0, const cv::Mat& d0,
                         const std::vector<cv::KeyPoint>& k1, const cv::Mat& d1) {
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(d0, d1, knn, 2);
  std::vector<cv::Point2f> p0, p1;
  for (const auto& m : knn) {
    if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance && m[0].distance <= 64) {
      p0.push_back(k0[m[0].queryIdx].pt);
      p1.push_back(k1[m[0].trainIdx].pt);
    }
  }
  MatchQuality q;
  q.matches = static_cast<int>(p0.size());
  if (p0.size() < 8) return q;
  std::vector<uchar> inliers;
  cv::findFundamentalMat(p0, p1, cv::FM_RANSAC, 2.0, 0.999, inliers);
  q.inliers = static_cast<int>(std::count(inliers.begin(), inliers.end(), 1));
  return q;
}

TEST(OrbExtractor, ConsecutiveKittiFramesMatch) {
  // The car moves about a metre between frames 0 and 1 of sequence 06.
  const OrbFeatures& f0 = KittiFeatures();
  const OrbFeatures f1 = DefaultExtractor().Extract(KittiFrame(1));
  const MatchQuality ours = MatchFrames(f0.keypoints, f0.descriptors, f1.keypoints, f1.descriptors);
  EXPECT_GE(ours.matches, 0.22 * f0.keypoints.size()) << ours.matches;
  EXPECT_GE(ours.inliers, 0.75 * ours.matches) << ours.inliers << " of " << ours.matches;
  // Same keypoints described by OpenCV's learned rBRIEF: our fixed-seed pattern must keep up.
  std::vector<cv::KeyPoint> k0 = f0.keypoints, k1 = f1.keypoints;
  cv::Mat d0, d1;
  cv::Ptr<cv::ORB> orb = cv::ORB::create();
  orb->compute(KittiFrame(0), k0, d0);
  orb->compute(KittiFrame(1), k1, d1);
  const MatchQuality reference = MatchFrames(k0, d0, k1, d1);
  EXPECT_GE(ours.inliers, 0.9 * reference.inliers)
      << "ours " << ours.inliers << " OpenCV rBRIEF " << reference.inliers;
}

TEST(DescriptorDistance, CountsDifferingBits) {
  cv::Mat zeros = cv::Mat::zeros(1, 32, CV_8U);
  cv::Mat ones(1, 32, CV_8U, cv::Scalar(255));
  EXPECT_EQ(DescriptorDistance(zeros, ones), 256);
  EXPECT_EQ(DescriptorDistance(ones, ones), 0);
  cv::Mat one_bit = zeros.clone();
  one_bit.at<uchar>(0, 31) = 0x80;
  EXPECT_EQ(DescriptorDistance(zeros, one_bit), 1);
  cv::RNG rng(42);
  cv::Mat a(50, 32, CV_8U), b(50, 32, CV_8U);
  rng.fill(a, cv::RNG::UNIFORM, 0, 256);
  rng.fill(b, cv::RNG::UNIFORM, 0, 256);
  for (int i = 0; i < 50; ++i) {
    EXPECT_EQ(DescriptorDistance(a.row(i), b.row(i)),
              static_cast<int>(cv::norm(a.row(i), b.row(i), cv::NORM_HAMMING)));
    EXPECT_EQ(DescriptorDistance(a.ptr<uchar>(i), b.ptr<uchar>(i)),
              DescriptorDistance(a.row(i), b.row(i)));
  }
}

TEST(DescriptorDistance, RejectsWrongShapes) {
  cv::Mat ok = cv::Mat::zeros(1, 32, CV_8U);
  EXPECT_THROW(DescriptorDistance(ok, cv::Mat::zeros(1, 31, CV_8U)), std::invalid_argument);
  EXPECT_THROW(DescriptorDistance(cv::Mat::zeros(2, 32, CV_8U), ok), std::invalid_argument);
  EXPECT_THROW(DescriptorDistance(ok, cv::Mat::zeros(1, 32, CV_16U)), std::invalid_argument);
}

}  // namespace
}  // namespace pcr
