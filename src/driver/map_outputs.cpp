#include "driver/map_outputs.h"

#include <algorithm>
#include <bit>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "eval/association.h"
#include "graph/pipeline_report.h"
#include "io/text_parse.h"
#include "io/trajectory_io.h"
#include "slam/common/error.h"
#include "slam/common/log.h"
#include "slam/geometry/ground_height.h"

namespace pcr::driver {
namespace {

static_assert(std::endian::native == std::endian::little,
              "PLY bodies are written as little-endian");

// One vertex record: x y z (float), red green blue (uchar), then the extra property.
template <typename Extra>
void PutVertex(std::string* body, const Eigen::Vector3d& p, uint8_t grey, Extra extra) {
  const float xyz[3] = {static_cast<float>(p.x()), static_cast<float>(p.y()),
                        static_cast<float>(p.z())};
  body->append(reinterpret_cast<const char*>(xyz), sizeof(xyz));
  const uint8_t rgb[3] = {grey, grey, grey};
  body->append(reinterpret_cast<const char*>(rgb), sizeof(rgb));
  body->append(reinterpret_cast<const char*>(&extra), sizeof(extra));
}

// The unit of the map's coordinates.
const char* MapUnits(SlamMode mode) {
  return mode == SlamMode::kStereo ? "m" : "map units (monocular: arbitrary scale)";
}

// "keyframes A-B" (both included), "keyframe A".
std::string KeyframeRange(size_t first, size_t end) {
  return end - first == 1 ? fmt::format("keyframe {}", first)
                          : fmt::format("keyframes {}-{}", first, end - 1);
}

// Coordinates in the camera frame of the map's first keyframe; metres in stereo, the map's
// arbitrary units in monocular runs.
void WritePly(const std::string& path, SlamMode mode, size_t count, const std::string& comments,
              const std::string& extra_property, const std::string& body) {
  std::ofstream out(path, std::ios::binary);
  out << "ply\nformat binary_little_endian 1.0\n"
      << "comment PCR-ORB map, world frame = the camera of the map's first keyframe (x right, "
         "y down, z forward), "
      << MapUnits(mode) << "\n"
      << comments << "element vertex " << count << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << extra_property << "\nend_header\n";
  out.write(body.data(), static_cast<std::streamsize>(body.size()));
  if (!out) throw InputError(path, 0, "cannot write");
}

// Top view (x right, z up the picture) of kept points, removed points, keyframes and loops.
void WriteMapPicture(const std::string& path, const graph::MapSnapshot& map,
                     const RunSummary& summary) {
  std::vector<double> xs, zs;
  for (const graph::MapCloudPoint& p : map.points) {
    xs.push_back(p.p_in_world.x());
    zs.push_back(p.p_in_world.z());
  }
  for (const StampedPose& k : map.keyframes) {
    xs.push_back(k.world_from_cam.translation().x());
    zs.push_back(k.world_from_cam.translation().z());
  }
  if (xs.empty()) xs = zs = {0.0};
  // The 1st-99th percentiles, so that a few far points do not shrink the picture.
  auto range = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t lo = v.size() / 100, hi = v.size() - 1 - v.size() / 100;
    return std::pair<double, double>(v[lo] - 5, v[hi] + 5);
  };
  const auto [x0, x1] = range(xs);
  const auto [z0, z1] = range(zs);
  const int size = 1000;
  const double scale = (size - 40) / std::max(x1 - x0, z1 - z0);
  cv::Mat canvas(size, size, CV_8UC3, cv::Scalar(255, 255, 255));
  auto pixel = [&](double x, double z) {
    return cv::Point(20 + static_cast<int>((x - x0) * scale),
                     size - 20 - static_cast<int>((z - z0) * scale));
  };
  auto inside = [&](const cv::Point& q) {
    return q.x >= 0 && q.y >= 0 && q.x < size && q.y < size;
  };
  for (const graph::MapCloudPoint& p : map.points) {
    const cv::Point q = pixel(p.p_in_world.x(), p.p_in_world.z());
    if (inside(q)) canvas.at<cv::Vec3b>(q) = cv::Vec3b(110, 110, 110);
  }
  for (const RunSummary::RemovedPoint& p : summary.removed_points) {
    const cv::Point q = pixel(p.p_in_world.x(), p.p_in_world.z());
    if (inside(q)) cv::circle(canvas, q, 1, cv::Scalar(0, 0, 230), cv::FILLED);
  }
  // The loaded map's keyframes and this run's are two paths: no line from the one to the other.
  const size_t loaded = LoadedKeyframes(map);
  for (size_t i = 1; i < map.keyframes.size(); ++i) {
    if (i == loaded) continue;
    const auto& a = map.keyframes[i - 1].world_from_cam.translation();
    const auto& b = map.keyframes[i].world_from_cam.translation();
    cv::line(canvas, pixel(a.x(), a.z()), pixel(b.x(), b.z()), cv::Scalar(200, 80, 0), 2);
  }
  // Loops on top: a line between the two keyframes and a ring on the query's.
  const cv::Scalar loop_bgr(kLoopColour.b, kLoopColour.g, kLoopColour.r);
  for (const auto& [query, match] : map.loops) {
    const auto& a = map.keyframes.at(query).world_from_cam.translation();
    const auto& b = map.keyframes.at(match).world_from_cam.translation();
    cv::line(canvas, pixel(a.x(), a.z()), pixel(b.x(), b.z()), loop_bgr, 2);
    cv::circle(canvas, pixel(a.x(), a.z()), 7, loop_bgr, 2);
  }
  cv::putText(canvas, MapPictureTitle(map, summary), cv::Point(10, 15), cv::FONT_HERSHEY_SIMPLEX,
              0.4, cv::Scalar(0, 0, 0), 1);
  if (!cv::imwrite(path, canvas)) throw InputError(path, 0, "cannot write");
}

}  // namespace

const char* RemovedPointsUnplacedWhy(const RunSummary& summary) {
  if (summary.filtered) return summary.mode != SlamMode::kStereo ? kRemovedPointsUnplaced : nullptr;
  return summary.keypoints_excluded > 0 ? kMaskExclusionsUnplaced : nullptr;
}

bool RemovedPointsUnplaced(const RunSummary& summary) {
  return RemovedPointsUnplacedWhy(summary) != nullptr;
}

size_t ExcludedKeypoints(const RunSummary& summary) {
  if (!summary.filtered) return static_cast<size_t>(summary.keypoints_excluded);
  size_t excluded = 0;
  for (const auto& [reason, count] : summary.filter_reasons)
    if (reason != FilterReasonName(FilterReason::kKept)) excluded += static_cast<size_t>(count);
  return excluded;
}

std::string MapPictureTitle(const graph::MapSnapshot& map, const RunSummary& summary) {
  const std::string removed =
      !RemovedPointsUnplaced(summary)
          ? std::to_string(summary.removed_points.size()) + " removed by the filter (red)"
      : summary.filtered ? std::to_string(ExcludedKeypoints(summary)) +
                               " excluded by the filter (mono: no depth, not drawn)"
                         : std::to_string(ExcludedKeypoints(summary)) +
                               " excluded by the masks (filter off: not drawn)";
  return std::to_string(map.points.size()) + " map points (grey), " + removed +
         ", keyframes (blue), loops closed (green): " + std::to_string(map.loops.size()) +
         "; top view, x right, z up";
}

MapGroundScale RoadScale(const graph::MapSnapshot& map) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(map.points.size());
  for (const graph::MapCloudPoint& p : map.points) points.push_back(p.p_in_world);
  std::vector<SE3> keyframes;
  keyframes.reserve(map.keyframes.size());
  for (const StampedPose& k : map.keyframes) keyframes.push_back(k.world_from_cam);
  return EstimateMapGroundScale(points, keyframes, kRoadCameraHeightM, GroundHeightOptions{});
}

nlohmann::json GroundScaleJson(const graph::MapSnapshot& map, const RunSummary& summary) {
  const std::optional<eval::EvalResult>& evaluation = summary.evaluation;
  const MapGroundScale s = RoadScale(map);
  const size_t keyframes = map.keyframes.size();
  nlohmann::json j = {{"camera_height_m", kRoadCameraHeightM},
                      {"keyframes", keyframes},
                      {"estimated", s.estimated}};
  if (s.estimated == 0) {
    Logger().info("no road found under the {} keyframes", keyframes);
    return j;
  }
  j["median_height"] = s.median_height;
  j["metres_per_unit"] = s.metres_per_unit;
  j["metres_per_unit_p10"] = s.p10;
  j["metres_per_unit_p90"] = s.p90;
  // The scale that aligns the trajectory to the ground truth: what the road's should be.
  if (evaluation) {
    j["truth_metres_per_unit"] = evaluation->alignment.scale;
    j["ratio_to_truth"] = s.metres_per_unit / evaluation->alignment.scale;
  }
  Logger().info(
      "the road under {} of {} keyframes: {:.4g} m per map unit (keyframes' p10-p90 "
      "{:.4g}-{:.4g}){}",
      s.estimated, keyframes, s.metres_per_unit, s.p10, s.p90,
      evaluation ? fmt::format("; the alignment to the ground truth: {:.4g} ({:.3f}x)",
                               evaluation->alignment.scale,
                               s.metres_per_unit / evaluation->alignment.scale)
                 : "");
  // A stereo map is in metres: a road that gives it another scale by more than a factor 2 is no
  // road (points by the camera, a wrong camera configuration), and says so.
  if (summary.mode == SlamMode::kStereo &&
      !(s.metres_per_unit >= 0.5 && s.metres_per_unit <= 2.0)) {
    j["plausible"] = false;
    Logger().warn(
        "the road found under {} keyframe{} is {:.4g} m below {} against the camera's {} m, on "
        "a stereo map in metres: it is not the road (points by the camera; is the camera "
        "configuration this sequence's?)",
        s.estimated, s.estimated > 1 ? "s" : "", s.median_height, s.estimated > 1 ? "them" : "it",
        kRoadCameraHeightM);
  }
  // A monocular run in the road's metres, aligned by rotation and translation only: its error
  // without the ground truth's scale (against the Sim(3) alignment's, which takes that scale).
  if (!evaluation || evaluation->align_mode != eval::AlignMode::kSim3) return j;
  Trajectory metric = summary.tracked;
  for (StampedPose& p : metric) p.world_from_cam.translation() *= s.metres_per_unit;
  eval::EvalOptions se3 = summary.eval_options;
  se3.alignment.mode = eval::AlignMode::kSe3;
  try {
    const double ate_m =
        eval::Evaluate(eval::AssociateByFrameIndex(summary.ground_truth, metric), se3)
            .ape.trans_m.rmse;
    j["ate_m_road_scale_se3"] = ate_m;
    Logger().info("ATE in the road's metres, SE(3)-aligned: {:.4f} m (Sim(3)-aligned: {:.4f} m)",
                  ate_m, evaluation->ape.trans_m.rmse);
  } catch (const std::exception& e) {
    Logger().warn("evaluation in the road's scale skipped: {}", e.what());
  }
  return j;
}

size_t LoadedKeyframes(const graph::MapSnapshot& map) {
  const auto first_made_here =
      std::find_if(map.keyframes.begin(), map.keyframes.end(),
                   [](const StampedPose& k) { return k.frame_index >= 0; });
  return static_cast<size_t>(first_made_here - map.keyframes.begin());
}

void WriteKeyframesFile(const std::string& path, const graph::MapSnapshot& map,
                        const RunSummary& summary) {
  const size_t count = map.keyframes.size();
  const size_t loaded = LoadedKeyframes(map);
  io::WriteFileAtomically(path, [&](std::ostream& out) {
    out << "# timestamp tx ty tz qx qy qz qw\n"
        << "# PCR-ORB keyframes: the map's keyframes when the run ended, one pose line each in "
           "the order they were made (stats.json's map.loops count these lines from 0), "
           "world_from_cam as the map held it then (after this run's bundle adjustments and "
           "loop corrections); world = the camera of the map's first keyframe, "
        << MapUnits(summary.mode) << "\n";
    if (loaded > 0)
      out << "# " << KeyframeRange(0, loaded) << ": " << loaded
          << " loaded with the map (--load-map), made by the runs that built it and stamped with "
             "their frames' times; not frames of this run: where this run has a frame of the "
             "same image (the same timestamp), trajectory.txt holds this run's own estimate of "
             "its pose, which differs from the map's by the two estimates' errors\n";
    for (size_t i = 0; i < count; ++i) {
      if (i == loaded)
        out << "# " << KeyframeRange(loaded, count) << ": " << count - loaded
            << " made in this run, each one of its frames at its pose in trajectory_tum.txt"
            << (loaded > 0 ? "; the timestamps start again here (this part is one trajectory, the "
                             "whole file is not)"
                           : "")
            << "\n";
      out << TumLine(map.keyframes[i]) << '\n';
    }
    if (loaded == count) out << "# no keyframe made in this run\n";
  });
}

nlohmann::json MapOutputsJson(const graph::MapSnapshot& map, const RunSummary& summary) {
  nlohmann::json by_reason = nlohmann::json::object(), by_truth = nlohmann::json::object();
  for (const RunSummary::RemovedPoint& p : summary.removed_points) {
    by_reason[FilterReasonName(p.reason)] = by_reason.value(FilterReasonName(p.reason), 0) + 1;
    if (p.truth != '-') {
      const char* kind = p.truth == 'm' ? "moving" : (p.truth == 'p' ? "parked" : "static");
      by_truth[kind] = by_truth.value(kind, 0) + 1;
    }
  }
  nlohmann::json summary_json = {{"points", map.points.size()}};
  if (RemovedPointsUnplaced(summary)) {
    summary_json["removed_points"] = nullptr;
    summary_json["removed_points_unplaced"] = RemovedPointsUnplacedWhy(summary);
  } else {
    summary_json["removed_points"] = summary.removed_points.size();
    summary_json["removed_by_reason"] = by_reason;
    summary_json["removed_by_truth"] = by_truth;
  }
  if (summary.filtered || summary.keypoints_excluded > 0)
    summary_json["excluded_keypoints"] = ExcludedKeypoints(summary);
  summary_json["keyframes"] = map.keyframes.size();
  summary_json["keyframes_loaded"] = LoadedKeyframes(map);
  summary_json["loops"] = map.loops;
  summary_json["parts"] = graph::MapPartsToJson(map);
  summary_json["ground"] = GroundScaleJson(map, summary);
  return summary_json;
}

void WriteMapFiles(const std::string& out_dir, const graph::MapSnapshot& map,
                   const RunSummary& summary) {
  CreateOutputDirectory(out_dir);
  OutputErrors errors;
  errors.Try([&] {
    std::string body;
    body.reserve(map.points.size() * 19);
    for (const graph::MapCloudPoint& p : map.points)
      PutVertex(&body, p.p_in_world, p.grey, static_cast<int32_t>(p.observations));
    WritePly(out_dir + "/map.ply", summary.mode, map.points.size(), "", "property int observations",
             body);
  });
  errors.Try([&] {
    std::string body, reasons;
    for (int r = 0; r < kNumFilterReasons; ++r)
      reasons += "comment reason " + std::to_string(r) + " = " +
                 FilterReasonName(static_cast<FilterReason>(r)) + "\n";
    if (RemovedPointsUnplaced(summary))
      reasons += fmt::format("comment {} excluded keypoints, none here: {}\n",
                             ExcludedKeypoints(summary), RemovedPointsUnplacedWhy(summary));
    for (const RunSummary::RemovedPoint& p : summary.removed_points)
      PutVertex(&body, p.p_in_world, p.grey, static_cast<uint8_t>(p.reason));
    WritePly(out_dir + "/map_removed.ply", summary.mode, summary.removed_points.size(), reasons,
             "property uchar reason", body);
  });
  errors.Try([&] { WriteKeyframesFile(out_dir + "/keyframes.txt", map, summary); });
  errors.Try([&] { WriteMapPicture(out_dir + "/map.png", map, summary); });
  errors.Rethrow();
}

nlohmann::json WriteMapOutputs(const std::string& out_dir, const graph::MapSnapshot& map,
                               const RunSummary& summary) {
  WriteMapFiles(out_dir, map, summary);
  return MapOutputsJson(map, summary);
}

}  // namespace pcr::driver
