#include "eval/plot.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "eval_test_util.h"
#include "io/trajectory_io.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::eval {
namespace {

size_t CountColor(const cv::Mat& bgr, Rgb c, int tolerance) {
  size_t count = 0;
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b v = bgr.at<cv::Vec3b>(y, x);
      if (std::abs(v[0] - c.b) <= tolerance && std::abs(v[1] - c.g) <= tolerance &&
          std::abs(v[2] - c.r) <= tolerance)
        ++count;
    }
  return count;
}

// How often needle occurs in text.
size_t CountOf(const std::string& text, const std::string& needle) {
  size_t count = 0;
  for (size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1))
    ++count;
  return count;
}

std::vector<PlotSeries> Seq07Series() {
  const Trajectory gt = ReadKittiTrajectory(pcr::test::SharedPath("data/kitti/poses/07.txt"));
  Trajectory est = gt;
  for (size_t i = 0; i < est.size(); ++i)
    est[i].world_from_cam.translation() += Eigen::Vector3d(0.02 * static_cast<double>(i), 0, 0);
  return GroundTruthAndEstimate(gt, est, "PCR-ORB");
}

TEST(PlotTest, PngHasBothTrajectoriesAndAxes) {
  const std::vector<PlotSeries> series = Seq07Series();
  PlotOptions options;
  options.title = "KITTI 07";
  const test::ScopedTempDir dir("pcr_eval_plot");
  const std::string path = dir.path + "/traj.png";
  WriteTrajectoryPlot(path, series, options);
  ASSERT_TRUE(std::filesystem::exists(path));
  EXPECT_GT(std::filesystem::file_size(path), 5000u);
  const cv::Mat img = cv::imread(path, cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, 1000);
  ASSERT_EQ(img.rows, 800);
  // Both polylines (2 px wide over hundreds of pixels) are drawn in their colours.
  EXPECT_GT(CountColor(img, series[0].color, 10), 400u);
  EXPECT_GT(CountColor(img, series[1].color, 10), 400u);
  // Mostly white background, but a real amount of ink (grid, text, frame).
  const size_t white = CountColor(img, Rgb{255, 255, 255}, 0);
  EXPECT_GT(white, img.total() / 2);
  EXPECT_LT(white, img.total() - 5000);
  // The title row holds dark text pixels; a blank row above it does not.
  EXPECT_GT(CountColor(img.rowRange(15, 45), Rgb{30, 30, 30}, 60), 50u);
  EXPECT_EQ(CountColor(img.rowRange(0, 5), Rgb{30, 30, 30}, 60), 0u);
}

TEST(PlotTest, RingsMarkTheirPlacesInPngAndSvg) {
  // Two rings (e.g. where loops were closed) on KITTI 07's trajectory: a ring of radius
  // kPlotRingRadiusPx in its colour around each place (a ring, not a disc) and one legend row; the
  // SVG has one circle per place and no polyline for them.
  std::vector<PlotSeries> series = Seq07Series();
  const Rgb green{40, 170, 40};
  PlotSeries rings{"loop closed",
                   {series[1].trajectory[300], series[1].trajectory[900]},
                   green,
                   2.0,
                   PlotStyle::kRings};
  series.push_back(rings);
  const cv::Mat img = RenderTrajectoryPlot(series, PlotOptions{});
  const size_t without = CountColor(RenderTrajectoryPlot(Seq07Series(), PlotOptions{}), green, 10);
  EXPECT_EQ(without, 0u);
  // Each ring is about 2 * pi * 8 px long and 2 px wide (measured 262 px for the three, the
  // legend's included; three filled discs of that radius would cover about 600).
  const size_t ink = CountColor(img, green, 10);
  EXPECT_GT(ink, 3 * 40u);
  EXPECT_LT(ink, 3 * 160u);
  const std::string svg = RenderTrajectoryPlotSvg(series, PlotOptions{});
  EXPECT_EQ(CountOf(svg, "stroke=\"#28aa28\""), 3u);  // two places and the legend's sample
  EXPECT_EQ(CountOf(svg, "<polyline"), 2u);
  EXPECT_NE(svg.find(">loop closed<"), std::string::npos);
}

TEST(PlotTest, SvgHasPolylinesLegendAndTicks) {
  const std::vector<PlotSeries> series = Seq07Series();
  PlotOptions options;
  options.title = "KITTI 07 <top view>";
  const test::ScopedTempDir dir("pcr_eval_plot");
  const std::string path = dir.path + "/traj.SVG";
  WriteTrajectoryPlot(path, series, options);
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string svg = buffer.str();
  EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_EQ(CountOf(svg, "<polyline"), 2u);
  EXPECT_NE(svg.find(">ground truth<"), std::string::npos);
  EXPECT_NE(svg.find(">PCR-ORB<"), std::string::npos);
  EXPECT_NE(svg.find("KITTI 07 &lt;top view&gt;"), std::string::npos);
  EXPECT_NE(svg.find(">x [m]<"), std::string::npos);
  EXPECT_NE(svg.find(">z [m]<"), std::string::npos);
  // Seq 07's first 160 poses span x from -77 m to 0: a tick label "-40" must be there.
  EXPECT_NE(svg.find(">-40<"), std::string::npos);
}

TEST(PlotTest, RejectsUnknownExtensionAndBadOptions) {
  const std::vector<PlotSeries> series = Seq07Series();
  EXPECT_THROW(WriteTrajectoryPlot("/tmp/plot.jpg", series, {}), InputError);
  EXPECT_THROW(WriteTrajectoryPlot("/nonexistent/dir/plot.png", series, {}), InputError);
  PlotOptions bad;
  bad.vertical_axis = bad.horizontal_axis;
  EXPECT_THROW(RenderTrajectoryPlot(series, bad), std::invalid_argument);
  // An empty or single-point plot still renders.
  EXPECT_NO_THROW(RenderTrajectoryPlot({}, {}));
  EXPECT_NO_THROW(
      RenderTrajectoryPlot({PlotSeries{"one", {test::MakeStamped(SE3::Identity())}, {}, 2}}, {}));
}

}  // namespace
}  // namespace pcr::eval
