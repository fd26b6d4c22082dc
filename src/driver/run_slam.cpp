#include "driver/run_slam.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "driver/map_outputs.h"
#include "eval/plot.h"
#include "eval/report.h"
#include "io/dataset.h"
#include "io/text_parse.h"
#include "io/trajectory_io.h"
#include "slam/common/error.h"
#include "slam/common/log.h"

namespace pcr::driver {
namespace {

// Whether a file can be made in dir: a probe file is created and removed again (access() says
// yes to root for any directory, /proc's included, where nothing can be created). Returns why
// not, or "" when it can.
std::string WhyNotWritable(const std::filesystem::path& dir) {
  std::string probe = (dir / ".pcr-orb-probe-XXXXXX").string();
  const int fd = mkstemp(probe.data());
  if (fd < 0) return std::strerror(errno);
  close(fd);
  unlink(probe.c_str());
  return "";
}

// Whether path is folder or lies under it, compared part by part as given (callers normalise).
bool IsAtOrUnder(std::filesystem::path path, const std::filesystem::path& folder) {
  for (;; path = path.parent_path()) {
    if (path == folder) return true;
    if (path.empty() || path == path.parent_path()) return false;
  }
}

nlohmann::json TimingJson(const TimingSummary& s) {
  return {{"count", s.count},   {"mean_ms", s.mean_ms}, {"p50_ms", s.p50_ms},
          {"p95_ms", s.p95_ms}, {"p99_ms", s.p99_ms},   {"max_ms", s.max_ms}};
}

}  // namespace

void WarnIfCameraOverrideDiffers(const Dataset& dataset, const CameraOverride& camera) {
  if (!camera.Active()) return;
  const StereoRig& rig = dataset.rig;
  auto differs = [](double a, double b) { return std::abs(a - b) > 0.01 * std::abs(b); };
  if (differs(camera.fx, rig.left.fx) || differs(camera.cx, rig.left.cx) ||
      (camera.baseline_m > 0 && differs(camera.baseline_m, rig.baseline_m)))
    Logger().warn("camera override differs from the dataset calibration by more than 1%");
}

StereoRig EffectiveRig(const Dataset& dataset, const CameraOverride& camera) {
  StereoRig rig = dataset.rig;
  if (!camera.Active()) return rig;
  rig.left.fx = camera.fx;
  rig.left.fy = camera.fy;
  rig.left.cx = camera.cx;
  rig.left.cy = camera.cy;
  if (camera.baseline_m > 0) rig.baseline_m = camera.baseline_m;
  return rig;
}

FrameRange FrameRange::ParseText(const std::string& text) {
  FrameRange r{0, 0};
  if (text.empty()) return r;
  const auto colon = text.find(':');
  if (colon == std::string::npos) throw ConfigError("--frames '" + text + "' is not A:B");
  // A whole frame number or nothing: no sign, no space, no fraction, no exponent, no suffix
  // (std::stoul took "1e3" as 1, "2.9" as 2 and "-1" as a huge number).
  // Frame numbers go up to INT64_MAX (api::Source holds them as int64_t).
  constexpr size_t kMaxFrame = static_cast<size_t>(std::numeric_limits<int64_t>::max());
  auto number = [&text](const std::string& part, size_t* value) {
    if (part.empty()) return;
    const char* end = part.data() + part.size();
    const auto [ptr, ec] = std::from_chars(part.data(), end, *value);
    if ((ec != std::errc() && ec != std::errc::result_out_of_range) || ptr != end)
      throw ConfigError("--frames '" + text + "': '" + part +
                        "' is not a frame number (A and B must be whole numbers >= 0)");
    if (ec == std::errc::result_out_of_range || *value > kMaxFrame)
      throw ConfigError("--frames '" + text + "': '" + part +
                        "' is out of range (frame numbers go up to " + std::to_string(kMaxFrame) +
                        ")");
  };
  const std::string a = text.substr(0, colon), b = text.substr(colon + 1);
  number(a, &r.first);
  number(b, &r.end);
  if (!b.empty() && r.end == 0) throw ConfigError("--frames '" + text + "' selects no frame");
  return r;
}

FrameRange FrameRange::Within(size_t size, const std::string& what) const {
  FrameRange r = *this;
  if (r.end == 0 || r.end > size) r.end = size;
  if (r.first >= r.end) throw ConfigError(what + " selects no frame of " + std::to_string(size));
  return r;
}

FrameRange FrameRange::Parse(const std::string& text, size_t size) {
  return ParseText(text).Within(size, "--frames '" + text + "'");
}

void AddFrameToSummary(const FrameOutput& out, double preprocess_ms, double segment_ms, bool stereo,
                       RunSummary* s) {
  ++s->frames_in;
  switch (out.status) {
    case TrackingStatus::kOk:
      ++s->frames_tracked;
      break;
    case TrackingStatus::kLost:
      ++s->frames_lost;
      break;
    case TrackingStatus::kNotInitialized:
      ++s->frames_not_initialized;
      s->not_initialized_frame_indices.push_back(out.frame_index);
      break;
  }
  s->stages["preprocess"].Add(preprocess_ms);
  if (segment_ms > 0) s->stages["segment"].Add(segment_ms);
  s->stages["orb_left"].Add(out.times_ms.orb_left);
  if (stereo) {
    s->stages["orb_right"].Add(out.times_ms.orb_right);
    s->stages["stereo"].Add(out.times_ms.stereo);
  }
  if (out.times_ms.filter > 0) s->stages["filter"].Add(out.times_ms.filter);
  s->stages["tracking"].Add(out.times_ms.tracking);
  // The initialisation's keyframe is made by tracking (keyframe_inserted, no mapping call).
  const bool keyframe_mapped =
      out.keyframe_inserted && out.method != TrackingMethod::kInitialisation;
  if (keyframe_mapped || out.loop_outcomes_applied > 0)
    s->stages["local_mapping"].Add(out.times_ms.local_mapping);
  // Where a keyframe's mapping time goes (out.mapping: valid for the keyframes mapping made).
  if (keyframe_mapped) {
    const MappingResult& m = out.mapping;
    s->stages["local_mapping_stereo_points"].Add(m.stereo_ms);
    s->stages["local_mapping_point_culling"].Add(m.culling_ms);
    s->stages["local_mapping_triangulation"].Add(m.triangulation_ms);
    s->stages["local_mapping_fusion"].Add(m.fusion_ms);
    s->stages["local_mapping_ba"].Add(m.ba_ms);
    s->stages["local_mapping_keyframe_culling"].Add(m.keyframe_culling_ms);
    if (m.ba_keyframes > 0)
      s->local_ba.push_back({m.ba_keyframes, m.ba_fixed_keyframes, m.ba_points});
  }
  s->stages["total"].Add(out.times_ms.total + preprocess_ms + segment_ms);
  s->keyframes = out.num_keyframes;
  s->map_points = out.num_map_points;
  s->keypoints += out.num_keypoints;
  s->keypoints_excluded += out.num_excluded;
}

void CompleteSummary(const Dataset& dataset, int64_t first, int64_t end, bool monocular,
                     RunSummary* s) {
  std::map<int64_t, SE3> refined;
  for (const StampedPose& p : s->tracked) refined[p.frame_index] = p.world_from_cam;
  // A frame not initialised when it ran that has a pose now (the monocular initialisation's
  // reference frame): tracked, as trajectory_tum.txt and the evaluation have it.
  const size_t promoted = std::erase_if(s->not_initialized_frame_indices,
                                        [&refined](int64_t i) { return refined.count(i) > 0; });
  s->frames_not_initialized -= promoted;
  s->frames_tracked += promoted;
  SE3 last = SE3::Identity();
  Trajectory gt;
  for (int64_t i = first; i < end; ++i) {
    StampedPose p;
    p.frame_index = i;
    p.t_ns = dataset.t_ns[static_cast<size_t>(i)];
    const auto it = refined.find(i);
    s->frame_tracked.push_back(it != refined.end());
    if (it != refined.end()) last = it->second;
    p.world_from_cam = last;
    s->per_frame.push_back(p);
    if (dataset.ground_truth) gt.push_back((*dataset.ground_truth)[static_cast<size_t>(i)]);
  }
  s->ground_truth = gt;
  if (!dataset.ground_truth || s->tracked.size() < 3) return;
  s->eval_options.alignment.mode = monocular ? eval::AlignMode::kSim3 : eval::AlignMode::kSe3;
  s->eval_options.kitti.lengths_m = {5, 10, 20, 40, 80, 100, 200, 400, 800};
  // Frames the realtime policy dropped leave gaps: RPE over 1 frame pairs neighbouring frames.
  s->eval_options.rpe.by_frame_index = true;
  try {
    s->evaluation = eval::Evaluate(eval::AssociateByFrameIndex(gt, s->tracked), s->eval_options);
  } catch (const std::exception& e) {
    Logger().warn("evaluation skipped: {}", e.what());
  }
}

void CreateOutputDirectory(const std::string& out_dir) {
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) throw InputError(out_dir, 0, "cannot create output directory: " + ec.message());
}

void CheckOutputDirectory(const std::string& out_dir, const std::string& what) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::path p = fs::absolute(out_dir, ec).lexically_normal();
  if (ec) p = out_dir;
  // The nearest part of the path that exists: the directory itself, or where it would be made.
  while (!fs::exists(p, ec)) {
    const fs::path parent = p.parent_path();
    if (parent.empty() || parent == p) break;
    p = parent;
  }
  const std::string cannot = what + ": cannot create the output directory: ";
  if (!fs::is_directory(p, ec))
    throw InputError(out_dir, 0, cannot + p.string() + " is not a directory");
  if (const std::string why = WhyNotWritable(p); !why.empty())
    throw InputError(out_dir, 0, cannot + p.string() + " is not writable (" + why + ")");
}

void CheckOutputsOutsideImages(const Dataset& dataset, const std::string& out_dir,
                               const std::string& save_map, const OptionNames& names) {
  namespace fs = std::filesystem;
  auto resolved = [](const fs::path& p) {
    std::error_code ec;
    fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec);
    return ec ? fs::path(NormalDirectoryPath(p.string())) : r.lexically_normal();
  };
  std::vector<fs::path> folders;
  for (const std::vector<std::string>* paths :
       {&dataset.left_paths, &dataset.right_paths, &dataset.left_color_paths}) {
    if (!paths->empty()) folders.push_back(resolved(fs::path(paths->front()).parent_path()));
  }
  auto check = [&](const std::string& path, const fs::path& dir, const std::string& what) {
    for (const fs::path& folder : folders)
      if (IsAtOrUnder(dir, folder))
        throw InputError(path, 0,
                         what + ": lies in the dataset's image folder " + folder.string() +
                             "; choose a place outside the dataset's image folders");
  };
  if (!out_dir.empty()) check(out_dir, resolved(out_dir), Named(names, "--out"));
  if (!save_map.empty()) {
    const fs::path parent = fs::path(save_map).parent_path();
    check(save_map, resolved(parent.empty() ? fs::path(".") : parent), Named(names, "--save-map"));
  }
}

const std::vector<std::string>& RunOutputNames() {
  static const std::vector<std::string> names = {
      "trajectory.txt",       "trajectory_tum.txt", "ground_truth.txt", "config.yaml", "stats.json",
      "filter_decisions.txt", "evaluation.json",    "trajectory.png",   "trace.json",  "map.ply",
      "map_removed.ply",      "keyframes.txt",      "map.png",          "timing.png"};
  return names;
}

std::vector<std::string> RunOutputsIn(const std::string& out_dir) {
  namespace fs = std::filesystem;
  std::vector<std::string> present;
  for (const std::string& name : RunOutputNames()) {
    std::error_code ec;
    const fs::file_status st = fs::symlink_status(out_dir + "/" + name, ec);
    if (fs::is_regular_file(st) || fs::is_symlink(st)) present.push_back(name);
  }
  return present;
}

std::vector<std::string> RemoveRunOutputs(const std::string& out_dir) {
  const std::vector<std::string> present = RunOutputsIn(out_dir);
  for (const std::string& name : present) {
    std::error_code ec;
    std::filesystem::remove(out_dir + "/" + name, ec);
    if (ec)
      throw InputError(out_dir + "/" + name, 0,
                       "cannot remove the earlier run's file: " + ec.message());
  }
  return present;
}

namespace {

// Whether directories a and b are the same: the same path once absolute and normal, or, where
// both exist, the same directory (through a symbolic link).
bool SameDirectory(const std::string& a, const std::string& b) {
  if (NormalDirectoryPath(a) == NormalDirectoryPath(b)) return true;
  std::error_code ec;
  return std::filesystem::equivalent(a, b, ec) && !ec;
}

}  // namespace

void CheckOutputFile(const std::string& path, const std::string& what,
                     const std::string& made_before, std::string_view replaces_only) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_directory(p, ec) || p.filename().empty())
    throw InputError(path, 0, what + ": is a directory, not a file");
  if (!replaces_only.empty() && fs::exists(p, ec)) {
    std::ifstream in(p, std::ios::binary);
    std::string head(replaces_only.size(), '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    if (!in || head != replaces_only)
      throw InputError(path, 0,
                       fmt::format("{}: the file exists and is not one this option writes (it does "
                                   "not begin with {}): not replaced; remove it or choose another "
                                   "name",
                                   what, replaces_only));
  }
  // made_before or a directory above it: a directory once the run has made made_before.
  if (!made_before.empty()) {
    if (IsAtOrUnder(NormalDirectoryPath(made_before), NormalDirectoryPath(path)))
      throw InputError(path, 0,
                       what + ": is a directory, not a file (the output directory " + made_before +
                           " is made there)");
  }
  const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  if (!made_before.empty() && SameDirectory(dir.string(), made_before)) {
    const std::vector<std::string>& names = RunOutputNames();
    if (std::find(names.begin(), names.end(), p.filename().string()) != names.end())
      throw InputError(path, 0,
                       what + ": is the run's own " + p.filename().string() + " in " + made_before +
                           " (out_dir, --out); choose another name");
    return;
  }
  if (!fs::exists(dir, ec))
    throw InputError(path, 0, what + ": the directory " + dir.string() + " does not exist");
  if (!fs::is_directory(dir, ec))
    throw InputError(path, 0, what + ": " + dir.string() + " is not a directory");
  if (const std::string why = WhyNotWritable(dir); !why.empty())
    throw InputError(path, 0,
                     what + ": the directory " + dir.string() + " is not writable (" + why + ")");
}

void OutputErrors::Try(const std::function<void()>& write) {
  try {
    write();
  } catch (const std::exception& e) {
    if (!first_) {
      first_ = std::current_exception();
    } else {
      Logger().error("{}", e.what());  // the first is thrown by Rethrow
    }
  }
}

void OutputErrors::Rethrow() const {
  if (first_) std::rethrow_exception(first_);
}

void WriteRunOutputs(const std::string& out_dir, const RunSummary& s,
                     const std::string& config_yaml, const nlohmann::json& extra) {
  CreateOutputDirectory(out_dir);
  // The trajectories, the configuration and stats.json first; each file is tried even when an
  // earlier one failed.
  OutputErrors errors;
  errors.Try([&] { WriteKittiTrajectory(out_dir + "/trajectory.txt", s.per_frame); });
  errors.Try([&] { WriteTumTrajectory(out_dir + "/trajectory_tum.txt", s.tracked); });
  // Beside trajectory.txt, line for line: `evo_ape kitti ground_truth.txt trajectory.txt -a`.
  if (!s.ground_truth.empty())
    errors.Try([&] { WriteKittiTrajectory(out_dir + "/ground_truth.txt", s.ground_truth); });
  errors.Try([&] {
    io::WriteFileAtomically(out_dir + "/config.yaml",
                            [&](std::ostream& out) { out << config_yaml; });
  });
  nlohmann::json j;
  j["dataset"] = s.dataset_name;
  if (!s.ground_truth_source.empty()) j["ground_truth_source"] = s.ground_truth_source;
  j["mode"] = ToString(s.mode);
  j["frames"] = {{"first", s.range.first}, {"end", s.range.end},
                 {"in", s.frames_in},      {"tracked", s.frames_tracked},
                 {"lost", s.frames_lost},  {"not_initialized", s.frames_not_initialized}};
  j["keyframes"] = s.keyframes;
  j["map_points"] = s.map_points;
  j["wall_s"] = s.wall_s;
  j["fps"] = s.wall_s > 0 ? static_cast<double>(s.frames_in) / s.wall_s : 0.0;
  for (const auto& [name, series] : s.stages) j["stages"][name] = TimingJson(series.Summarize());
  if (!s.local_ba.empty()) {
    auto size = [&s](int RunSummary::LocalBaSize::*field) {
      double sum = 0;
      int max = 0;
      for (const RunSummary::LocalBaSize& b : s.local_ba) {
        sum += b.*field;
        max = std::max(max, b.*field);
      }
      return nlohmann::json{{"mean", sum / static_cast<double>(s.local_ba.size())}, {"max", max}};
    };
    j["local_ba"] = {{"count", s.local_ba.size()},
                     {"keyframes", size(&RunSummary::LocalBaSize::keyframes)},
                     {"fixed_keyframes", size(&RunSummary::LocalBaSize::fixed_keyframes)},
                     {"points", size(&RunSummary::LocalBaSize::points)}};
  }
  if (!s.error.empty()) j["error"] = s.error;
  if (s.interrupted) j["interrupted"] = true;
  j["keypoints"] = {{"total", s.keypoints}, {"excluded", s.keypoints_excluded}};
  if (s.filtered) {
    j["filter"]["reasons"] = s.filter_reasons;
    if (s.filter_confusion) j["filter"]["confusion"] = eval::ToJson(*s.filter_confusion);
    for (const auto& [mask, confusion] : s.filter_confusion_by_mask)
      j["filter"]["confusion_by_mask"][mask] = eval::ToJson(confusion);
    if (s.parked_points > 0)
      j["filter"]["parked_points"] = {{"total", s.parked_points}, {"kept", s.parked_points_kept}};
  }
  if (s.evaluation) {
    const eval::EvalResult& e = *s.evaluation;
    j["ate_m"] = {{"rmse", e.ape.trans_m.rmse},
                  {"mean", e.ape.trans_m.mean},
                  {"median", e.ape.trans_m.median},
                  {"max", e.ape.trans_m.max},
                  {"matched", e.matched}};
    j["rpe_m"] = {{"rmse", e.rpe.trans_m.rmse}, {"max", e.rpe.trans_m.max}};
  }
  if (extra.is_object())
    for (const auto& [key, value] : extra.items()) j[key] = value;
  errors.Try([&] {
    io::WriteFileAtomically(out_dir + "/stats.json",
                            [&](std::ostream& out) { out << j.dump(2) << "\n"; });
  });
  if (!s.filter_dump.empty()) {
    errors.Try([&] {
      io::WriteFileAtomically(out_dir + "/filter_decisions.txt", [&](std::ostream& out) {
        out << "# frame keypoint x_px y_px excluded reason score "
               "truth(moving:ID|parked:ID|static|-) "
               "s_mask has_motion m_motion observability residual_px instance mask_depth_outlier "
               "frame_static_prob chi2 depth_m ground\n";
        for (const std::string& line : s.filter_dump) out << line << "\n";
      });
    });
  }
  if (s.evaluation) {
    const eval::EvalResult& e = *s.evaluation;
    errors.Try([&] {
      io::WriteFileAtomically(out_dir + "/evaluation.json", [&](std::ostream& out) {
        out << eval::ToJson(e, s.eval_options).dump(2) << "\n";
      });
    });
    errors.Try([&] {
      eval::PlotOptions plot;
      plot.title = "PCR-ORB " + s.dataset_name + " (top view, " +
                   (s.eval_options.alignment.mode == eval::AlignMode::kSim3 ? "Sim(3)" : "SE(3)") +
                   "-aligned)";
      std::vector<eval::PlotSeries> series =
          eval::GroundTruthAndEstimate(e.reference, e.aligned_estimate);
      eval::PlotSeries loops{"loop closed", {}, kLoopColour, 2.0, eval::PlotStyle::kRings};
      for (const StampedPose& p : e.aligned_estimate)
        if (std::find(s.loops_closed_t_ns.begin(), s.loops_closed_t_ns.end(), p.t_ns) !=
            s.loops_closed_t_ns.end())
          loops.trajectory.push_back(p);
      if (!loops.trajectory.empty()) series.push_back(std::move(loops));
      eval::WriteTrajectoryPlot(out_dir + "/trajectory.png", series, plot);
    });
  }
  errors.Rethrow();
}

std::string FormatRunSummary(const RunSummary& s) {
  std::ostringstream o;
  o << "frames: " << s.frames_in << " in, " << s.frames_tracked << " tracked, " << s.frames_lost
    << " lost, " << s.frames_not_initialized << " not initialised; " << s.keyframes
    << " keyframes, " << s.map_points << " map points; "
    << fmt::format("{:.1f} s ({:.1f} fps)\n", s.wall_s,
                   s.wall_s > 0 ? static_cast<double>(s.frames_in) / s.wall_s : 0.0);
  // Per frame that ran (a frame the realtime policy dropped has none; segment: the result the
  // frame used); the pipeline's table below counts every call of its nodes.
  o << "per frame run:\n";
  size_t width = 14;
  for (const auto& [name, series] : s.stages) width = std::max(width, name.size());
  o << fmt::format("{:<{}} {:>6} {:>9} {:>9} {:>9} {:>9}\n", "stage", width, "frames", "mean ms",
                   "p50 ms", "p95 ms", "p99 ms");
  for (const auto& [name, series] : s.stages) {
    const TimingSummary t = series.Summarize();
    o << fmt::format("{:<{}} {:>6} {:>9.2f} {:>9.2f} {:>9.2f} {:>9.2f}\n", name, width, t.count,
                     t.mean_ms, t.p50_ms, t.p95_ms, t.p99_ms);
  }
  if (s.filtered) {
    o << "dynamic filter decisions:";
    for (const auto& [reason, n] : s.filter_reasons) o << " " << reason << " " << n;
    o << "\n";
    const size_t excluded = ExcludedKeypoints(s);
    if (RemovedPointsUnplaced(s))
      o << fmt::format(
          "removed points placed: none; a monocular run has no depth to place its {} excluded "
          "keypoints by\n",
          excluded);
    else
      o << fmt::format(
          "removed points placed: {} of the {} excluded keypoints (those with stereo depth in "
          "tracked frames)\n",
          s.removed_points.size(), excluded);
    if (s.filter_confusion)
      o << eval::FormatConfusionMatrix(
          *s.filter_confusion,
          "moving-object keypoints, " + s.filter_truth +
              " (predicted dynamic: excluded as moving or by a mask; the sky, border, ground "
              "and low-score exclusions count as kept)");
    if (s.parked_points > 0)
      o << fmt::format(
          "parked-object keypoints kept (not excluded for any reason): {} of {} ({:.1f}%)\n",
          s.parked_points_kept, s.parked_points, 100.0 * s.parked_points_kept / s.parked_points);
  } else if (s.keypoints_excluded > 0) {
    o << fmt::format(
        "segmentation masks (filter off) excluded {} of {} keypoints ({:.1f}%) from tracking and "
        "the map; removed points placed: none (map_removed.ply places the filter's decisions "
        "only)\n",
        s.keypoints_excluded, s.keypoints,
        100.0 * s.keypoints_excluded / std::max<int64_t>(1, s.keypoints));
  }
  if (s.evaluation) o << eval::FormatReport(*s.evaluation, s.eval_options);
  if (!s.error.empty())
    o << (s.interrupted ? "run interrupted: " : "run stopped early: ") << s.error << "\n";
  return o.str();
}

}  // namespace pcr::driver
