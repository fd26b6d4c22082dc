#include "slam/dynamic/mask_propagation.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <stdexcept>
#include <vector>

#include "slam/dynamic/mask_utils.h"

namespace pcr {
namespace {

bool Fail(std::string* why, const char* text) {
  if (why) *why = text;
  return false;
}

float Median(std::vector<float> v) {
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

// Corners of `grey` inside roi where roi_mask (CV_8U of roi's size) is non-zero.
void CornersIn(const cv::Mat& grey, const cv::Mat& roi_mask, const cv::Rect& roi, int max_corners,
               std::vector<cv::Point2f>* out) {
  if (roi.width < 3 || roi.height < 3 || cv::countNonZero(roi_mask) < 9) return;
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(grey(roi), corners, max_corners, 0.01, 3.0, roi_mask, 3);
  for (const cv::Point2f& c : corners) out->push_back(c + cv::Point2f(roi.tl()));
}

// Scale + translation about the tracks' median point (scale 1 when asked or the tracks are too
// close together to measure it).
InstanceMove Fit(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to,
                 bool with_scale, const MaskPropagationOptions& o) {
  InstanceMove m;
  m.tracks = static_cast<int>(from.size());
  std::vector<float> fx, fy, tx, ty;
  for (size_t i = 0; i < from.size(); ++i) {
    fx.push_back(from[i].x);
    fy.push_back(from[i].y);
    tx.push_back(to[i].x);
    ty.push_back(to[i].y);
  }
  m.centre_from = {Median(fx), Median(fy)};
  m.centre_to = {Median(tx), Median(ty)};
  if (with_scale) {
    std::vector<float> ratios;
    for (size_t i = 0; i < from.size(); ++i) {
      const double d0 = cv::norm(from[i] - m.centre_from);
      if (d0 > 3.0) ratios.push_back(static_cast<float>(cv::norm(to[i] - m.centre_to) / d0));
    }
    if (ratios.size() >= 3) {
      m.scale = std::clamp(Median(ratios), static_cast<float>(o.min_scale),
                           static_cast<float>(o.max_scale));
    }
  }
  return m;
}

// The box moved (continuous corner coordinates; points use pixel centres).
cv::Rect2f MoveBox(const cv::Rect2f& box, const InstanceMove& m, cv::Size size) {
  const cv::Point2f half(0.5f, 0.5f);
  const cv::Point2f a = m.Apply(box.tl() - half) + half;
  const cv::Point2f b = m.Apply(box.br() - half) + half;
  return ClipBox(cv::Rect2f(a, b), size);
}

// Destination pixels of src_pixels moved by m, clipped to the image.
cv::Rect MovedPixels(const cv::Rect& src_pixels, const InstanceMove& m, cv::Size size) {
  const cv::Rect2f moved = MoveBox(cv::Rect2f(src_pixels), m, size);
  return PixelsInBox(moved, size);
}

}  // namespace

bool MaskPropagationOptions::IsValid(std::string* why) const {
  if (max_points_per_instance < 1) return Fail(why, "max_points_per_instance must be >= 1");
  if (min_points < 1) return Fail(why, "min_points must be >= 1");
  if (!(max_fb_error_px > 0)) return Fail(why, "max_fb_error_px must be > 0");
  if (lk_window_px < 5 || lk_window_px % 2 == 0) return Fail(why, "lk_window_px: odd, >= 5");
  if (lk_levels < 0 || lk_levels > 6) return Fail(why, "lk_levels must be in [0, 6]");
  if (!(ring_fraction > 0 && ring_fraction <= 2)) return Fail(why, "ring_fraction: (0, 2]");
  if (confidence_margin_px < 0) return Fail(why, "confidence_margin_px must be >= 0");
  if (!(confidence_decay > 0 && confidence_decay <= 1))
    return Fail(why, "confidence_decay: (0, 1]");
  if (!(min_scale > 0 && min_scale <= 1 && max_scale >= 1))
    return Fail(why, "min_scale must be in (0, 1] and max_scale >= 1");
  return true;
}

const char* ToString(InstanceMoveSource source) {
  switch (source) {
    case InstanceMoveSource::kOwnTracks:
      return "own-tracks";
    case InstanceMoveSource::kSurroundings:
      return "surroundings";
    case InstanceMoveSource::kUnmoved:
      return "unmoved";
  }
  return "?";
}

Segmentation PropagateSegmentation(const Segmentation& seg, const cv::Mat& prev_grey,
                                   const cv::Mat& grey, const MaskPropagationOptions& options,
                                   PropagationReport* report) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("MaskPropagationOptions: " + why);
  if (prev_grey.type() != CV_8UC1 || grey.type() != CV_8UC1 || prev_grey.size() != grey.size())
    throw std::invalid_argument("PropagateSegmentation: images must be CV_8UC1 of one size");
  const cv::Size size = grey.size();
  cv::Mat instance_map = seg.instance_map;
  if (instance_map.empty()) instance_map = BuildInstanceMap(seg.instances, size);
  if (instance_map.size() != size || instance_map.type() != CV_16U)
    throw std::invalid_argument("PropagateSegmentation: instance_map is not CV_16U of the image");
  if (!seg.dynamic_confidence.empty() &&
      (seg.dynamic_confidence.size() != size || seg.dynamic_confidence.type() != CV_32F))
    throw std::invalid_argument("PropagateSegmentation: dynamic_confidence is not CV_32F");

  const int n = static_cast<int>(seg.instances.size());
  const cv::Rect image_rect(cv::Point(), size);
  std::vector<cv::Rect> pixels(n);
  for (int k = 0; k < n; ++k) pixels[k] = PixelsInBox(seg.instances[k].box_px, size);

  // LK on both pyramids, built once (with their derivatives) for every pass: points tracked
  // forward and back, kept (good) when they come back within max_fb_error_px.
  const cv::Size window(options.lk_window_px, options.lk_window_px);
  std::vector<cv::Mat> prev_pyramid, pyramid;
  int levels = -1;
  const auto track = [&](const std::vector<cv::Point2f>& points, std::vector<cv::Point2f>* moved,
                         std::vector<uint8_t>* good) {
    good->assign(points.size(), 0);
    if (points.empty()) return;
    if (levels < 0) {
      levels = cv::buildOpticalFlowPyramid(prev_grey, prev_pyramid, window, options.lk_levels);
      cv::buildOpticalFlowPyramid(grey, pyramid, window, options.lk_levels);
    }
    const cv::TermCriteria stop(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
    std::vector<uint8_t> status_fw, status_bw;
    std::vector<float> err;
    std::vector<cv::Point2f> back;
    cv::calcOpticalFlowPyrLK(prev_pyramid, pyramid, points, *moved, status_fw, err, window, levels,
                             stop);
    cv::calcOpticalFlowPyrLK(pyramid, prev_pyramid, *moved, back, status_bw, err, window, levels,
                             stop);
    for (size_t i = 0; i < points.size(); ++i) {
      (*good)[i] = status_fw[i] && status_bw[i] &&
                   cv::norm(back[i] - points[i]) <= options.max_fb_error_px &&
                   image_rect.contains(cv::Point(cvRound((*moved)[i].x), cvRound((*moved)[i].y)));
    }
  };
  // The good tracks of points[begin[k], begin[k + 1]).
  const auto tracks_of = [](int k, const std::vector<int>& begin,
                            const std::vector<cv::Point2f>& points,
                            const std::vector<cv::Point2f>& moved, const std::vector<uint8_t>& good,
                            std::vector<cv::Point2f>* from, std::vector<cv::Point2f>* to) {
    for (int i = begin[k]; i < begin[k + 1]; ++i) {
      if (!good[i]) continue;
      from->push_back(points[i]);
      to->push_back(moved[i]);
    }
  };

  PropagationReport local;
  PropagationReport& rep = report ? *report : local;
  rep = PropagationReport{};
  rep.moves.resize(n);

  // 1. Each instance's own corners: inside its mask, away from its outline (corners on the
  // outline are half background).
  std::vector<cv::Point2f> points, moved;
  std::vector<uint8_t> good;
  std::vector<int> begin(n + 1);
  for (int k = 0; k < n; ++k) {
    begin[k] = static_cast<int>(points.size());
    if (pixels[k].empty()) continue;
    cv::Mat mine = instance_map(pixels[k]) == (k + 1);
    cv::erode(mine, mine, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(7, 7)),
              cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
    CornersIn(prev_grey, mine, pixels[k], options.max_points_per_instance, &points);
  }
  begin[n] = static_cast<int>(points.size());
  track(points, &moved, &good);
  std::vector<int> without;  // instances with too few tracks of their own
  for (int k = 0; k < n; ++k) {
    std::vector<cv::Point2f> from, to;
    tracks_of(k, begin, points, moved, good, &from, &to);
    if (static_cast<int>(from.size()) >= options.min_points) {
      rep.moves[k] = Fit(from, to, true, options);
      rep.moves[k].source = InstanceMoveSource::kOwnTracks;
      ++rep.own;
    } else {
      without.push_back(k);
    }
  }

  // 2. The others move as their surroundings do: corners in a ring around the box, outside every
  // instance; their translation is applied about the instance's own centre.
  points.clear();
  std::vector<int> ring_begin(without.size() + 1);
  for (size_t w = 0; w < without.size(); ++w) {
    const int k = without[w];
    ring_begin[w] = static_cast<int>(points.size());
    if (pixels[k].empty()) continue;
    const int gx = static_cast<int>(std::lround(pixels[k].width * options.ring_fraction));
    const int gy = static_cast<int>(std::lround(pixels[k].height * options.ring_fraction));
    const cv::Rect ring = (pixels[k] + cv::Size(2 * gx, 2 * gy) - cv::Point(gx, gy)) & image_rect;
    const cv::Mat free_pixels = instance_map(ring) == 0;
    CornersIn(prev_grey, free_pixels, ring, options.max_points_per_instance, &points);
  }
  ring_begin[without.size()] = static_cast<int>(points.size());
  track(points, &moved, &good);
  for (size_t w = 0; w < without.size(); ++w) {
    const int k = without[w];
    std::vector<cv::Point2f> from, to;
    tracks_of(static_cast<int>(w), ring_begin, points, moved, good, &from, &to);
    InstanceMove& m = rep.moves[k];
    const cv::Point2f centre(pixels[k].x + 0.5f * pixels[k].width,
                             pixels[k].y + 0.5f * pixels[k].height);
    m.centre_from = m.centre_to = centre;
    if (static_cast<int>(from.size()) >= options.min_points) {
      const InstanceMove ring = Fit(from, to, false, options);
      m.centre_to = centre + (ring.centre_to - ring.centre_from);
      m.tracks = ring.tracks;
      m.source = InstanceMoveSource::kSurroundings;
      ++rep.surroundings;
    } else {
      ++rep.unmoved;
    }
  }

  Segmentation out;
  out.backend = seg.backend;
  out.source_grey = grey;
  out.instance_map = cv::Mat(size, CV_16U, cv::Scalar(0));
  if (!seg.dynamic_confidence.empty()) {
    // Confidence that belongs to no instance (a segmenter without instances) stays where it was.
    out.dynamic_confidence = seg.dynamic_confidence * options.confidence_decay;
    for (int k = 0; k < n; ++k) {
      if (pixels[k].empty()) continue;
      const int g = options.confidence_margin_px;
      out.dynamic_confidence((pixels[k] + cv::Size(2 * g, 2 * g) - cv::Point(g, g)) & image_rect)
          .setTo(0);
    }
  }
  out.instances.reserve(n);
  // Lowest confidence first, so that where moved instances overlap the more confident one wins
  // (as in BuildInstanceMap).
  for (int k = n - 1; k >= 0; --k) {
    const InstanceMove& m = rep.moves[k];
    const float inv = 1.0f / m.scale;
    const auto source_of = [&](int u, int v) {
      const cv::Point2f p =
          m.centre_from +
          inv * (cv::Point2f(static_cast<float>(u), static_cast<float>(v)) - m.centre_to);
      return cv::Point(cvRound(p.x), cvRound(p.y));
    };
    const uint16_t id = static_cast<uint16_t>(k + 1);
    const cv::Rect dst = MovedPixels(pixels[k], m, size);
    for (int v = dst.y; v < dst.br().y; ++v) {
      uint16_t* row = out.instance_map.ptr<uint16_t>(v);
      for (int u = dst.x; u < dst.br().x; ++u) {
        const cv::Point s = source_of(u, v);
        if (pixels[k].contains(s) && instance_map.at<uint16_t>(s) == id) row[u] = id;
      }
    }
    if (!out.dynamic_confidence.empty() && !pixels[k].empty()) {
      const int g = options.confidence_margin_px;
      const cv::Rect src = (pixels[k] + cv::Size(2 * g, 2 * g) - cv::Point(g, g)) & image_rect;
      const cv::Rect dst_conf = MovedPixels(src, m, size);
      for (int v = dst_conf.y; v < dst_conf.br().y; ++v) {
        float* row = out.dynamic_confidence.ptr<float>(v);
        for (int u = dst_conf.x; u < dst_conf.br().x; ++u) {
          const cv::Point s = source_of(u, v);
          if (!src.contains(s)) continue;
          const float c = options.confidence_decay * seg.dynamic_confidence.at<float>(s);
          if (c > row[u]) row[u] = c;
        }
      }
    }
  }
  for (int k = 0; k < n; ++k) {
    Instance inst = seg.instances[k];
    inst.mask.release();
    inst.box_px = pixels[k].empty() ? cv::Rect2f() : MoveBox(inst.box_px, rep.moves[k], size);
    out.instances.push_back(std::move(inst));
  }
  return out;
}

}  // namespace pcr
