#pragma once
// Top-view trajectory plots (ground truth vs estimates) as PNG (OpenCV) or SVG (plain text).
// Default view: x to the right, z up, i.e. the ground plane of KITTI camera frames (x right,
// y down, z forward). Equal scale on both axes, ticks in metres, legend, title.
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "slam/common/pose.h"

namespace pcr::eval {

struct Rgb {
  uint8_t r = 0, g = 0, b = 0;
};

// kLine: a polyline through the positions with a dot at the first; kRings: a ring on each
// position (places along a trajectory, e.g. where loops were closed).
enum class PlotStyle { kLine, kRings };

struct PlotSeries {
  std::string label;
  Trajectory trajectory;  // positions of world_from_cam are drawn
  Rgb color;
  double line_width_px = 2.0;
  PlotStyle style = PlotStyle::kLine;
};

inline constexpr double kPlotRingRadiusPx = 8.0;

struct PlotOptions {
  std::string title = "Trajectory (top view)";
  int width_px = 1000;
  int height_px = 800;
  int horizontal_axis = 0;  // index of the world coordinate drawn to the right (0 = x)
  int vertical_axis = 2;    // index of the world coordinate drawn upwards (2 = z)

  bool IsValid(std::string* why) const;
};

// Ground truth (grey, 4 px, so that it shows around a coinciding estimate) and the estimate
// (blue, 2 px).
std::vector<PlotSeries> GroundTruthAndEstimate(const Trajectory& ground_truth,
                                               const Trajectory& estimate,
                                               const std::string& estimate_label = "estimate");

// An 8-bit BGR image of options.width_px x options.height_px. Throws std::invalid_argument on
// invalid options.
cv::Mat RenderTrajectoryPlot(const std::vector<PlotSeries>& series, const PlotOptions& options);

// The same plot as an SVG document.
std::string RenderTrajectoryPlotSvg(const std::vector<PlotSeries>& series,
                                    const PlotOptions& options);

// True when the path ends in .png or .svg (case-insensitive).
bool HasPlotExtension(const std::string& path);

// Writes a .png or .svg (chosen by the extension, case-insensitive) through a temporary file and
// a rename. Throws pcr::InputError(path, 0, ...) for another extension or a failed write.
void WriteTrajectoryPlot(const std::string& path, const std::vector<PlotSeries>& series,
                         const PlotOptions& options);

}  // namespace pcr::eval
