#include "slam/features/stereo_matcher.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include "slam/common/error.h"

namespace pcr {
namespace {

constexpr float kMinDisparityPx = 0.01f;  // disparities below this are clamped (depth ~ Bf/0.01)
// Row band of a right keypoint: y +- kRowBandSigmas * scale of its octave.
constexpr float kRowBandSigmas = 2.0f;
// The slanted refinement may move a disparity this far (level pixels) from the SAD fit.
constexpr double kMaxSlantMovePx = 1.0;

// Buffers of the correlation search, reused across keypoints.
struct SadWorkspace {
  std::vector<float> left;         // (2w+1)^2 window of the left level, row-major
  std::vector<float> right;        // 2w+1 rows of 2(w+s)+1 pixels of the right level
  std::vector<float> column_sums;  // per column of `right`
  std::vector<float> offset;       // per shift: mean(left window) - mean(right window)
  std::vector<float> cost;         // per shift: zero-mean SAD
};

// Zero-mean SAD costs of the (2w+1)^2 window of `left` at (xl, y) against the windows of `right`
// at (xr0 + inc, y), inc in [-s, s]: cost[inc + s] = sum |(L - mean L) - (R - mean R)|. All
// windows must lie inside the images. The loops run over the shifts innermost, so they vectorise.
void ZeroMeanSadCosts(const cv::Mat& left, int xl, const cv::Mat& right, int xr0, int y, int w,
                      int s, SadWorkspace* ws) {
  const int side = 2 * w + 1;
  const int n_shifts = 2 * s + 1;
  const int strip_w = side + 2 * s;
  const float inv_n = 1.0f / static_cast<float>(side * side);
  ws->left.resize(side * side);
  ws->right.resize(side * strip_w);
  ws->column_sums.assign(strip_w, 0.0f);
  ws->offset.resize(n_shifts);
  ws->cost.assign(n_shifts, 0.0f);
  float left_sum = 0.0f;
  for (int r = 0; r < side; ++r) {
    const std::uint8_t* l = left.ptr<std::uint8_t>(y - w + r) + xl - w;
    const std::uint8_t* q = right.ptr<std::uint8_t>(y - w + r) + xr0 - s - w;
    float* lf = ws->left.data() + r * side;
    float* rf = ws->right.data() + r * strip_w;
    for (int c = 0; c < side; ++c) {
      lf[c] = l[c];
      left_sum += lf[c];
    }
    for (int c = 0; c < strip_w; ++c) {
      rf[c] = q[c];
      ws->column_sums[c] += rf[c];
    }
  }
  float window_sum = 0.0f;
  for (int c = 0; c < side; ++c) window_sum += ws->column_sums[c];
  for (int k = 0; k < n_shifts; ++k) {
    if (k > 0) window_sum += ws->column_sums[k + side - 1] - ws->column_sums[k - 1];
    ws->offset[k] = (left_sum - window_sum) * inv_n;
  }
  float* cost = ws->cost.data();
  const float* offset = ws->offset.data();
  for (int r = 0; r < side; ++r) {
    const float* lf = ws->left.data() + r * side;
    const float* rf = ws->right.data() + r * strip_w;
    for (int c = 0; c < side; ++c) {
      const float l = lf[c];
      const float* rc = rf + c;
      for (int k = 0; k < n_shifts; ++k) cost[k] += std::abs(l - rc[k] - offset[k]);
    }
  }
}

// Gauss-Newton refinement of a level disparity over the (2w+1)^2 window of `left` at (xl, y): the
// right window is sampled at x - (d + gy * dy) on each row dy (a surface whose disparity changes
// down the window, as a road's does by ~0.33 px per row at KITTI geometry), with a brightness
// offset. Inverse compositional (Baker and Matthews): the Jacobian comes from the left window's
// gradient, so the 3x3 system is factored once; rows stay whole pixels, so each row is one linear
// interpolation along x. Returns false (d unchanged) when a sample leaves the image, the left
// window has no x gradient or d moves more than max_move_px.
bool RefineSlantedDisparity(const cv::Mat& left, const cv::Mat& right, int xl, int y, int w,
                            double max_move_px, double* d) {
  const int side = 2 * w + 1;
  if (xl - w - 1 < 0 || xl + w + 1 >= left.cols) return false;
  // Left window gradient and the Jacobian sums: (-g, -g * dy, -1) for (d, gy, offset).
  std::array<float, (2 * kMaxSadWindowHalfPx + 1) * (2 * kMaxSadWindowHalfPx + 1)> gradient;
  double sg2 = 0, sg2y = 0, sg2y2 = 0, sg = 0, sgy = 0;
  for (int dy = -w; dy <= w; ++dy) {
    const std::uint8_t* l = left.ptr<std::uint8_t>(y + dy) + xl - w;
    float row_g2 = 0, row_g = 0;
    for (int c = 0; c < side; ++c) {
      const float g = 0.5f * static_cast<float>(l[c + 1] - l[c - 1]);
      gradient[(dy + w) * side + c] = g;
      row_g2 += g * g;
      row_g += g;
    }
    sg2 += row_g2;
    sg2y += row_g2 * dy;
    sg2y2 += static_cast<double>(row_g2) * dy * dy;
    sg += row_g;
    sgy += row_g * dy;
  }
  if (!(sg2 > 0)) return false;
  Eigen::Matrix3d h;
  h << sg2, sg2y, sg, sg2y, sg2y2, sgy, sg, sgy, side * side;
  const Eigen::LDLT<Eigen::Matrix3d> solver(h);
  if (solver.info() != Eigen::Success || !solver.isPositive()) return false;

  const double d0 = *d;
  double disparity = d0, gy = 0.0, offset = 0.0;
  constexpr int kIterations = 5;
  for (int it = 0; it < kIterations; ++it) {
    // Residual e = right(x - d - gy * dy) + offset - left(x); right-hand side sum(J * e).
    double sge = 0, sgye = 0, se = 0;
    for (int dy = -w; dy <= w; ++dy) {
      const double x0 = xl - w - (disparity + gy * dy);  // right position of the row's first pixel
      const int i0 = static_cast<int>(std::floor(x0));
      if (i0 < 0 || i0 + side >= right.cols) return false;
      const float a = static_cast<float>(x0 - i0), b = 1.0f - a;
      const float o = static_cast<float>(offset);
      const std::uint8_t* r = right.ptr<std::uint8_t>(y + dy) + i0;
      const std::uint8_t* l = left.ptr<std::uint8_t>(y + dy) + xl - w;
      const float* g = gradient.data() + (dy + w) * side;
      float row_ge = 0, row_e = 0;
      for (int c = 0; c < side; ++c) {
        const float e = b * r[c] + a * r[c + 1] + o - static_cast<float>(l[c]);
        row_ge += g[c] * e;
        row_e += e;
      }
      sge += row_ge;
      sgye += row_ge * dy;
      se += row_e;
    }
    const Eigen::Vector3d step = solver.solve(Eigen::Vector3d(-sge, -sgye, -se));
    if (!step.allFinite()) return false;
    // Compose with the inverse of the step: the warp's parameters add.
    disparity -= step(0);
    gy -= step(1);
    offset += step(2);
    if (std::abs(disparity - d0) > max_move_px) return false;
    if (std::abs(step(0)) < 5e-3) break;
  }
  *d = disparity;
  return true;
}

void CheckFeatures(const OrbFeatures& f, const char* side, size_t n_scales) {
  const std::string who = std::string("MatchStereo: ") + side + " features: ";
  if (f.descriptors.rows != static_cast<int>(f.keypoints.size()) ||
      (!f.keypoints.empty() &&
       (f.descriptors.type() != CV_8UC1 || f.descriptors.cols != kOrbDescriptorBytes))) {
    throw std::invalid_argument(who + "descriptors must be N x 32 CV_8UC1, one per keypoint");
  }
  if (f.keypoints.empty()) return;
  if (f.pyramid.empty() || f.pyramid[0].empty()) throw std::invalid_argument(who + "no pyramid");
  for (const cv::KeyPoint& kp : f.keypoints) {
    if (kp.octave < 0 || static_cast<size_t>(kp.octave) >= f.pyramid.size() ||
        static_cast<size_t>(kp.octave) >= n_scales) {
      throw std::invalid_argument(who + "keypoint octave " + std::to_string(kp.octave) +
                                  " has no pyramid level or scale factor");
    }
    if (f.pyramid[kp.octave].type() != CV_8UC1) {
      throw std::invalid_argument(who + "pyramid levels must be CV_8UC1");
    }
  }
}

}  // namespace

bool StereoMatchOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (max_descriptor_distance < 1 || max_descriptor_distance > 8 * kOrbDescriptorBytes + 1)
    return fail("max_descriptor_distance must be in [1, 257]");
  if (!std::isfinite(min_depth_m) || min_depth_m < 0) return fail("min_depth_m must be >= 0");
  if (!std::isfinite(max_depth_m) || max_depth_m < 0) return fail("max_depth_m must be >= 0");
  if (max_depth_m > 0 && min_depth_m > 0 && max_depth_m <= min_depth_m)
    return fail("max_depth_m must be 0 or greater than min_depth_m");
  if (sad_window_half_px < 1 || sad_window_half_px > kMaxSadWindowHalfPx)
    return fail("sad_window_half_px must be in [1, " + std::to_string(kMaxSadWindowHalfPx) + "]");
  if (sad_search_half_px < 2 || sad_search_half_px > 64)
    return fail("sad_search_half_px must be in [2, 64]");
  if (!std::isfinite(outlier_sad_factor) || outlier_sad_factor <= 0)
    return fail("outlier_sad_factor must be > 0");
  if (subpixel_fit != SubpixelFit::kParabola && subpixel_fit != SubpixelFit::kEquiangular)
    return fail("subpixel_fit must be kParabola or kEquiangular");
  return true;
}

StereoMatches MatchStereo(const StereoRig& rig, const OrbFeatures& left, const OrbFeatures& right,
                          const std::vector<double>& scale_factors,
                          const StereoMatchOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("StereoMatchOptions: " + why);
  if (!rig.IsValid(&why)) throw std::invalid_argument("MatchStereo: rig: " + why);
  if (!rig.IsStereo()) throw std::invalid_argument("MatchStereo: the rig has no baseline");
  CheckFeatures(left, "left", scale_factors.size());
  CheckFeatures(right, "right", scale_factors.size());

  const size_t n_left = left.keypoints.size();
  StereoMatches out;
  out.u_right_px.assign(n_left, -1.0f);
  out.depth_m.assign(n_left, -1.0f);
  if (n_left == 0 || right.keypoints.empty()) return out;
  if (left.pyramid.size() != right.pyramid.size() ||
      left.pyramid[0].size() != right.pyramid[0].size()) {
    throw std::invalid_argument("MatchStereo: left and right pyramids differ in size");
  }

  // Right keypoints by image row (compressed rows: row_begin[r]..row_begin[r+1] in row_items).
  const int n_rows = right.pyramid[0].rows;
  std::vector<int> row_begin(n_rows + 1, 0);
  std::vector<int> band_lo(right.keypoints.size()), band_hi(right.keypoints.size());
  for (size_t j = 0; j < right.keypoints.size(); ++j) {
    const cv::KeyPoint& kp = right.keypoints[j];
    const float r = kRowBandSigmas * static_cast<float>(scale_factors[kp.octave]);
    band_lo[j] = std::max(0, static_cast<int>(std::floor(kp.pt.y - r)));
    band_hi[j] = std::min(n_rows - 1, static_cast<int>(std::ceil(kp.pt.y + r)));
    for (int y = band_lo[j]; y <= band_hi[j]; ++y) ++row_begin[y + 1];
  }
  for (int y = 0; y < n_rows; ++y) row_begin[y + 1] += row_begin[y];
  // Row lists hold (x, octave, index) of the right keypoints, sorted by x within a row.
  struct RightEntry {
    float x;
    int octave;
    int index;
  };
  std::vector<RightEntry> row_items(row_begin[n_rows]);
  {
    std::vector<int> by_x(right.keypoints.size());
    for (size_t j = 0; j < by_x.size(); ++j) by_x[j] = static_cast<int>(j);
    std::stable_sort(by_x.begin(), by_x.end(), [&](int a, int b) {
      return right.keypoints[a].pt.x < right.keypoints[b].pt.x;
    });
    std::vector<int> fill(row_begin.begin(), row_begin.end() - 1);
    for (int j : by_x) {
      const RightEntry e{right.keypoints[j].pt.x, right.keypoints[j].octave, j};
      for (int y = band_lo[j]; y <= band_hi[j]; ++y) row_items[fill[y]++] = e;
    }
  }

  const double bf = rig.Bf();
  const double min_disparity = options.max_depth_m > 0 ? bf / options.max_depth_m : 0.0;
  const double max_disparity =
      bf / (options.min_depth_m > 0 ? options.min_depth_m : rig.baseline_m);  // fx by default
  const int w = options.sad_window_half_px;
  const int search = options.sad_search_half_px;
  const int window_area = (2 * w + 1) * (2 * w + 1);
  SadWorkspace workspace;
  std::vector<float> sad_per_px(n_left, -1.0f);  // best SAD per pixel of the accepted matches

  for (size_t i = 0; i < n_left; ++i) {
    const cv::KeyPoint& kl = left.keypoints[i];
    const int row = static_cast<int>(std::lround(kl.pt.y));
    if (row < 0 || row >= n_rows) continue;
    const float u_left = kl.pt.x;
    const double min_u = u_left - max_disparity;
    const double max_u = u_left - min_disparity;
    const std::uint8_t* dl = left.descriptors.ptr<std::uint8_t>(static_cast<int>(i));

    int best_distance = INT_MAX;
    int best_j = -1;
    const RightEntry* first = row_items.data() + row_begin[row];
    const RightEntry* last = row_items.data() + row_begin[row + 1];
    first =
        std::lower_bound(first, last, min_u, [](const RightEntry& e, double u) { return e.x < u; });
    for (const RightEntry* e = first; e != last && e->x <= max_u; ++e) {
      if (std::abs(e->octave - kl.octave) > 1) continue;
      const int d = DescriptorDistance(dl, right.descriptors.ptr<std::uint8_t>(e->index));
      if (d < best_distance) {
        best_distance = d;
        best_j = e->index;
      }
    }
    if (best_j < 0 || best_distance >= options.max_descriptor_distance) continue;

    // Sub-pixel refinement on the left keypoint's pyramid level.
    const int level = kl.octave;
    const cv::Mat& img_l = left.pyramid[level];
    const cv::Mat& img_r = right.pyramid[level];
    const cv::Point2f p_left = left.LevelFromBase(level, kl.pt);
    const int xl = static_cast<int>(std::lround(p_left.x));
    const int yl = static_cast<int>(std::lround(p_left.y));
    const int xr0 =
        static_cast<int>(std::lround(right.LevelFromBase(level, right.keypoints[best_j].pt).x));
    if (xl - w < 0 || xl + w >= img_l.cols || yl - w < 0 || yl + w >= img_l.rows) continue;
    if (xr0 - search - w < 0 || xr0 + search + w >= img_r.cols) continue;

    ZeroMeanSadCosts(img_l, xl, img_r, xr0, yl, w, search, &workspace);
    const std::vector<float>& sad = workspace.cost;
    const int best_k = static_cast<int>(std::min_element(sad.begin(), sad.end()) - sad.begin());
    const int best_inc = best_k - search;
    const float best_sad = sad[best_k];
    if (best_inc == -search || best_inc == search) continue;
    const double d1 = sad[best_inc + search - 1];
    const double d2 = sad[best_inc + search];
    const double d3 = sad[best_inc + search + 1];
    // Offset of the cost minimum from best_inc, from the three costs around it.
    const double denominator = options.subpixel_fit == SubpixelFit::kParabola
                                   ? 2.0 * (d1 + d3 - 2.0 * d2)
                                   : 2.0 * (std::max(d1, d3) - d2);
    if (denominator <= 0) continue;  // flat cost: no defined minimum
    const double delta = (d1 - d3) / denominator;
    if (std::abs(delta) > 1.0) continue;

    double level_disparity = xl - (xr0 + best_inc + delta);
    // A refinement that leaves the window or wanders off the SAD minimum: no reliable depth.
    if (options.slant_refinement &&
        !RefineSlantedDisparity(img_l, img_r, xl, yl, w, kMaxSlantMovePx, &level_disparity))
      continue;
    const float x_right_level = static_cast<float>(xl - level_disparity);
    float u_right = right.BaseFromLevel(level, {x_right_level, p_left.y}).x;
    float disparity = u_left - u_right;
    if (disparity < min_disparity || disparity >= max_disparity) continue;
    if (disparity < kMinDisparityPx) {
      disparity = kMinDisparityPx;
      u_right = u_left - kMinDisparityPx;
    }
    out.u_right_px[i] = u_right;
    out.depth_m[i] = static_cast<float>(bf / disparity);
    sad_per_px[i] = best_sad / static_cast<float>(window_area);
  }

  // Reject matches whose correlation cost is far above the frame's median.
  std::vector<float> costs;
  for (float c : sad_per_px) {
    if (c >= 0) costs.push_back(c);
  }
  if (!costs.empty()) {
    const auto mid = costs.begin() + static_cast<std::ptrdiff_t>(costs.size() / 2);
    std::nth_element(costs.begin(), mid, costs.end());
    // A mean residual under one grey level is never an outlier (matters for perfect images).
    const float threshold = std::max(static_cast<float>(*mid * options.outlier_sad_factor), 1.0f);
    for (size_t i = 0; i < n_left; ++i) {
      if (sad_per_px[i] < 0) continue;
      if (sad_per_px[i] > threshold) {
        out.u_right_px[i] = -1.0f;
        out.depth_m[i] = -1.0f;
      } else {
        ++out.num_matched;
      }
    }
  }
  return out;
}

}  // namespace pcr
