#include "slam/features/orb_extractor.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <numbers>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/popcount_clones.h"

namespace pcr {
namespace {

constexpr int kPatchRadius = kOrbPatchSize / 2;  // 15
// Every sampling point of the binary test pattern lies in a disc of this radius, so that any
// rotation of the pattern stays inside the orientation disc (and inside the edge threshold).
constexpr int kPatternRadius = kPatchRadius;
constexpr double kPatternSigmaPx = 8.0;  // spread of the sampling points around the keypoint
// Seed of the pattern generator. The pattern is part of the descriptor format: changing the seed
// or the generator makes descriptors incompatible with stored ones (vocabularies, maps). This
// seed was the best of ten consecutive ones by correct matches between consecutive KITTI frames
// (sequences 06, 00 and 07), on par with OpenCV's learned rBRIEF pattern.
constexpr std::uint64_t kPatternSeed = 0x5043522D4F524232ull;
constexpr int kNumTests = 8 * kOrbDescriptorBytes;  // 256 point pairs
constexpr int kCellSizePx = 30;                     // FAST grid cell, pixels of the level
constexpr int kFastRadius = 3;                      // cv::FAST needs 3 pixels around a corner
constexpr int kMinEdgeThresholdPx = kPatchRadius + 1;

// Half widths of the rows of the orientation disc: pixel (u, v) is in the disc iff
// |u| <= half_width[|v|]. Defined by u^2 + v^2 <= r^2 on integers, so the disc is symmetric
// under 90-degree rotations and mirror images.
using DiscHalfWidths = std::array<int, kPatchRadius + 1>;
const DiscHalfWidths& OrientationDisc() {
  static const DiscHalfWidths disc = [] {
    DiscHalfWidths w{};
    const int r2 = kPatchRadius * kPatchRadius + kPatchRadius;  // radius ~15.5
    for (int v = 0; v <= kPatchRadius; ++v) {
      int u = 0;
      while ((u + 1) * (u + 1) + v * v <= r2) ++u;
      w[v] = u;
    }
    return w;
  }();
  return disc;
}

// Sampling pattern of the binary tests, generated once from a fixed seed: both points of a pair
// are drawn independently from an isotropic Gaussian around the keypoint (the "G II" pattern of
// the BRIEF paper, with sigma kPatternSigmaPx, a bit wider than the paper's patch size / 5, which
// matched better), rounded to integer pixels and redrawn until they lie in the disc of radius
// kPatternRadius, are at least 2 px apart and differ from every earlier pair.
struct alignas(16) TestPattern {
  // x and y of point a (index 2i) and point b (index 2i + 1) of test i.
  std::array<float, 2 * kNumTests> x;
  std::array<float, 2 * kNumTests> y;
};

// SplitMix64: a tiny generator with a fully specified output sequence (std::normal_distribution
// is not specified bit-for-bit across standard libraries).
class PatternRng {
 public:
  explicit PatternRng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t Next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // Uniform in (0, 1).
  double Uniform() { return (static_cast<double>(Next() >> 11) + 0.5) * 0x1.0p-53; }
  // Standard normal pair by the Box-Muller transform.
  std::pair<double, double> Gaussian2() {
    const double r = std::sqrt(-2.0 * std::log(Uniform()));
    const double t = 2.0 * std::numbers::pi * Uniform();
    return {r * std::cos(t), r * std::sin(t)};
  }

 private:
  std::uint64_t state_;
};

const TestPattern& BinaryTestPattern() {
  static const TestPattern pattern = [] {
    TestPattern p{};
    PatternRng rng(kPatternSeed);
    const double sigma = kPatternSigmaPx;
    auto draw_point = [&](int* px, int* py) {
      while (true) {
        const auto [gx, gy] = rng.Gaussian2();
        const int x = static_cast<int>(std::lround(gx * sigma));
        const int y = static_cast<int>(std::lround(gy * sigma));
        if (x * x + y * y <= kPatternRadius * kPatternRadius) {
          *px = x;
          *py = y;
          return;
        }
      }
    };
    int count = 0;
    while (count < kNumTests) {
      int ax, ay, bx, by;
      draw_point(&ax, &ay);
      draw_point(&bx, &by);
      if ((ax - bx) * (ax - bx) + (ay - by) * (ay - by) < 4) continue;
      bool duplicate = false;
      for (int i = 0; i < count && !duplicate; ++i) {
        duplicate =
            p.x[2 * i] == ax && p.y[2 * i] == ay && p.x[2 * i + 1] == bx && p.y[2 * i + 1] == by;
      }
      if (duplicate) continue;
      p.x[2 * count] = static_cast<float>(ax);
      p.y[2 * count] = static_cast<float>(ay);
      p.x[2 * count + 1] = static_cast<float>(bx);
      p.y[2 * count + 1] = static_cast<float>(by);
      ++count;
    }
    return p;
  }();
  return pattern;
}

// Intensity-centroid orientation (degrees in [0, 360)) of the disc around integer pixel (x, y)
// of `img`; the disc must lie inside the image.
float CentroidAngleDeg(const cv::Mat& img, int x, int y, const DiscHalfWidths& disc) {
  const std::uint8_t* center = img.ptr<std::uint8_t>(y) + x;
  const std::ptrdiff_t step = static_cast<std::ptrdiff_t>(img.step[0]);
  int m10 = 0;
  int m01 = 0;
  for (int u = -kPatchRadius; u <= kPatchRadius; ++u) m10 += u * center[u];
  for (int v = 1; v <= kPatchRadius; ++v) {
    const std::uint8_t* below = center + v * step;
    const std::uint8_t* above = center - v * step;
    const int half = disc[v];
    int diff_sum = 0;
    for (int u = -half; u <= half; ++u) {
      diff_sum += below[u] - above[u];
      m10 += u * (below[u] + above[u]);
    }
    m01 += v * diff_sum;
  }
  return cv::fastAtan2(static_cast<float>(m01), static_cast<float>(m10));
}

// Writes the 32 bytes of the rBRIEF descriptor of integer pixel (x, y) of the smoothed level.
void DescribeKeypoint(const cv::Mat& smoothed, int x, int y, float angle_deg,
                      const TestPattern& pattern, std::uint8_t* descriptor) {
  const float angle_rad = angle_deg * static_cast<float>(std::numbers::pi / 180.0);
  const float c = std::cos(angle_rad);
  const float s = std::sin(angle_rad);
  const int step = static_cast<int>(smoothed.step[0]);
  const std::uint8_t* center = smoothed.ptr<std::uint8_t>(y) + x;
  alignas(16) std::array<int, 2 * kNumTests> offsets;
  // Rotated sample offsets, rounded to the nearest pixel (ties to even, as cvRound).
  const cv::v_float32x4 vc = cv::v_setall_f32(c);
  const cv::v_float32x4 vs = cv::v_setall_f32(s);
  const cv::v_int32x4 vstep = cv::v_setall_s32(step);
  for (int j = 0; j < 2 * kNumTests; j += 4) {
    const cv::v_float32x4 px = cv::v_load(pattern.x.data() + j);
    const cv::v_float32x4 py = cv::v_load(pattern.y.data() + j);
    const cv::v_int32x4 rx = cv::v_round(px * vc - py * vs);
    const cv::v_int32x4 ry = cv::v_round(px * vs + py * vc);
    cv::v_store_aligned(offsets.data() + j, ry * vstep + rx);
  }
  for (int b = 0; b < kOrbDescriptorBytes; ++b) {
    const int* o = offsets.data() + 16 * b;
    unsigned value = 0;
    for (int k = 0; k < 8; ++k) {
      value |= static_cast<unsigned>(center[o[2 * k]] < center[o[2 * k + 1]]) << k;
    }
    descriptor[b] = static_cast<std::uint8_t>(value);
  }
}

// Candidate keypoints of one level, in level pixel coordinates.
struct Candidate {
  float x, y, response;
};

// FAST corners of `level` inside `area`, on a grid of about kCellSizePx cells: the high
// threshold first, the low one in cells where the high one finds nothing. For speed, the high
// threshold runs on whole rows of cells and the low one on runs of adjacent empty cells of a row
// (cv::FAST vectorises along image rows); non-maximum suppression then also acts across the
// borders between cells of such a run, which only removes duplicates of the same corner.
void DetectCorners(const cv::Mat& level, const cv::Rect& area, int threshold_high,
                   int threshold_low, std::vector<cv::KeyPoint>* corners,
                   std::vector<std::uint8_t>* cell_has_corner, std::vector<Candidate>* candidates) {
  candidates->clear();
  const int n_cols = std::max(1, area.width / kCellSizePx);
  const int n_rows = std::max(1, area.height / kCellSizePx);
  const int cell_w = (area.width + n_cols - 1) / n_cols;
  const int cell_h = (area.height + n_rows - 1) / n_rows;
  const int x_end = area.x + area.width;
  // cv::FAST reports corners at least kFastRadius inside the image it gets, so every ROI is
  // padded by kFastRadius to cover exactly the wanted pixels.
  auto detect = [&](int x0, int x1, int y0, int y1, int threshold) {
    const cv::Rect roi(x0 - kFastRadius, y0 - kFastRadius, x1 - x0 + 2 * kFastRadius,
                       y1 - y0 + 2 * kFastRadius);
    cv::FAST(level(roi), *corners, threshold, /*nonmaxSuppression=*/true);
    for (const cv::KeyPoint& kp : *corners) {
      candidates->push_back(
          {kp.pt.x + static_cast<float>(roi.x), kp.pt.y + static_cast<float>(roi.y), kp.response});
    }
  };
  for (int r = 0; r < n_rows; ++r) {
    const int y0 = area.y + r * cell_h;
    const int y1 = std::min(y0 + cell_h, area.y + area.height);
    if (y0 >= y1) break;
    const size_t first_new = candidates->size();
    detect(area.x, x_end, y0, y1, threshold_high);
    if (threshold_low >= threshold_high) continue;
    cell_has_corner->assign(n_cols, 0);
    for (size_t k = first_new; k < candidates->size(); ++k) {
      const int c = static_cast<int>((*candidates)[k].x - static_cast<float>(area.x)) / cell_w;
      (*cell_has_corner)[std::min(c, n_cols - 1)] = 1;
    }
    for (int c = 0; c < n_cols;) {
      if ((*cell_has_corner)[c]) {
        ++c;
        continue;
      }
      int c_end = c + 1;
      while (c_end < n_cols && !(*cell_has_corner)[c_end]) ++c_end;
      const int x0 = area.x + c * cell_w;
      const int x1 = std::min(area.x + c_end * cell_w, x_end);
      if (x0 < x1) detect(x0, x1, y0, y1, threshold_low);
      c = c_end;
    }
  }
}

// Node of the quadtree: a rectangle and the range [begin, end) of candidate indices in it.
struct QuadNode {
  float x0, y0, x1, y1;
  int begin, end;
  int Count() const { return end - begin; }
  bool Splittable() const { return end - begin > 1 && (x1 - x0 > 1.0f || y1 - y0 > 1.0f); }
};

// Splits `node` in four quadrants by reordering indices[node.begin, node.end); appends the
// non-empty children to `out`.
void SplitNode(const QuadNode& node, const std::vector<Candidate>& candidates,
               std::vector<int>* indices, std::vector<QuadNode>* out) {
  const float xm = 0.5f * (node.x0 + node.x1);
  const float ym = 0.5f * (node.y0 + node.y1);
  int* first = indices->data() + node.begin;
  int* last = indices->data() + node.end;
  int* mid_y = std::partition(first, last, [&](int i) { return candidates[i].y < ym; });
  int* mid_top = std::partition(first, mid_y, [&](int i) { return candidates[i].x < xm; });
  int* mid_bottom = std::partition(mid_y, last, [&](int i) { return candidates[i].x < xm; });
  const int base = node.begin;
  auto offset = [&](const int* p) { return base + static_cast<int>(p - first); };
  const QuadNode children[4] = {
      {node.x0, node.y0, xm, ym, node.begin, offset(mid_top)},
      {xm, node.y0, node.x1, ym, offset(mid_top), offset(mid_y)},
      {node.x0, ym, xm, node.y1, offset(mid_y), offset(mid_bottom)},
      {xm, ym, node.x1, node.y1, offset(mid_bottom), node.end},
  };
  for (const QuadNode& child : children) {
    if (child.Count() > 0) out->push_back(child);
  }
}

// Working buffers of the quadtree, reused across levels.
struct QuadtreeBuffers {
  std::vector<int> indices, root_of, root_begin, fill;
  std::vector<QuadNode> nodes, next, order;
};

// Spreads at most `budget` of the candidates over `area` with a quadtree: nodes are split in
// breadth-first rounds (a round splits every node holding more than one candidate) until there
// are at least budget * oversplit nodes; the last round splits the most populated nodes first and
// stops there. Each final node keeps its strongest candidate, and of those the `budget` strongest
// are chosen (oversplit 1 keeps every node's winner). Writes the chosen indices, ascending.
void DistributeQuadtree(const std::vector<Candidate>& candidates, const cv::Rect& area, int budget,
                        double oversplit, QuadtreeBuffers* buf, std::vector<int>* chosen) {
  chosen->clear();
  const int n_nodes_wanted = static_cast<int>(std::ceil(budget * oversplit));
  const int n = static_cast<int>(candidates.size());
  if (budget <= 0 || n == 0) return;
  std::vector<int>& indices = buf->indices;
  indices.resize(n);

  std::vector<QuadNode>& nodes = buf->nodes;
  nodes.clear();
  if (n > n_nodes_wanted) {
    // Roots: about square cells along the longer side.
    const int n_roots_x =
        std::max(1, static_cast<int>(std::lround(static_cast<double>(area.width) / area.height)));
    const int n_roots_y =
        std::max(1, static_cast<int>(std::lround(static_cast<double>(area.height) / area.width)));
    const float root_w = static_cast<float>(area.width) / n_roots_x;
    const float root_h = static_cast<float>(area.height) / n_roots_y;
    // Assign candidates to roots by a counting sort on the root id.
    const int n_roots = n_roots_x * n_roots_y;
    std::vector<int>& root_of = buf->root_of;
    root_of.resize(n);
    std::vector<int>& root_begin = buf->root_begin;
    root_begin.assign(n_roots + 1, 0);
    for (int i = 0; i < n; ++i) {
      const int rx = std::min(n_roots_x - 1, static_cast<int>((candidates[i].x - area.x) / root_w));
      const int ry = std::min(n_roots_y - 1, static_cast<int>((candidates[i].y - area.y) / root_h));
      root_of[i] = ry * n_roots_x + rx;
      ++root_begin[root_of[i] + 1];
    }
    for (int r = 0; r < n_roots; ++r) root_begin[r + 1] += root_begin[r];
    std::vector<int>& fill = buf->fill;
    fill.assign(root_begin.begin(), root_begin.end() - 1);
    for (int i = 0; i < n; ++i) indices[fill[root_of[i]]++] = i;
    for (int ry = 0; ry < n_roots_y; ++ry) {
      for (int rx = 0; rx < n_roots_x; ++rx) {
        const int id = ry * n_roots_x + rx;
        if (root_begin[id + 1] > root_begin[id]) {
          const float x0 = area.x + rx * root_w;
          const float y0 = area.y + ry * root_h;
          nodes.push_back({x0, y0, x0 + root_w, y0 + root_h, root_begin[id], root_begin[id + 1]});
        }
      }
    }

    std::vector<QuadNode>& next = buf->next;
    std::vector<QuadNode>& order = buf->order;
    while (static_cast<int>(nodes.size()) < n_nodes_wanted) {
      int n_splittable = 0;
      for (const QuadNode& node : nodes) n_splittable += node.Splittable() ? 1 : 0;
      if (n_splittable == 0) break;
      const bool last_round = static_cast<int>(nodes.size()) + 3 * n_splittable >= n_nodes_wanted;
      if (!last_round) {
        next.clear();
        for (const QuadNode& node : nodes) {
          if (node.Splittable()) {
            SplitNode(node, candidates, &indices, &next);
          } else {
            next.push_back(node);
          }
        }
        nodes.swap(next);
        continue;
      }
      // Last round: split the most populated nodes first until there are enough nodes.
      order.clear();
      next.clear();
      for (const QuadNode& node : nodes) (node.Splittable() ? order : next).push_back(node);
      std::stable_sort(order.begin(), order.end(),
                       [](const QuadNode& a, const QuadNode& b) { return a.Count() > b.Count(); });
      size_t k = 0;
      for (; k < order.size(); ++k) {
        if (next.size() + (order.size() - k) >= static_cast<size_t>(n_nodes_wanted)) break;
        SplitNode(order[k], candidates, &indices, &next);
      }
      next.insert(next.end(), order.begin() + static_cast<std::ptrdiff_t>(k), order.end());
      nodes.swap(next);
    }
  } else {
    for (int i = 0; i < n; ++i) {
      indices[i] = i;
      nodes.push_back(
          {candidates[i].x, candidates[i].y, candidates[i].x, candidates[i].y, i, i + 1});
    }
  }

  for (const QuadNode& node : nodes) {
    int best = indices[node.begin];
    for (int k = node.begin + 1; k < node.end; ++k) {
      if (candidates[indices[k]].response > candidates[best].response) best = indices[k];
    }
    chosen->push_back(best);
  }
  if (static_cast<int>(chosen->size()) > budget) {
    // Total order (response, then position) so that the result does not depend on the sort.
    auto stronger = [&](int a, int b) {
      const Candidate& ca = candidates[a];
      const Candidate& cb = candidates[b];
      if (ca.response != cb.response) return ca.response > cb.response;
      if (ca.y != cb.y) return ca.y < cb.y;
      return ca.x < cb.x;
    };
    std::nth_element(chosen->begin(), chosen->begin() + budget, chosen->end(), stronger);
    chosen->resize(budget);
  }
  std::sort(chosen->begin(), chosen->end());
}

}  // namespace

bool OrbOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (num_features < 1) return fail("num_features must be >= 1");
  if (!(std::isfinite(scale_factor) && scale_factor > 1.0)) return fail("scale_factor must be > 1");
  if (num_levels < 1 || num_levels > 32) return fail("num_levels must be in [1, 32]");
  if (fast_threshold_high < 1 || fast_threshold_high > 254)
    return fail("fast_threshold_high must be in [1, 254]");
  if (fast_threshold_low < 1 || fast_threshold_low > fast_threshold_high)
    return fail("fast_threshold_low must be in [1, fast_threshold_high]");
  if (!(std::isfinite(quadtree_oversplit) && quadtree_oversplit >= 1.0 &&
        quadtree_oversplit <= 16.0))
    return fail("quadtree_oversplit must be in [1, 16]");
  if (edge_threshold_px < kMinEdgeThresholdPx)
    return fail("edge_threshold_px must be >= " + std::to_string(kMinEdgeThresholdPx) +
                " (orientation patch radius + 1)");
  return true;
}

cv::Point2f OrbFeatures::LevelFromBase(int level, const cv::Point2f& p_base_px) const {
  const cv::Mat& base = pyramid.at(0);
  const cv::Mat& lvl = pyramid.at(static_cast<size_t>(level));
  const float sx = static_cast<float>(lvl.cols) / static_cast<float>(base.cols);
  const float sy = static_cast<float>(lvl.rows) / static_cast<float>(base.rows);
  return {(p_base_px.x + 0.5f) * sx - 0.5f, (p_base_px.y + 0.5f) * sy - 0.5f};
}

cv::Point2f OrbFeatures::BaseFromLevel(int level, const cv::Point2f& p_level_px) const {
  const cv::Mat& base = pyramid.at(0);
  const cv::Mat& lvl = pyramid.at(static_cast<size_t>(level));
  const float sx = static_cast<float>(base.cols) / static_cast<float>(lvl.cols);
  const float sy = static_cast<float>(base.rows) / static_cast<float>(lvl.rows);
  return {(p_level_px.x + 0.5f) * sx - 0.5f, (p_level_px.y + 0.5f) * sy - 0.5f};
}

OrbExtractor::OrbExtractor(const OrbOptions& options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("OrbOptions: " + why);
  const int n_levels = options_.num_levels;
  scale_factors_.resize(n_levels);
  level_sigma2_.resize(n_levels);
  inv_level_sigma2_.resize(n_levels);
  for (int i = 0; i < n_levels; ++i) {
    scale_factors_[i] = std::pow(options_.scale_factor, i);
    level_sigma2_[i] = scale_factors_[i] * scale_factors_[i];
    inv_level_sigma2_[i] = 1.0 / level_sigma2_[i];
  }
  // Geometric split: level i gets a share proportional to 1 / scale^i; the last level takes
  // what rounding left over.
  features_per_level_.assign(n_levels, 0);
  const double ratio = 1.0 / options_.scale_factor;
  double share = options_.num_features * (1.0 - ratio) / (1.0 - std::pow(ratio, n_levels));
  int assigned = 0;
  for (int i = 0; i + 1 < n_levels; ++i) {
    features_per_level_[i] =
        std::min(options_.num_features - assigned, static_cast<int>(std::lround(share)));
    assigned += features_per_level_[i];
    share *= ratio;
  }
  features_per_level_[n_levels - 1] = std::max(0, options_.num_features - assigned);
  // Build the shared tables now rather than on the first Extract().
  (void)OrientationDisc();
  (void)BinaryTestPattern();
}

OrbFeatures OrbExtractor::Extract(const cv::Mat& gray) const {
  if (gray.empty()) throw std::invalid_argument("OrbExtractor::Extract: empty image");
  if (gray.type() != CV_8UC1) {
    throw std::invalid_argument("OrbExtractor::Extract: expected a CV_8UC1 grey image, got type " +
                                std::to_string(gray.type()));
  }
  const int n_levels = options_.num_levels;
  const int edge = options_.edge_threshold_px;
  OrbFeatures out;
  out.pyramid.resize(n_levels);
  out.pyramid[0] = gray.clone();
  for (int i = 1; i < n_levels; ++i) {
    const cv::Size size(static_cast<int>(std::lround(gray.cols / scale_factors_[i])),
                        static_cast<int>(std::lround(gray.rows / scale_factors_[i])));
    if (size.width < 1 || size.height < 1) {
      out.pyramid[i] = cv::Mat(std::max(size.height, 0), std::max(size.width, 0), CV_8UC1);
      continue;
    }
    cv::resize(out.pyramid[i - 1], out.pyramid[i], size, 0, 0, cv::INTER_LINEAR);
  }

  const DiscHalfWidths& disc = OrientationDisc();
  const TestPattern& pattern = BinaryTestPattern();
  std::vector<cv::KeyPoint> cell_corners;
  std::vector<std::uint8_t> cell_has_corner;
  std::vector<Candidate> candidates;
  std::vector<int> chosen;
  QuadtreeBuffers quadtree;
  std::vector<int> level_begin(n_levels + 1, 0);
  out.keypoints.reserve(options_.num_features);

  for (int level = 0; level < n_levels; ++level) {
    level_begin[level] = static_cast<int>(out.keypoints.size());
    const cv::Mat& img = out.pyramid[level];
    const cv::Rect area(edge, edge, img.cols - 2 * edge, img.rows - 2 * edge);
    if (area.width < 1 || area.height < 1 || features_per_level_[level] == 0) continue;
    DetectCorners(img, area, options_.fast_threshold_high, options_.fast_threshold_low,
                  &cell_corners, &cell_has_corner, &candidates);
    DistributeQuadtree(candidates, area, features_per_level_[level], options_.quadtree_oversplit,
                       &quadtree, &chosen);
    const float size = static_cast<float>(kOrbPatchSize * scale_factors_[level]);
    for (int index : chosen) {
      const Candidate& c = candidates[index];
      const float angle = CentroidAngleDeg(img, static_cast<int>(c.x), static_cast<int>(c.y), disc);
      // Level coordinates for now; converted to level 0 after the descriptors.
      out.keypoints.emplace_back(c.x, c.y, size, angle, c.response, level);
    }
  }
  level_begin[n_levels] = static_cast<int>(out.keypoints.size());

  out.descriptors.create(static_cast<int>(out.keypoints.size()), kOrbDescriptorBytes, CV_8UC1);
  cv::Mat smoothed;
  for (int level = 0; level < n_levels; ++level) {
    if (level_begin[level] == level_begin[level + 1]) continue;
    const cv::Mat& img = out.pyramid[level];
    cv::GaussianBlur(img, smoothed, cv::Size(7, 7), 2.0, 2.0, cv::BORDER_REFLECT_101);
    const float sx = static_cast<float>(gray.cols) / static_cast<float>(img.cols);
    const float sy = static_cast<float>(gray.rows) / static_cast<float>(img.rows);
    for (int k = level_begin[level]; k < level_begin[level + 1]; ++k) {
      cv::KeyPoint& kp = out.keypoints[k];
      DescribeKeypoint(smoothed, static_cast<int>(kp.pt.x), static_cast<int>(kp.pt.y), kp.angle,
                       pattern, out.descriptors.ptr<std::uint8_t>(k));
      kp.pt.x = (kp.pt.x + 0.5f) * sx - 0.5f;
      kp.pt.y = (kp.pt.y + 0.5f) * sy - 0.5f;
    }
  }
  return out;
}

PCR_POPCNT_CLONES int DescriptorDistance(const std::uint8_t* a, const std::uint8_t* b) {
  int distance = 0;
  for (int i = 0; i < kOrbDescriptorBytes; i += 8) {
    std::uint64_t wa, wb;
    std::memcpy(&wa, a + i, 8);
    std::memcpy(&wb, b + i, 8);
    distance += std::popcount(wa ^ wb);
  }
  return distance;
}

int DescriptorDistance(const cv::Mat& a, const cv::Mat& b) {
  auto ok = [](const cv::Mat& m) {
    return m.depth() == CV_8U && m.rows == 1 &&
           m.cols * static_cast<int>(m.elemSize()) == kOrbDescriptorBytes;
  };
  if (!ok(a) || !ok(b)) {
    throw std::invalid_argument("DescriptorDistance: expected two 1 x 32 CV_8U descriptors");
  }
  return DescriptorDistance(a.ptr<std::uint8_t>(0), b.ptr<std::uint8_t>(0));
}

}  // namespace pcr
