// Stereo disparity accuracy against ground truth: synthetic loop streets (`pcr_orb synth --route
// loop`) rendered in this process, whose renderer gives each pixel's true depth. Every --stride'th
// frame of a --frames loop (default 600 / 30: 20 frames spread over the whole route, turns
// included) is extracted with the default OrbExtractor and matched by MatchStereo under each
// setting below; each match's disparity is compared with the true one at its left keypoint
// (bilinear in the true disparity, fx * baseline / depth).
//
// Matches at depth edges (the 3x3 pixels around the keypoint not on one plane), where no single
// disparity is right, are counted and left out of the statistics. Errors above 1 px are counted
// as wrong matches and left out of bias, SD, RMS and p95. Rows: all matches, the road (points
// within 3 cm of the frame's road plane, fitted to the true points of the road just in front of
// the car; frames without a flat patch there add no road points), the matches whose SAD window
// holds a markedly nearer surface (WindowHoldsNearer: the window fattens the foreground, and the
// disparity comes out too large), and bins of true disparity.
// Prints figures and asserts nothing; the exit status is 1 only for bad arguments.
//
//   bench_stereo_truth [--seeds 1,2] [--frames 600] [--stride 30]
//
// Runtime: ~0.25 s a frame on one core (render, extract, match three times); the default (two
// seeds, 40 frames) takes ~10 s.
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bench_args.h"
#include "eval/statistics.h"
#include "sim/instances.h"
#include "sim/synthetic_world.h"
#include "slam/common/timing.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/stereo_matcher.h"
#include "slam/geometry/plane.h"

namespace {

struct Setting {
  const char* name;
  pcr::StereoMatchOptions options;
};

std::vector<Setting> Settings() {
  pcr::StereoMatchOptions parabola;
  parabola.subpixel_fit = pcr::SubpixelFit::kParabola;
  pcr::StereoMatchOptions slanted;
  slanted.slant_refinement = true;
  return {{"default (equiangular)", {}}, {"parabola", parabola}, {"slant_refinement", slanted}};
}

// Rows of the table: all, road, a nearer surface in the window, then true-disparity bins.
constexpr std::array<const char*, 7> kRowNames = {"all",     "road",     "nearer",  "d < 4 px",
                                                  "4-10 px", "10-25 px", ">= 25 px"};
constexpr int kRoadRow = 1, kNearerRow = 2, kFirstBinRow = 3;

struct Stats {
  long matched = 0, edge = 0, wrong = 0;
  std::vector<double> errors;  // measured - true, px, |e| <= 1
};

// True disparity at a sub-pixel position (bilinear); NaN off the image, on the sky and at depth
// edges: on one plane the disparity is affine in the pixel coordinates, so the 3x3 pixels around
// the keypoint must fit an affine function within kEdgeResidualPx.
constexpr double kEdgeResidualPx = 0.05;

double TrueDisparity(const cv::Mat& disparity, cv::Point2f pt) {
  const int x0 = static_cast<int>(std::floor(pt.x)), y0 = static_cast<int>(std::floor(pt.y));
  if (x0 < 1 || y0 < 1 || x0 + 2 >= disparity.cols || y0 + 2 >= disparity.rows) return NAN;
  auto at = [&](int y, int x) { return static_cast<double>(disparity.at<float>(y, x)); };
  const int xc = static_cast<int>(std::lround(pt.x)), yc = static_cast<int>(std::lround(pt.y));
  double mean = 0, gx = 0, gy = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const double v = at(yc + dy, xc + dx);
      if (!(v > 0)) return NAN;
      mean += v / 9;
      gx += dx * v / 6;
      gy += dy * v / 6;
    }
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      if (std::abs(at(yc + dy, xc + dx) - (mean + gx * dx + gy * dy)) > kEdgeResidualPx) return NAN;
  const double ax = pt.x - x0, ay = pt.y - y0;
  return (1 - ay) * ((1 - ax) * at(y0, x0) + ax * at(y0, x0 + 1)) +
         ay * ((1 - ax) * at(y0 + 1, x0) + ax * at(y0 + 1, x0 + 1));
}

// Whether the matcher's SAD window (half_px level-0 pixels either side of the keypoint) holds a
// surface markedly nearer than the keypoint's own: a true disparity above kNearerFactor times
// its own plus kNearerPx. Window matching is pulled toward such a surface (it fattens the
// foreground), so these matches' disparities come out too large.
constexpr double kNearerFactor = 1.3, kNearerPx = 0.3;

bool WindowHoldsNearer(const cv::Mat& disparity, cv::Point2f pt, double half_px, double truth) {
  const double limit = kNearerFactor * truth + kNearerPx;
  const int x0 = std::max(0, static_cast<int>(std::floor(pt.x - half_px)));
  const int x1 = std::min(disparity.cols - 1, static_cast<int>(std::ceil(pt.x + half_px)));
  const int y0 = std::max(0, static_cast<int>(std::floor(pt.y - half_px)));
  const int y1 = std::min(disparity.rows - 1, static_cast<int>(std::ceil(pt.y + half_px)));
  for (int y = y0; y <= y1; ++y) {
    const float* row = disparity.ptr<float>(y);
    for (int x = x0; x <= x1; ++x)
      if (row[x] > limit) return true;
  }
  return false;
}

// A true point of the left camera at a pixel and its true disparity.
Eigen::Vector3d PointAt(const pcr::StereoRig& rig, cv::Point2f pt, double disparity) {
  return rig.left.Unproject(Eigen::Vector2d(pt.x, pt.y), rig.Bf() / disparity);
}

constexpr double kRoadBandM = 0.03;  // a road point: within 3 cm of the frame's road plane

// The road plane of a frame in the left camera: a least-squares fit (FitPlaneLeastSquares) to the
// true points of the static world in a patch of road in front of the car (the bottom rows, centre
// columns). None when that patch is not flat (a car close ahead, a kerb): RMS distance > 1 cm.
std::optional<pcr::Plane> FitRoadPlane(const pcr::sim::RenderedFrame& frame,
                                       const cv::Mat& disparity, const pcr::StereoRig& rig) {
  std::vector<Eigen::Vector3d> points;
  const int rows = disparity.rows, cols = disparity.cols;
  for (int y = rows - 40; y < rows - 4; y += 3)
    for (int x = cols / 2 - 150; x <= cols / 2 + 150; x += 6) {
      const float d = disparity.at<float>(y, x);
      if (d > 0 && frame.instance_left.at<uint16_t>(y, x) == pcr::sim::kStaticInstanceId)
        points.push_back(
            PointAt(rig, cv::Point2f(static_cast<float>(x), static_cast<float>(y)), d));
    }
  if (points.size() < 100) return std::nullopt;
  const std::optional<pcr::Plane> plane = pcr::FitPlaneLeastSquares(points);
  if (!plane) return std::nullopt;
  double sum2 = 0;
  for (const Eigen::Vector3d& p : points) sum2 += std::pow(plane->SignedDistance(p), 2);
  if (std::sqrt(sum2 / static_cast<double>(points.size())) > 0.01) return std::nullopt;
  return plane;
}

void PrintRow(const char* name, const Stats& s) {
  const size_t n = s.errors.size();
  const pcr::eval::ErrorStatistics stats = pcr::eval::ComputeStatistics(s.errors);
  std::vector<double> abs_errors;
  abs_errors.reserve(n);
  long within = 0;
  for (double e : s.errors) {
    abs_errors.push_back(std::abs(e));
    within += std::abs(e) <= 0.15;
  }
  const double p95 = n ? pcr::Percentile(std::move(abs_errors), 95.0) : NAN;
  std::printf("  %-10s %8ld %6ld %6ld %8.4f %7.4f %7.4f %7.3f %7.1f%%\n", name, s.matched, s.edge,
              s.wrong, stats.mean, stats.std, stats.rmse, p95, n ? 100.0 * within / n : NAN);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Stereo disparity accuracy against the synthetic renderer's true depth"};
  std::string seeds = "1,2";
  int frames = 600, stride = 30;
  app.add_option("--seeds", seeds, "synthetic loop seeds")->capture_default_str();
  app.add_option("--frames", frames, "frames of each loop route")->capture_default_str();
  app.add_option("--stride", stride, "every stride'th frame is measured")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (frames < 1 || stride < 1) {
    std::fprintf(stderr, "bench_stereo_truth: --frames and --stride must be >= 1\n");
    return 1;
  }
  std::vector<uint64_t> seed_list;
  try {
    seed_list = pcr::bench::ParseSeeds(seeds, "--seeds");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_stereo_truth: %s\n", e.what());
    return 1;
  }
  cv::setNumThreads(1);
  const std::vector<Setting> settings = Settings();
  std::vector<std::array<Stats, kRowNames.size()>> stats(settings.size());
  const pcr::OrbExtractor extractor{pcr::OrbOptions{}};
  long keypoints = 0;
  int measured_frames = 0, road_frames = 0;
  std::printf("bench_stereo_truth: seeds %s, loop of %d frames, every %d'th, load average %s\n",
              seeds.c_str(), frames, stride, pcr::bench::LoadAverage().c_str());
  for (uint64_t seed : seed_list) {
    pcr::sim::SynthOptions o;
    o.frames = frames;
    o.seed = seed;
    o.route = pcr::sim::RouteKind::kLoop;
    const pcr::sim::SyntheticWorld world(o);
    const pcr::StereoRig rig = world.Rig();
    for (int f = 0; f < frames; f += stride) {
      const pcr::sim::RenderedFrame frame = world.RenderFrame(f);
      cv::Mat disparity(frame.depth_left.size(), CV_32FC1);
      for (int y = 0; y < disparity.rows; ++y)
        for (int x = 0; x < disparity.cols; ++x) {
          const float z = frame.depth_left.at<float>(y, x);
          disparity.at<float>(y, x) =
              std::isfinite(z) && z > 0 ? static_cast<float>(rig.Bf() / z) : 0.0f;
        }
      const std::optional<pcr::Plane> road_plane = FitRoadPlane(frame, disparity, rig);
      const pcr::OrbFeatures left = extractor.Extract(frame.left);
      const pcr::OrbFeatures right = extractor.Extract(frame.right);
      keypoints += static_cast<long>(left.keypoints.size());
      ++measured_frames;
      road_frames += road_plane.has_value();
      for (size_t s = 0; s < settings.size(); ++s) {
        const pcr::StereoMatches m =
            pcr::MatchStereo(rig, left, right, extractor.scale_factors(), settings[s].options);
        for (size_t i = 0; i < left.keypoints.size(); ++i) {
          if (m.u_right_px[i] < 0) continue;
          const cv::Point2f pt = left.keypoints[i].pt;
          const double truth = TrueDisparity(disparity, pt);
          const bool edge = !(truth > 0);
          const bool road =
              !edge && road_plane &&
              std::abs(road_plane->SignedDistance(PointAt(rig, pt, truth))) < kRoadBandM;
          const double half_px = (settings[s].options.sad_window_half_px + 0.5) *
                                 extractor.scale_factors()[left.keypoints[i].octave];
          const bool nearer = !edge && WindowHoldsNearer(disparity, pt, half_px, truth);
          const int bin = edge         ? -1
                          : truth < 4  ? kFirstBinRow
                          : truth < 10 ? kFirstBinRow + 1
                          : truth < 25 ? kFirstBinRow + 2
                                       : kFirstBinRow + 3;
          const double e = (pt.x - m.u_right_px[i]) - truth;
          for (int row = 0; row < static_cast<int>(kRowNames.size()); ++row) {
            if (row == kRoadRow && !road) continue;
            if (row == kNearerRow && !nearer) continue;
            if (row >= kFirstBinRow && row != bin) continue;
            if (row >= 1 && edge) continue;
            Stats& st = stats[s][static_cast<size_t>(row)];
            ++st.matched;
            if (edge)
              ++st.edge;
            else if (std::abs(e) > 1.0)
              ++st.wrong;
            else
              st.errors.push_back(e);
          }
        }
      }
    }
  }
  std::printf(
      "%d frames (a road plane in %d), %ld left keypoints; disparity error = measured - true "
      "(px), matches within 1 px of the truth:\n",
      measured_frames, road_frames, keypoints);
  for (size_t s = 0; s < settings.size(); ++s) {
    std::printf("%s\n  %-10s %8s %6s %6s %8s %7s %7s %7s %8s\n", settings[s].name, "rows",
                "matched", "edge", "wrong", "bias", "SD", "RMS", "p95|e|", "<=0.15");
    for (size_t row = 0; row < kRowNames.size(); ++row) PrintRow(kRowNames[row], stats[s][row]);
  }
  std::printf(
      "(matched: matches in the row; edge: at a depth edge, left out; wrong: more than 1 px off, "
      "left out of bias, SD, RMS and p95; <=0.15: share within 0.15 px)\n");
  return 0;
}
