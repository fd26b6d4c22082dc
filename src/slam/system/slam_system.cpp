#include "slam/system/slam_system.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/image.h"
#include "slam/common/log.h"
#include "slam/common/timing.h"
#include "slam/system/map_archive.h"

namespace pcr {
namespace {

constexpr size_t kMaxPendingFrames = 256;
// A run on a loaded map warns when this many frames from its start were not relocalised in it.
constexpr int64_t kLostInLoadedMapWarnFrames = 5;

StereoRig CheckedRig(const StereoRig& rig, SlamMode mode) {
  std::string why;
  if (!rig.IsValid(&why)) throw ConfigError("SlamSystem rig: " + why);
  if (mode == SlamMode::kStereo && !rig.IsStereo())
    throw ConfigError("SlamSystem in stereo mode needs a stereo rig (baseline_m > 0)");
  if (rig.left.width_px <= 0 || rig.left.height_px <= 0)
    throw ConfigError("SlamSystem rig: image size must be set");
  StereoRig checked = rig;
  if (mode == SlamMode::kMonocular) checked.baseline_m = 0;
  return checked;
}

const OrbOptions& CheckedOptions(const SlamOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("SlamOptions: " + why);
  return options.orb;
}

}  // namespace

const char* ToString(SlamMode mode) {
  switch (mode) {
    case SlamMode::kStereo:
      return "stereo";
    case SlamMode::kMonocular:
      return "mono";
  }
  return "?";
}

bool SlamOptions::IsValid(std::string* why) const {
  std::string inner;
  auto sub = [&](bool ok, const char* name) {
    if (!ok && why) *why = std::string(name) + ": " + inner;
    return ok;
  };
  return sub(orb.IsValid(&inner), "orb") && sub(stereo.IsValid(&inner), "stereo") &&
         sub(tracker.IsValid(&inner), "tracker") && sub(mapping.IsValid(&inner), "mapping") &&
         sub(keyframe.IsValid(&inner), "keyframe") && sub(loop.IsValid(&inner), "loop");
}

SlamSystem::SlamSystem(const StereoRig& rig, const SlamOptions& options, SlamMode mode,
                       std::shared_ptr<const Vocabulary> vocabulary)
    : mode_(mode),
      rig_(CheckedRig(rig, mode)),
      map_rig_(rig_),
      options_(options),
      extractor_(CheckedOptions(options)),
      tracker_(options.tracker),
      mapper_(options.mapping),
      loop_closer_(options.loop, std::move(vocabulary), mode == SlamMode::kStereo) {
  tracker_.SetLocalisationMode(options.localize_only);
  if (loop_closer_.IsActive()) map_.set_edit_log(loop_closer_.edit_log());
  scale_.scale_factors = extractor_.scale_factors();
  scale_.level_sigma2 = extractor_.level_sigma2();
  scale_.inv_level_sigma2 = extractor_.inv_level_sigma2();
  map_scale_ = scale_;
}

OrbFeatures SlamSystem::ExtractRight(const cv::Mat& right) const {
  if (mode_ == SlamMode::kMonocular) return {};
  return extractor_.Extract(right);
}

StereoMatches SlamSystem::MatchStereoFeatures(const OrbFeatures& left,
                                              const OrbFeatures& right) const {
  if (mode_ == SlamMode::kMonocular) return {};
  return MatchStereo(rig_, left, right, extractor_.scale_factors(), options_.stereo);
}

KeypointFilter SlamSystem::SampleFilter(const FrameFilterInput& filter,
                                        const std::vector<cv::KeyPoint>& keypoints) {
  KeypointFilter out;
  if (!filter.excluded_mask.empty()) {
    if (filter.excluded_mask.type() != CV_8UC1)
      throw std::invalid_argument("FrameFilterInput: excluded_mask must be CV_8UC1");
    out.excluded.reserve(keypoints.size());
    for (const cv::KeyPoint& kp : keypoints)
      out.excluded.push_back(
          filter.excluded_mask.at<uint8_t>(NearestPixel(filter.excluded_mask, kp.pt)) ? 1 : 0);
  }
  if (!filter.weight_map.empty()) {
    if (filter.weight_map.type() != CV_32FC1)
      throw std::invalid_argument("FrameFilterInput: weight_map must be CV_32FC1");
    out.weight.reserve(keypoints.size());
    for (const cv::KeyPoint& kp : keypoints) {
      const float w = filter.weight_map.at<float>(NearestPixel(filter.weight_map, kp.pt));
      out.weight.push_back(std::isfinite(w) ? std::clamp(w, 1e-3f, 1.0f) : 1.0f);
    }
  }
  return out;
}

FramePtr SlamSystem::BuildFrame(int64_t t_ns, const OrbFeatures& left, const StereoMatches& stereo,
                                const KeypointFilter& filter) {
  if (mode_ == SlamMode::kMonocular)
    return Frame::Create(next_frame_id_++, t_ns, rig_, scale_, left, StereoMatches{}, filter);
  return Frame::Create(next_frame_id_++, t_ns, rig_, scale_, left, stereo, filter);
}

TrackingResult SlamSystem::Track(const FramePtr& frame, int64_t frame_index) {
  if (options_.localize_only && map_.empty()) {
    TrackingResult none;  // nothing to localise in, and no map may be made
    none.frame_id = frame->id();
    none.points.assign(frame->size(), MapPointId());
    return none;
  }
  PlaceQuery place;
  if (loop_closer_.HasPlaceRecognition())
    place = [this](const Frame& f) {
      return loop_closer_.PlaceCandidates(f, map_, options_.tracker.relocalisation_keyframes);
    };
  TrackingResult result = tracker_.Track(frame, map_, place);
  if (loaded_map_keyframes_ > 0) NoteLoadedMapStart(result, frame_index);
  if (options_.localize_only) {
    RecordTracked(result, *frame, frame_index);
    result.map_delta = MapDelta{};  // the counters: the map stays as loaded
    return result;
  }
  const bool initialised = result.method == TrackingMethod::kInitialisation;
  if (result.first_keyframe_delta) {
    // Monocular: the reference frame becomes the first keyframe and a tracked frame.
    const NewKeyframe& first = *result.first_keyframe_delta->new_keyframe;
    map_.Apply(*result.first_keyframe_delta);
    for (const PendingFrame& p : pending_) {
      if (p.frame_id != first.frame->id()) continue;
      FrameRecord record;
      record.frame_index = p.frame_index;
      record.t_ns = p.t_ns;
      record.reference = KeyframeId(p.frame_id);
      records_.push_back(record);
    }
  }
  map_.Apply(result.map_delta);
  if (initialised) {
    if (result.reinitialised && !result.own_part_in_loaded_map)
      Logger().info(
          "frame {}: after {} lost frames a new part of the map starts here, from its stereo "
          "depth at the pose the last tracked frame's motion extrapolates to ({} points; it joins "
          "the rest of the map where a loop closes)",
          frame_index, result.frames_lost_before, result.map_delta.new_points.size());
    pending_.clear();
    const KeyframeId id(frame->id());
    // The frame is its own keyframe: recorded at the identity from it, so that it follows its
    // local BA (the monocular second keyframe moves in it), as InsertKeyframe records.
    RecordTracked(result, *frame, frame_index);
    records_.back().reference = id;
    records_.back().cam_from_reference = SE3::Identity();
    mapper_.ProcessKeyframe(id, &map_);
    tracker_.OnKeyframeInserted(id, map_);
    if (result.first_keyframe_delta)  // monocular: the initialisation's reference keyframe
      loop_closer_.OnKeyframe(KeyframeId(result.first_keyframe_delta->new_keyframe->frame->id()),
                              map_);
    loop_closer_.OnKeyframe(id, map_);
    return result;
  }
  if (map_.empty()) {
    if (pending_.size() >= kMaxPendingFrames) pending_.erase(pending_.begin());
    pending_.push_back({frame->id(), frame_index, frame->t_ns()});
  }
  RecordTracked(result, *frame, frame_index);
  return result;
}

void SlamSystem::NoteLoadedMapStart(const TrackingResult& result, int64_t frame_index) {
  if (result.own_part_in_loaded_map) {
    Logger().info(
        "frame {}: after {} frames not found in the loaded map ({} keyframes), this run starts a "
        "part of the map of its own here, from its stereo depth at the map's origin ({} points; "
        "it joins the loaded map where a loop closes)",
        frame_index, result.frames_lost_before, loaded_map_keyframes_,
        result.map_delta.new_points.size());
    loaded_map_keyframes_ = 0;
    return;
  }
  if (result.status == TrackingStatus::kOk) {
    if (frames_before_loaded_map_ >= kLostInLoadedMapWarnFrames)
      Logger().info("frame {} relocalised in the loaded map after {} frames that were not",
                    frame_index, frames_before_loaded_map_);
    loaded_map_keyframes_ = 0;  // started: nothing more to say
    return;
  }
  if (++frames_before_loaded_map_ != kLostInLoadedMapWarnFrames) return;
  const bool own_part = tracker_.StartsNewParts(mode_ == SlamMode::kStereo);
  Logger().warn(
      "the first {} frames of this run were not relocalised in the loaded map ({} keyframes{}): "
      "{}",
      frames_before_loaded_map_, loaded_map_keyframes_,
      loop_closer_.HasPlaceRecognition()
          ? ""
          : fmt::format(", tried against its {} newest only: no vocabulary",
                        options_.tracker.relocalisation_keyframes),
      own_part ? fmt::format("the run starts a part of the map of its own once {} frames in a row "
                             "with stereo depth are not found in it "
                             "(tracking.reinitialise_after_lost_frames)",
                             options_.tracker.reinitialise_after_lost_frames)
               : fmt::format("a run on a loaded map starts at the first frame found in it; until "
                             "then no frame is tracked{}",
                             options_.localize_only ? "" : " and nothing is added to the map"));
}

void SlamSystem::RecordTracked(const TrackingResult& result, const Frame& frame,
                               int64_t frame_index) {
  if (result.status != TrackingStatus::kOk) return;
  FrameRecord record;
  record.frame_index = frame_index;
  record.t_ns = frame.t_ns();
  record.reference = result.reference_keyframe;
  if (const auto ref_pose = map_.CamFromWorld(record.reference))
    record.cam_from_reference = result.cam_from_world * ref_pose->inverse();
  records_.push_back(record);
}

KeyframeDecision SlamSystem::DecideKeyframe(const TrackingResult& tracking,
                                            double min_interval_s) const {
  if (tracking.status != TrackingStatus::kOk ||
      tracking.method == TrackingMethod::kInitialisation) {
    KeyframeDecision d;
    d.reason =
        tracking.method == TrackingMethod::kInitialisation ? "initial keyframe" : "not tracking";
    return d;
  }
  if (options_.localize_only) {
    KeyframeDecision d;
    d.reason = "localize only";
    return d;
  }
  KeyframeDecisionOptions options = options_.keyframe;
  options.min_interval_s =
      std::max(options.min_interval_s, std::min(min_interval_s, options.max_interval_s));
  return ShouldInsertKeyframe(tracking.keyframe_input, options);
}

MappingResult SlamSystem::InsertKeyframe(const FramePtr& frame, const TrackingResult& tracking,
                                         int ba_max_iterations) {
  MapDelta delta;
  NewKeyframe kf;
  kf.frame = frame;
  kf.cam_from_world = tracking.cam_from_world;
  kf.parent_hint = tracking.reference_keyframe;
  for (int i = 0; i < static_cast<int>(tracking.points.size()); ++i)
    if (tracking.points[i].valid()) kf.associations.emplace_back(i, tracking.points[i]);
  delta.new_keyframe = std::move(kf);
  map_.Apply(delta);
  const KeyframeId id(frame->id());
  MappingResult result = mapper_.ProcessKeyframe(id, &map_, ba_max_iterations);
  tracker_.OnKeyframeInserted(id, map_);
  loop_closer_.OnKeyframe(id, map_);
  // The frame is now its own reference.
  if (!records_.empty() && records_.back().t_ns == frame->t_ns()) {
    records_.back().reference = id;
    records_.back().cam_from_reference = SE3::Identity();
  }
  return result;
}

MapArchive SlamSystem::ArchiveMap() const {
  MapArchive archive;
  archive.mode = mode_;
  archive.rig = map_rig_;
  archive.scale = map_scale_;
  archive.map = map_;
  archive.place = loop_closer_.Archive(map_);
  return archive;
}

void SlamSystem::RestoreMap(const MapArchive& archive) {
  if (!map_.empty() || next_frame_id_ != 0)
    throw ConfigError("SlamSystem::RestoreMap: a map is loaded before the first frame");
  if (archive.mode != mode_) {
    throw ConfigError(std::string("the map was made in ") + ToString(archive.mode) +
                      " mode, this run is " + ToString(mode_));
  }
  const PinholeCamera& a = archive.rig.left;
  const PinholeCamera& b = rig_.left;
  auto near = [](double x, double y) {
    return std::abs(x - y) <= 1e-6 * std::max(1.0, std::abs(y));
  };
  if (!near(a.fx, b.fx) || !near(a.fy, b.fy) || !near(a.cx, b.cx) || !near(a.cy, b.cy) ||
      a.width_px != b.width_px || a.height_px != b.height_px ||
      !near(archive.rig.baseline_m, rig_.baseline_m)) {
    throw ConfigError(fmt::format(
        "the map was made with another camera (fx {} fy {} cx {} cy {} {}x{} baseline {} m; this "
        "run: fx {} fy {} cx {} cy {} {}x{} baseline {} m)",
        a.fx, a.fy, a.cx, a.cy, a.width_px, a.height_px, archive.rig.baseline_m, b.fx, b.fy, b.cx,
        b.cy, b.width_px, b.height_px, rig_.baseline_m));
  }
  if (archive.scale.num_levels() != scale_.num_levels() ||
      !near(archive.scale.scale_factor(), scale_.scale_factor())) {
    throw ConfigError(fmt::format(
        "the map was made with another ORB pyramid ({} levels, factor {}; this run: {} levels, "
        "factor {})",
        archive.scale.num_levels(), archive.scale.scale_factor(), scale_.num_levels(),
        scale_.scale_factor()));
  }
  map_ = archive.map;
  // The map keeps the camera and pyramid it was made with (equal to this run's within the
  // tolerance above): saving it again writes them as they were.
  map_rig_ = archive.rig;
  map_scale_ = archive.scale;
  loaded_map_keyframes_ = map_.num_keyframes();
  frames_before_loaded_map_ = 0;
  loop_closer_.ResetEditLog();
  const int computed = loop_closer_.Restore(archive.place, map_);
  if (computed > 0)
    Logger().info("loaded map: {} keyframes' bags of words computed with this run's vocabulary",
                  computed);
  if (!loop_closer_.HasPlaceRecognition() && !map_.empty())
    Logger().warn(
        "loaded map without a vocabulary: a frame is relocalised only against the map's {} newest "
        "keyframes (tracking.relocalisation_keyframes) and their covisible ones, not in the whole "
        "map{}",
        options_.tracker.relocalisation_keyframes,
        archive.place ? " (its place-recognition database is kept for saving, not used)" : "");
  // Frame ids continue after every keyframe id the map has used.
  int64_t next = 0;
  for (const auto& [id, kf] : map_.keyframes()) next = std::max(next, id.value + 1);
  for (const auto& [id, erased] : map_.bookkeeping().erased_keyframes)
    next = std::max(next, id.value + 1);
  next_frame_id_ = next;
  tracker_.Reset();
}

std::shared_ptr<const LoopJob> SlamSystem::DetectLoop(KeyframeId id, bool busy) {
  return loop_closer_.Detect(id, map_, busy);
}

bool SlamSystem::ApplyLoopOutcome(const LoopOutcome& outcome, int64_t frame_index) {
  bool changed = false;
  if (outcome.kind != LoopOutcomeKind::kRejected && !outcome.ba_aborted &&
      !outcome.correction.after.empty()) {
    map_.Apply(LoopCloser::CorrectionDelta(map_, outcome.correction));
    changed = true;
    if (outcome.kind == LoopOutcomeKind::kGlobalBundleAdjustment)
      last_global_ba_newest_ = outcome.correction.after.rbegin()->first;
  }
  loop_closer_.OnOutcome(outcome, map_);
  if (outcome.kind == LoopOutcomeKind::kCorrected && outcome.match) {
    Logger().info(
        "loop closed at frame {}: keyframe {} -> {} ({} matches, scale {:.4f}), moved {:.3f} {} / "
        "{:.2f} deg, {} points fused",
        frame_index, outcome.query.value, outcome.match->matched.value,
        outcome.match->matches.size(), outcome.match->query_from_matched.scale,
        outcome.correction_m, mode_ == SlamMode::kStereo ? "m" : "map units",
        outcome.correction_deg, outcome.fused_points);
  } else if (outcome.kind == LoopOutcomeKind::kGlobalBundleAdjustment) {
    Logger().info("global BA at frame {}: {} keyframes, {} points, {:.0f} ms{}", frame_index,
                  outcome.ba_keyframes, outcome.ba_points, outcome.ba_ms,
                  outcome.ba_aborted ? " (aborted by a newer loop)" : "");
  } else {
    Logger().debug("loop candidate of keyframe {} rejected: {}", outcome.query.value,
                   outcome.rejection);
  }
  LoopEvent event;
  event.frame_index = frame_index;
  event.outcome = outcome;
  event.outcome.correction = MapCorrection{};
  loop_events_.push_back(std::move(event));
  return changed;
}

void SlamSystem::RunLoopJob(const std::shared_ptr<const LoopJob>& job, int64_t frame_index) {
  const std::shared_ptr<const LoopJob> resolved = loop_replica_.Resolve(job);
  const LoopOutcome corrected = LoopCloser::CloseLoop(*resolved);
  ApplyLoopOutcome(corrected, frame_index);
  if (LoopCloser::FollowsWithGlobalBundleAdjustment(*resolved, corrected))
    ApplyLoopOutcome(LoopCloser::GlobalBundleAdjustment(*resolved, corrected, nullptr),
                     frame_index);
}

bool SlamSystem::NeedsFinalGlobalBundleAdjustment() const {
  const bool wanted = mode_ == SlamMode::kStereo ? options_.loop.final_global_ba
                                                 : options_.loop.final_global_ba_mono;
  // final_global_ba_min_keyframes >= 1 (LoopClosingOptions::IsValid): an empty map never asks.
  return loop_closer_.IsActive() && wanted && loop_closer_.stats().corrections > 0 &&
         KeyframesAfterLastGlobalBundleAdjustment() >= options_.loop.final_global_ba_min_keyframes;
}

int SlamSystem::KeyframesAfterLastGlobalBundleAdjustment() const {
  if (!last_global_ba_newest_.valid()) return static_cast<int>(map_.keyframes().size());
  // Ids grow with time: the keyframes after it are the map's tail past its newest.
  return static_cast<int>(
      std::distance(map_.keyframes().upper_bound(last_global_ba_newest_), map_.keyframes().end()));
}

bool SlamSystem::FinalGlobalBundleAdjustment() {
  if (!NeedsFinalGlobalBundleAdjustment()) return false;
  Logger().info("final global BA: {} of the map's {} keyframes came after the last global BA",
                KeyframesAfterLastGlobalBundleAdjustment(), map_.keyframes().size());
  LoopOutcome outcome = LoopCloser::GlobalBundleAdjustmentOfMap(map_, options_.loop);
  outcome.query = map_.keyframes().rbegin()->first;
  return ApplyLoopOutcome(outcome, -1);
}

void FillTrackingOutput(const TrackingResult& tracking, FrameOutput* out) {
  out->status = tracking.status;
  out->method = tracking.method;
  out->num_tracked = tracking.num_tracked;
  out->num_matches_initial = tracking.num_matches_initial;
  out->num_inliers_initial = tracking.num_inliers_initial;
  out->num_local_projected = tracking.num_local_projected;
  out->num_local_matches = tracking.num_local_matches;
  out->world_from_cam = tracking.cam_from_world.inverse();
}

FrameOutput SlamSystem::ProcessFrame(int64_t frame_index, int64_t t_ns, const cv::Mat& left,
                                     const cv::Mat& right, const FrameFilterInput* filter) {
  const auto start = std::chrono::steady_clock::now();
  FrameOutput out;
  out.frame_index = frame_index;
  out.t_ns = t_ns;

  auto t = std::chrono::steady_clock::now();
  const OrbFeatures left_features = ExtractLeft(left);
  out.times_ms.orb_left = MsSince(t);
  StereoMatches stereo;
  if (mode_ == SlamMode::kStereo) {
    t = std::chrono::steady_clock::now();
    const OrbFeatures right_features = ExtractRight(right);
    out.times_ms.orb_right = MsSince(t);
    t = std::chrono::steady_clock::now();
    stereo = MatchStereoFeatures(left_features, right_features);
    out.times_ms.stereo = MsSince(t);
  }

  KeypointFilter keypoint_filter;
  if (filter) {
    t = std::chrono::steady_clock::now();
    keypoint_filter = SampleFilter(*filter, left_features.keypoints);
    out.times_ms.filter = MsSince(t);
  }
  const FramePtr frame = BuildFrame(t_ns, left_features, stereo, keypoint_filter);
  out.num_keypoints = frame->size();
  out.num_stereo = frame->num_stereo();
  out.num_excluded = frame->num_excluded();

  t = std::chrono::steady_clock::now();
  const TrackingResult tracking = Track(frame, frame_index);
  out.times_ms.tracking = MsSince(t);
  FillTrackingOutput(tracking, &out);

  t = std::chrono::steady_clock::now();
  const KeyframeDecision decision = DecideKeyframe(tracking);
  out.keyframe_reason = decision.reason;
  if (decision.insert) {
    out.mapping = InsertKeyframe(frame, tracking);
    out.keyframe_inserted = true;
    if (const auto job = DetectLoop(KeyframeId(frame->id()), false)) RunLoopJob(job, frame_index);
  }
  out.keyframe_inserted =
      out.keyframe_inserted || tracking.method == TrackingMethod::kInitialisation;
  out.times_ms.local_mapping = MsSince(t);
  out.num_keyframes = map_.num_keyframes();
  out.num_map_points = map_.num_points();
  out.times_ms.total = MsSince(start);
  return out;
}

Trajectory SlamSystem::RefinedTrajectory(const std::map<KeyframeId, int>* part_of,
                                         std::vector<int>* parts) const {
  Trajectory trajectory;
  if (parts) parts->clear();
  for (const FrameRecord& r : records_) {
    const auto ref_pose = map_.CamFromWorld(r.reference);
    if (!ref_pose) continue;
    StampedPose p;
    p.t_ns = r.t_ns;
    p.frame_index = r.frame_index;
    p.world_from_cam = (r.cam_from_reference * *ref_pose).inverse();
    trajectory.push_back(p);
    if (part_of && parts) {
      const auto it = part_of->find(map_.ResolveKeyframe(r.reference));
      parts->push_back(it == part_of->end() ? -1 : it->second);
    }
  }
  return trajectory;
}

}  // namespace pcr
