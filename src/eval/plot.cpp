#include "eval/plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "slam/common/error.h"

namespace pcr::eval {
namespace {

constexpr int kMarginLeft = 84, kMarginRight = 28, kMarginTop = 56, kMarginBottom = 64;
constexpr int kMinTickSpacingPx = 80;
constexpr Rgb kGridColor{232, 232, 232}, kFrameColor{110, 110, 110}, kTextColor{30, 30, 30};
constexpr const char* kAxisNames[3] = {"x", "y", "z"};

// Pixel geometry shared by the PNG and SVG renderers.
struct Layout {
  int area_left = 0, area_top = 0, area_right = 0, area_bottom = 0;
  double h_min_m = 0, v_min_m = 0;  // data at the area's left / bottom edge
  double m_per_px = 1;
  double tick_step_m = 1;
  int tick_decimals = 0;
  std::vector<double> h_ticks_m, v_ticks_m;
  int h_axis = 0, v_axis = 2;

  double PixelX(double h_m) const { return area_left + (h_m - h_min_m) / m_per_px; }
  double PixelY(double v_m) const { return area_bottom - (v_m - v_min_m) / m_per_px; }
  cv::Point2d Pixel(const SE3& pose) const {
    const Eigen::Vector3d p = pose.translation();
    return {PixelX(p(h_axis)), PixelY(p(v_axis))};
  }
  std::string TickLabel(double value_m) const {
    std::string s = fmt::format("{:.{}f}", value_m, tick_decimals);
    if (s.find_first_not_of("-0.") == std::string::npos && s[0] == '-') s.erase(0, 1);  // "-0"
    return s;
  }
};

double NiceStep(double raw) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double normalized = raw / magnitude;
  const double nice = normalized <= 1 ? 1 : normalized <= 2 ? 2 : normalized <= 5 ? 5 : 10;
  return nice * magnitude;
}

std::vector<double> Ticks(double from_m, double to_m, double step_m) {
  std::vector<double> ticks;
  for (double k = std::ceil(from_m / step_m - 1e-9); k * step_m <= to_m + 1e-9 * step_m; k += 1)
    ticks.push_back(k * step_m);
  return ticks;
}

Layout ComputeLayout(const std::vector<PlotSeries>& series, const PlotOptions& o) {
  Layout l;
  l.h_axis = o.horizontal_axis;
  l.v_axis = o.vertical_axis;
  l.area_left = kMarginLeft;
  l.area_top = kMarginTop;
  l.area_right = o.width_px - kMarginRight;
  l.area_bottom = o.height_px - kMarginBottom;
  double h_lo = INFINITY, h_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY;
  for (const PlotSeries& s : series)
    for (const StampedPose& p : s.trajectory) {
      const Eigen::Vector3d t = p.world_from_cam.translation();
      h_lo = std::min(h_lo, t(l.h_axis));
      h_hi = std::max(h_hi, t(l.h_axis));
      v_lo = std::min(v_lo, t(l.v_axis));
      v_hi = std::max(v_hi, t(l.v_axis));
    }
  if (!(h_lo <= h_hi)) h_lo = h_hi = v_lo = v_hi = 0;  // nothing to draw
  const double span_m = std::max({h_hi - h_lo, v_hi - v_lo, 1.0});
  const double pad_m = 0.05 * span_m;
  const double area_w = l.area_right - l.area_left, area_h = l.area_bottom - l.area_top;
  l.m_per_px = std::max((h_hi - h_lo + 2 * pad_m) / area_w, (v_hi - v_lo + 2 * pad_m) / area_h);
  l.h_min_m = 0.5 * (h_lo + h_hi) - 0.5 * area_w * l.m_per_px;
  l.v_min_m = 0.5 * (v_lo + v_hi) - 0.5 * area_h * l.m_per_px;
  l.tick_step_m = NiceStep(kMinTickSpacingPx * l.m_per_px);
  l.tick_decimals = std::max(0, static_cast<int>(-std::floor(std::log10(l.tick_step_m) + 1e-9)));
  l.h_ticks_m = Ticks(l.h_min_m, l.h_min_m + area_w * l.m_per_px, l.tick_step_m);
  l.v_ticks_m = Ticks(l.v_min_m, l.v_min_m + area_h * l.m_per_px, l.tick_step_m);
  return l;
}

struct LegendBox {
  int x = 0, y = 0, width = 0, height = 0;
  static constexpr int kRowHeight = 22, kPadding = 10, kSampleWidth = 30;
};

// The corner of the plot area whose legend box covers the fewest trajectory points.
LegendBox PlaceLegend(const std::vector<PlotSeries>& series, const Layout& l, int widest_label_px) {
  LegendBox box;
  box.width = 2 * LegendBox::kPadding + LegendBox::kSampleWidth + 8 + widest_label_px;
  box.height =
      2 * LegendBox::kPadding - 6 + LegendBox::kRowHeight * static_cast<int>(series.size());
  const int inset = 10;
  const std::array<cv::Point, 4> corners = {
      cv::Point(l.area_left + inset, l.area_top + inset),
      cv::Point(l.area_right - inset - box.width, l.area_top + inset),
      cv::Point(l.area_left + inset, l.area_bottom - inset - box.height),
      cv::Point(l.area_right - inset - box.width, l.area_bottom - inset - box.height)};
  size_t best_hits = SIZE_MAX;
  for (const cv::Point& c : corners) {
    const cv::Rect2d rect(c.x, c.y, box.width, box.height);
    size_t hits = 0;
    for (const PlotSeries& s : series)
      for (const StampedPose& p : s.trajectory) hits += rect.contains(l.Pixel(p.world_from_cam));
    if (hits < best_hits) {
      best_hits = hits;
      box.x = c.x;
      box.y = c.y;
    }
  }
  return box;
}

std::string AxisLabel(int axis) { return fmt::format("{} [m]", kAxisNames[axis]); }

// ---- PNG (OpenCV) ----------------------------------------------------------------------------

cv::Scalar Bgr(Rgb c) { return cv::Scalar(c.b, c.g, c.r); }

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kTickFontScale = 0.45, kLabelFontScale = 0.55, kTitleFontScale = 0.75;

cv::Size TextSize(const std::string& text, double scale, int thickness) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline);
}

void PutText(cv::Mat& img, const std::string& text, cv::Point origin, double scale, Rgb color,
             int thickness = 1) {
  cv::putText(img, text, origin, kFont, scale, Bgr(color), thickness, cv::LINE_AA);
}

constexpr int kShift = 4;  // sub-pixel bits for cv drawing
cv::Point Fixed(cv::Point2d p) {
  return {static_cast<int>(std::lround(p.x * (1 << kShift))),
          static_cast<int>(std::lround(p.y * (1 << kShift)))};
}

// ---- SVG -------------------------------------------------------------------------------------

std::string Hex(Rgb c) { return fmt::format("#{:02x}{:02x}{:02x}", c.r, c.g, c.b); }

std::string EscapeXml(const std::string& text) {
  std::string out;
  for (char ch : text) {
    switch (ch) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += ch;
    }
  }
  return out;
}

void WriteBytesAtomically(const std::string& path, const char* data, size_t size) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path temporary = target.string() + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out)
      throw InputError(path, 0, "cannot write the plot (cannot create " + temporary.string() + ")");
    out.write(data, static_cast<std::streamsize>(size));
    out.close();
    if (!out) {
      std::error_code ignored;
      fs::remove(temporary, ignored);
      throw InputError(path, 0, "cannot write the plot");
    }
  }
  std::error_code ec;
  fs::rename(temporary, target, ec);
  if (ec) {
    fs::remove(temporary, ec);
    throw InputError(path, 0, "cannot write the plot: " + ec.message());
  }
}

}  // namespace

bool PlotOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (width_px < 320 || height_px < 240 || width_px > 8000 || height_px > 8000)
    return fail(
        fmt::format("plot size {}x{} px outside 320x240 .. 8000x8000", width_px, height_px));
  if (horizontal_axis < 0 || horizontal_axis > 2 || vertical_axis < 0 || vertical_axis > 2 ||
      horizontal_axis == vertical_axis)
    return fail("plot axes must be two different indices in 0..2");
  return true;
}

std::vector<PlotSeries> GroundTruthAndEstimate(const Trajectory& ground_truth,
                                               const Trajectory& estimate,
                                               const std::string& estimate_label) {
  return {PlotSeries{"ground truth", ground_truth, Rgb{120, 120, 120}, 4.0},
          PlotSeries{estimate_label, estimate, Rgb{31, 119, 180}, 2.0}};
}

cv::Mat RenderTrajectoryPlot(const std::vector<PlotSeries>& series, const PlotOptions& o) {
  std::string why;
  if (!o.IsValid(&why)) throw std::invalid_argument(why);
  const Layout l = ComputeLayout(series, o);
  cv::Mat img(o.height_px, o.width_px, CV_8UC3, cv::Scalar(255, 255, 255));

  // Grid, ticks and tick labels.
  for (double h : l.h_ticks_m) {
    const int x = static_cast<int>(std::lround(l.PixelX(h)));
    cv::line(img, {x, l.area_top}, {x, l.area_bottom}, Bgr(kGridColor), 1);
    cv::line(img, {x, l.area_bottom}, {x, l.area_bottom + 5}, Bgr(kFrameColor), 1);
    const std::string label = l.TickLabel(h);
    const cv::Size size = TextSize(label, kTickFontScale, 1);
    PutText(img, label, {x - size.width / 2, l.area_bottom + 10 + size.height}, kTickFontScale,
            kTextColor);
  }
  for (double v : l.v_ticks_m) {
    const int y = static_cast<int>(std::lround(l.PixelY(v)));
    cv::line(img, {l.area_left, y}, {l.area_right, y}, Bgr(kGridColor), 1);
    cv::line(img, {l.area_left - 5, y}, {l.area_left, y}, Bgr(kFrameColor), 1);
    const std::string label = l.TickLabel(v);
    const cv::Size size = TextSize(label, kTickFontScale, 1);
    PutText(img, label, {l.area_left - 9 - size.width, y + size.height / 2}, kTickFontScale,
            kTextColor);
  }
  cv::rectangle(img, {l.area_left, l.area_top}, {l.area_right, l.area_bottom}, Bgr(kFrameColor), 1);

  // Axis labels; the vertical one is drawn on its own canvas and rotated.
  {
    const std::string h_label = AxisLabel(l.h_axis);
    const cv::Size size = TextSize(h_label, kLabelFontScale, 1);
    PutText(img, h_label, {(l.area_left + l.area_right - size.width) / 2, o.height_px - 14},
            kLabelFontScale, kTextColor);
    const std::string v_label = AxisLabel(l.v_axis);
    const cv::Size v_size = TextSize(v_label, kLabelFontScale, 1);
    cv::Mat canvas(v_size.height + 8, v_size.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
    PutText(canvas, v_label, {2, v_size.height + 2}, kLabelFontScale, kTextColor);
    cv::Mat rotated;
    cv::rotate(canvas, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int x = 12, y = (l.area_top + l.area_bottom - rotated.rows) / 2;
    if (y >= 0 && y + rotated.rows <= img.rows)
      rotated.copyTo(img(cv::Rect(x, y, rotated.cols, rotated.rows)));
  }

  // Title.
  {
    const cv::Size size = TextSize(o.title, kTitleFontScale, 2);
    PutText(img, o.title, {(o.width_px - size.width) / 2, 16 + size.height}, kTitleFontScale,
            kTextColor, 2);
  }

  // Trajectories, clipped to the plot area, with a marker at each start.
  cv::Mat area = img(cv::Rect(l.area_left + 1, l.area_top + 1, l.area_right - l.area_left - 1,
                              l.area_bottom - l.area_top - 1));
  const cv::Point2d area_origin(l.area_left + 1, l.area_top + 1);
  for (const PlotSeries& s : series) {
    if (s.trajectory.empty()) continue;
    std::vector<cv::Point> points;
    for (const StampedPose& p : s.trajectory)
      points.push_back(Fixed(l.Pixel(p.world_from_cam) - area_origin));
    const int thickness = std::max(1, static_cast<int>(std::lround(s.line_width_px)));
    if (s.style == PlotStyle::kRings) {
      for (const cv::Point& p : points)
        cv::circle(area, p, static_cast<int>(kPlotRingRadiusPx) << kShift, Bgr(s.color), thickness,
                   cv::LINE_AA, kShift);
      continue;
    }
    cv::polylines(area, points, false, Bgr(s.color), thickness, cv::LINE_AA, kShift);
    cv::circle(area, points.front(), 5 << kShift, Bgr(s.color), cv::FILLED, cv::LINE_AA, kShift);
  }

  // Legend.
  int widest = 0;
  for (const PlotSeries& s : series)
    widest = std::max(widest, TextSize(s.label, kLabelFontScale, 1).width);
  const LegendBox box = PlaceLegend(series, l, widest);
  cv::rectangle(img, {box.x, box.y}, {box.x + box.width, box.y + box.height},
                cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(img, {box.x, box.y}, {box.x + box.width, box.y + box.height},
                Bgr(Rgb{190, 190, 190}), 1);
  for (size_t i = 0; i < series.size(); ++i) {
    const int y = box.y + LegendBox::kPadding + 8 + LegendBox::kRowHeight * static_cast<int>(i);
    const int x = box.x + LegendBox::kPadding;
    const int thickness = std::max(1, static_cast<int>(std::lround(series[i].line_width_px)));
    if (series[i].style == PlotStyle::kRings)
      cv::circle(img, {x + LegendBox::kSampleWidth / 2, y}, static_cast<int>(kPlotRingRadiusPx),
                 Bgr(series[i].color), thickness, cv::LINE_AA);
    else
      cv::line(img, {x, y}, {x + LegendBox::kSampleWidth, y}, Bgr(series[i].color), thickness,
               cv::LINE_AA);
    PutText(img, series[i].label, {x + LegendBox::kSampleWidth + 8, y + 5}, kLabelFontScale,
            kTextColor);
  }
  return img;
}

std::string RenderTrajectoryPlotSvg(const std::vector<PlotSeries>& series, const PlotOptions& o) {
  std::string why;
  if (!o.IsValid(&why)) throw std::invalid_argument(why);
  const Layout l = ComputeLayout(series, o);
  const std::string font = "font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\"";
  std::string svg = fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" "
      "viewBox=\"0 0 {0} {1}\">\n"
      "<rect x=\"0\" y=\"0\" width=\"{0}\" height=\"{1}\" fill=\"#ffffff\"/>\n"
      "<defs><clipPath id=\"area\"><rect x=\"{2}\" y=\"{3}\" width=\"{4}\" height=\"{5}\"/>"
      "</clipPath></defs>\n",
      o.width_px, o.height_px, l.area_left, l.area_top, l.area_right - l.area_left,
      l.area_bottom - l.area_top);
  svg += "<g stroke=\"" + Hex(kGridColor) + "\" stroke-width=\"1\">\n";
  for (double h : l.h_ticks_m)
    svg += fmt::format("<line x1=\"{0:.2f}\" y1=\"{1}\" x2=\"{0:.2f}\" y2=\"{2}\"/>\n", l.PixelX(h),
                       l.area_top, l.area_bottom);
  for (double v : l.v_ticks_m)
    svg += fmt::format("<line x1=\"{1}\" y1=\"{0:.2f}\" x2=\"{2}\" y2=\"{0:.2f}\"/>\n", l.PixelY(v),
                       l.area_left, l.area_right);
  svg += "</g>\n";
  svg += fmt::format("<g {} font-size=\"12\" fill=\"{}\">\n", font, Hex(kTextColor));
  for (double h : l.h_ticks_m)
    svg += fmt::format(
        "<line x1=\"{0:.2f}\" y1=\"{1}\" x2=\"{0:.2f}\" y2=\"{2}\" stroke=\"{3}\"/>"
        "<text x=\"{0:.2f}\" y=\"{4}\" text-anchor=\"middle\">{5}</text>\n",
        l.PixelX(h), l.area_bottom, l.area_bottom + 5, Hex(kFrameColor), l.area_bottom + 20,
        l.TickLabel(h));
  for (double v : l.v_ticks_m)
    svg += fmt::format(
        "<line x1=\"{1}\" y1=\"{0:.2f}\" x2=\"{2}\" y2=\"{0:.2f}\" stroke=\"{3}\"/>"
        "<text x=\"{4}\" y=\"{0:.2f}\" dy=\"0.35em\" text-anchor=\"end\">{5}</text>\n",
        l.PixelY(v), l.area_left - 5, l.area_left, Hex(kFrameColor), l.area_left - 9,
        l.TickLabel(v));
  svg += "</g>\n";
  svg += fmt::format(
      "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"{}\"/>\n",
      l.area_left, l.area_top, l.area_right - l.area_left, l.area_bottom - l.area_top,
      Hex(kFrameColor));
  svg += fmt::format(
      "<text x=\"{}\" y=\"{}\" {} font-size=\"14\" text-anchor=\"middle\" fill=\"{}\">{}</text>\n",
      0.5 * (l.area_left + l.area_right), o.height_px - 16, font, Hex(kTextColor),
      AxisLabel(l.h_axis));
  const double v_label_y = 0.5 * (l.area_top + l.area_bottom);
  svg += fmt::format(
      "<text x=\"22\" y=\"{0:.1f}\" transform=\"rotate(-90 22 {0:.1f})\" {1} font-size=\"14\" "
      "text-anchor=\"middle\" fill=\"{2}\">{3}</text>\n",
      v_label_y, font, Hex(kTextColor), AxisLabel(l.v_axis));
  svg += fmt::format(
      "<text x=\"{}\" y=\"34\" {} font-size=\"18\" font-weight=\"bold\" text-anchor=\"middle\" "
      "fill=\"{}\">{}</text>\n",
      0.5 * o.width_px, font, Hex(kTextColor), EscapeXml(o.title));

  svg +=
      "<g clip-path=\"url(#area)\" fill=\"none\" stroke-linejoin=\"round\" "
      "stroke-linecap=\"round\">\n";
  for (const PlotSeries& s : series) {
    if (s.trajectory.empty()) continue;
    if (s.style == PlotStyle::kRings) {
      for (const StampedPose& p : s.trajectory) {
        const cv::Point2d px = l.Pixel(p.world_from_cam);
        svg += fmt::format(
            "<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"{:g}\" stroke=\"{}\" "
            "stroke-width=\"{:g}\"/>\n",
            px.x, px.y, kPlotRingRadiusPx, Hex(s.color), s.line_width_px);
      }
      continue;
    }
    svg += fmt::format("<polyline stroke=\"{}\" stroke-width=\"{:g}\" points=\"", Hex(s.color),
                       s.line_width_px);
    for (const StampedPose& p : s.trajectory) {
      const cv::Point2d px = l.Pixel(p.world_from_cam);
      svg += fmt::format("{:.2f},{:.2f} ", px.x, px.y);
    }
    svg += "\"/>\n";
    const cv::Point2d start = l.Pixel(s.trajectory.front().world_from_cam);
    svg +=
        fmt::format("<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"5\" fill=\"{}\" stroke=\"none\"/>\n",
                    start.x, start.y, Hex(s.color));
  }
  svg += "</g>\n";

  size_t widest_chars = 0;
  for (const PlotSeries& s : series) widest_chars = std::max(widest_chars, s.label.size());
  const LegendBox box = PlaceLegend(series, l, static_cast<int>(8 * widest_chars));
  svg += fmt::format(
      "<g {}><rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"#ffffff\" "
      "stroke=\"#bebebe\"/>\n",
      font, box.x, box.y, box.width, box.height);
  for (size_t i = 0; i < series.size(); ++i) {
    const int y = box.y + LegendBox::kPadding + 8 + LegendBox::kRowHeight * static_cast<int>(i);
    const int x = box.x + LegendBox::kPadding;
    if (series[i].style == PlotStyle::kRings)
      svg += fmt::format(
          "<circle cx=\"{}\" cy=\"{}\" r=\"{:g}\" fill=\"none\" stroke=\"{}\" "
          "stroke-width=\"{:g}\"/>",
          x + LegendBox::kSampleWidth / 2, y, kPlotRingRadiusPx, Hex(series[i].color),
          series[i].line_width_px);
    else
      svg += fmt::format(
          "<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\" stroke-width=\"{:g}\"/>", x,
          y, x + LegendBox::kSampleWidth, y, Hex(series[i].color), series[i].line_width_px);
    svg += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"13\" fill=\"{}\">{}</text>\n",
                       x + LegendBox::kSampleWidth + 8, y + 5, Hex(kTextColor),
                       EscapeXml(series[i].label));
  }
  svg += "</g>\n</svg>\n";
  return svg;
}

namespace {
std::string LowerExtension(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension;
}
}  // namespace

bool HasPlotExtension(const std::string& path) {
  const std::string extension = LowerExtension(path);
  return extension == ".png" || extension == ".svg";
}

void WriteTrajectoryPlot(const std::string& path, const std::vector<PlotSeries>& series,
                         const PlotOptions& options) {
  const std::string extension = LowerExtension(path);
  if (extension == ".svg") {
    const std::string svg = RenderTrajectoryPlotSvg(series, options);
    WriteBytesAtomically(path, svg.data(), svg.size());
  } else if (extension == ".png") {
    std::vector<uchar> png;
    if (!cv::imencode(".png", RenderTrajectoryPlot(series, options), png))
      throw InputError(path, 0, "cannot encode the plot as PNG");
    WriteBytesAtomically(path, reinterpret_cast<const char*>(png.data()), png.size());
  } else {
    throw InputError(path, 0, "plot files must end in .png or .svg");
  }
}

}  // namespace pcr::eval
