#include "slam/dynamic/dynamic_filter.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/timing.h"
#include "slam/common/validation.h"
#include "slam/geometry/se3.h"

namespace pcr {
namespace {

using Clock = std::chrono::steady_clock;

// Bilinear sample of a CV_32F map at a camera-convention pixel position, clamped to the image.
float SampleBilinear(const cv::Mat& map, float u, float v) {
  const float x = std::clamp(u, 0.0f, static_cast<float>(map.cols - 1));
  const float y = std::clamp(v, 0.0f, static_cast<float>(map.rows - 1));
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, map.cols - 1), y1 = std::min(y0 + 1, map.rows - 1);
  const float ax = x - x0, ay = y - y0;
  const float* r0 = map.ptr<float>(y0);
  const float* r1 = map.ptr<float>(y1);
  return (1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x1]) + ay * ((1 - ax) * r1[x0] + ax * r1[x1]);
}

// Where static points at the keypoints would have been in the previous image, for those with a
// stereo depth; (-1, -1) for the others (a guess at infinite depth is poor for mid-range points)
// and where the prediction leaves the image.
std::vector<cv::Point2f> PredictPreviousPixels(const PinholeCamera& camera,
                                               const std::vector<cv::Point2f>& cur_uv,
                                               const std::vector<float>& depth_m,
                                               const SE3& prev_from_cur) {
  std::vector<cv::Point2f> out(cur_uv.size());
  for (size_t i = 0; i < cur_uv.size(); ++i) {
    out[i] = cv::Point2f(-1.0f, -1.0f);
    if (!(depth_m[i] > 0.0f)) continue;
    const Eigen::Vector2d uv(cur_uv[i].x, cur_uv[i].y);
    const Eigen::Vector3d p = prev_from_cur * camera.Unproject(uv, depth_m[i]);
    if (p.z() > 0.05) {
      const Eigen::Vector2d q = camera.Project(p);
      if (camera.InImage(q))
        out[i] = cv::Point2f(static_cast<float>(q.x()), static_cast<float>(q.y()));
    }
  }
  return out;
}

}  // namespace

const char* MotionSourceName(MotionSource source) {
  switch (source) {
    case MotionSource::kNone:
      return "none";
    case MotionSource::kPrior:
      return "prior";
    case MotionSource::kPnp:
      return "pnp";
  }
  return "unknown";
}

bool DynamicFilterOptions::IsValid(std::string* why) const {
  std::string sub;
  auto check = [&](bool ok, const char* name) {
    if (!ok && why) *why = std::string(name) + ": " + sub;
    return ok;
  };
  if (!check(lk.IsValid(&sub), "lk") || !check(ego_motion.IsValid(&sub), "ego_motion") ||
      !check(motion.IsValid(&sub), "motion") || !check(ground.IsValid(&sub), "ground") ||
      !check(edge.IsValid(&sub), "edge") || !check(sky.IsValid(&sub), "sky") ||
      !check(voting.IsValid(&sub), "voting") || !check(scoring.IsValid(&sub), "scoring") ||
      !check(instances.IsValid(&sub), "instances") ||
      !check(instance_memory.IsValid(&sub), "instance_memory") ||
      !check(cluster.IsValid(&sub), "cluster") || !check(mask_depth.IsValid(&sub), "mask_depth") ||
      !check(classes.IsValid(&sub), "classes")) {
    return false;
  }
  if (!(keypoint_sigma_px > 0.0 && lk_sigma_px > 0.0)) {
    return Fail(why, "keypoint_sigma_px and lk_sigma_px must be > 0");
  }
  if (!(track_match_radius_px > 0.0)) return Fail(why, "track_match_radius_px must be > 0");
  if (!(previous_disparity_radius_px >= 0.0))
    return Fail(why, "previous_disparity_radius_px must be >= 0");
  if (!(pnp_max_dynamic_confidence > 0.0f && pnp_max_dynamic_confidence <= 1.0f)) {
    return Fail(why, "pnp_max_dynamic_confidence must be in (0, 1]");
  }
  if (!(default_frame_dt_s > 0.0)) return Fail(why, "default_frame_dt_s must be > 0");
  if (max_plane_age_frames < 0) return Fail(why, "max_plane_age_frames must be >= 0");
  if (!(max_prior_deviation_m > 0.0 && max_prior_deviation_rad > 0.0)) {
    return Fail(why, "max_prior_deviation_m and max_prior_deviation_rad must be > 0");
  }
  if (!(stale_mask_scale >= 0.0f && stale_mask_scale <= 1.0f)) {
    return Fail(why, "stale_mask_scale must be in [0, 1]");
  }
  if (long_baseline_frames < 0 || long_baseline_frames > kMaxLongBaseline) {
    return Fail(why,
                "long_baseline_frames must be in [0, " + std::to_string(kMaxLongBaseline) + "]");
  }
  return true;
}

DynamicFilter::DynamicFilter(const DynamicFilterOptions& options)
    : options_(options), sequence_(options.voting) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("DynamicFilterOptions: " + why);
  flow_ = options_.flow_factory ? options_.flow_factory() : MakeOpenCvFlowEngine();
  if (!flow_) throw ConfigError("DynamicFilterOptions: flow_factory made no engine");
}

struct DynamicFilter::FrameWork {
  FrameWork(const FilterInput& in, int64_t frame_index)
      : input(in),
        frame(frame_index),
        camera(in.rig.left),
        bf(in.rig.IsStereo() ? in.rig.Bf() : 0.0),
        n(in.keypoints.size()),
        matched_mode(!in.previous_uv_px.empty()) {}

  const FilterInput& input;
  const int64_t frame;
  const PinholeCamera& camera;
  const double bf;          // stereo baseline x focal length (px m), 0: monocular
  const size_t n;           // keypoints
  const bool matched_mode;  // previous positions from the input, not LK
  FilterOutput out;

  // PrepareKeypoints.
  std::vector<cv::Point2f> cur_uv;
  std::vector<float> depth;
  std::vector<double> scale;
  // SampleMask (confidence and instance also ReleaseRoadMargins).
  std::vector<float> confidence;
  std::vector<uint16_t> instance;  // dynamic-class instances only
  std::vector<uint8_t> sky_instance;
  std::vector<uint8_t> mask_outlier;
  std::vector<uint8_t> margin;
  std::vector<double> instance_speed_mps;  // per instance: reference speed, 0: default
  int num_instances = 0;
  // TrackFlow.
  std::vector<cv::Point2f> prev_uv;
  std::vector<uint8_t> observed;
  std::vector<int64_t> track_ids;
  std::vector<int> continues;  // index of the previous keypoint this one continues
  std::vector<cv::Mat> cur_pyramid;
  // ExtendLongBaseline.
  std::vector<std::array<cv::Point2f, kMaxLongBaseline>> history;
  std::vector<uint8_t> history_count;
  std::vector<SE3> cur_from_past;  // index m: current <- m + 1 frames back
  bool long_pnp = false;
  // EstimateGround.
  std::vector<Eigen::Vector3d> points;
  std::vector<uint8_t> has_depth;
  // ScoreMotion.
  std::vector<PointMotion> motions;
  // VoteTemporally (has_motion, static_prob and observability also ApplyInstanceMotion).
  std::vector<uint8_t> has_motion;
  std::vector<float> static_prob;
  std::vector<float> observability;
  // ApplyInstanceMotion: non-zero where the three above are the instance's verdict, taken by a
  // point that has no observation of its own or whose own test could not see a motion.
  std::vector<uint8_t> from_instance;
  std::vector<TrackVote> votes;
  std::vector<TrackState> states;
};

void DynamicFilter::Reset() { sequence_ = SequenceState(options_.voting); }

FilterOutput DynamicFilter::Process(const FilterInput& input) {
  const auto start = Clock::now();
  FrameWork w(input, CheckInput(input));
  w.out.frame_index = w.frame;
  w.out.t_ns = input.t_ns;
  w.out.points.resize(w.n);
  PrepareKeypoints(&w);

  auto stage = Clock::now();
  SampleMask(&w);
  w.out.timing.mask_ms = MsSince(stage);

  stage = Clock::now();
  TrackFlow(&w);
  w.out.timing.flow_ms = MsSince(stage);

  stage = Clock::now();
  EstimateCameraMotion(&w);
  w.out.timing.pose_ms = MsSince(stage);
  ExtendLongBaseline(&w);

  stage = Clock::now();
  EstimateGround(&w);
  w.out.timing.ransac_ms = MsSince(stage);
  ReleaseRoadMargins(&w);

  stage = Clock::now();
  ScoreMotion(&w);
  VoteTemporally(&w);
  ApplyInstanceMotion(&w);
  Decide(ScorePointTerms(w), &w);
  w.out.timing.scoring_ms = MsSince(stage);

  StoreForNextFrame(&w);
  w.out.timing.total_ms = MsSince(start);
  return std::move(w.out);
}

int64_t DynamicFilter::CheckInput(const FilterInput& input) const {
  const size_t n = input.keypoints.size();
  const cv::Mat& image = input.left_image;
  if (image.empty() || image.type() != CV_8UC1) {
    throw std::invalid_argument("DynamicFilter: left_image must be a non-empty CV_8UC1");
  }
  if (!input.previous_left_image.empty() && (input.previous_left_image.type() != CV_8UC1 ||
                                             input.previous_left_image.size() != image.size())) {
    throw std::invalid_argument(
        "DynamicFilter: previous_left_image must be CV_8UC1 of the image's size");
  }
  if ((!input.depth_m.empty() && input.depth_m.size() != n) ||
      (!input.point_ids.empty() && input.point_ids.size() != n) ||
      (!input.previous_uv_px.empty() && input.previous_uv_px.size() != n)) {
    throw std::invalid_argument("DynamicFilter: per-keypoint inputs must match the keypoints");
  }
  if (!(input.scale_factor >= 1.0)) {
    throw std::invalid_argument("DynamicFilter: scale_factor must be >= 1");
  }
  const Segmentation* seg = input.segmentation;
  if (seg) {
    if (!seg->dynamic_confidence.empty() && (seg->dynamic_confidence.type() != CV_32FC1 ||
                                             seg->dynamic_confidence.size() != image.size())) {
      throw std::invalid_argument("DynamicFilter: dynamic_confidence must be CV_32F, image size");
    }
    if (!seg->instance_map.empty() &&
        (seg->instance_map.type() != CV_16UC1 || seg->instance_map.size() != image.size())) {
      throw std::invalid_argument("DynamicFilter: instance_map must be CV_16U, image size");
    }
  }
  const std::optional<PreviousFrame>& previous = sequence_.previous;
  const int64_t previous_frame = previous ? previous->frame : -1;
  const int64_t frame = input.frame_index >= 0 ? input.frame_index : previous_frame + 1;
  if (previous && frame <= previous_frame) {
    throw std::invalid_argument("DynamicFilter: frame_index must increase (call Reset())");
  }
  return frame;
}

void DynamicFilter::PrepareKeypoints(FrameWork* w) {
  const FilterInput& input = w->input;
  const size_t n = w->n;
  w->cur_uv.resize(n);
  w->depth.assign(n, -1.0f);
  w->scale.assign(n, 1.0);
  for (size_t i = 0; i < n; ++i) {
    w->cur_uv[i] = input.keypoints[i].pt;
    if (!input.depth_m.empty() && w->bf > 0.0 && input.depth_m[i] > 0.0f &&
        std::isfinite(input.depth_m[i])) {
      w->depth[i] = input.depth_m[i];
    }
    w->scale[i] = std::pow(input.scale_factor, std::max(0, input.keypoints[i].octave));
  }
}

void DynamicFilter::SampleMask(FrameWork* w) const {
  const size_t n = w->n;
  const cv::Mat& image = w->input.left_image;
  const std::vector<cv::Point2f>& cur_uv = w->cur_uv;
  std::vector<float>& confidence = w->confidence;
  std::vector<uint16_t>& instance = w->instance;
  confidence.assign(n, 0.0f);
  instance.assign(n, 0);
  w->sky_instance.assign(n, 0);
  w->mask_outlier.assign(n, 0);
  w->margin.assign(n, kNotMargin);
  w->instance_speed_mps.assign(1, 0.0);
  const Segmentation* seg = w->input.segmentation;
  if (!seg) return;
  const int num_instances = static_cast<int>(seg->instances.size());
  w->num_instances = num_instances;
  std::vector<uint8_t> is_dynamic(num_instances + 1, 0), is_sky(num_instances + 1, 0);
  for (int k = 1; k <= num_instances; ++k) {
    const std::string& name = seg->instances[k - 1].class_name;
    const DynamicClass* dynamic_class = options_.classes.Find(name);
    is_dynamic[k] = dynamic_class != nullptr;
    w->instance_speed_mps.push_back(
        dynamic_class ? options_.classes.Params(dynamic_class->policy).reference_speed_mps : 0.0);
    is_sky[k] = std::find(options_.sky.class_names.begin(), options_.sky.class_names.end(), name) !=
                options_.sky.class_names.end();
  }
  const float mask_scale = seg->stale ? options_.stale_mask_scale : 1.0f;
  for (size_t i = 0; i < n; ++i) {
    if (!seg->dynamic_confidence.empty()) {
      confidence[i] =
          std::clamp(SampleBilinear(seg->dynamic_confidence, cur_uv[i].x, cur_uv[i].y) * mask_scale,
                     0.0f, 1.0f);
    }
    if (!seg->instance_map.empty()) {
      const int u = std::clamp(static_cast<int>(std::lround(cur_uv[i].x)), 0, image.cols - 1);
      const int v = std::clamp(static_cast<int>(std::lround(cur_uv[i].y)), 0, image.rows - 1);
      const int k = seg->instance_map.at<uint16_t>(v, u);
      if (k >= 1 && k <= num_instances) {
        if (is_dynamic[k]) instance[i] = static_cast<uint16_t>(k);
        w->sky_instance[i] = is_sky[k];
      }
    }
  }
  std::vector<cv::Rect2f> boxes(num_instances);
  for (int k = 1; k <= num_instances; ++k) {
    if (is_dynamic[k]) boxes[k - 1] = seg->instances[k - 1].box_px;
  }
  MaskMembership membership =
      ResolveMaskMembership(cur_uv, w->depth, instance, confidence, boxes, options_.mask_depth);
  instance = std::move(membership.instance);
  w->mask_outlier = std::move(membership.depth_outlier);
  w->margin = std::move(membership.margin);
  for (size_t i = 0; i < n; ++i) {
    if (w->mask_outlier[i]) confidence[i] = 0.0f;
    if (w->margin[i] == kMarginUnresolved)
      confidence[i] *= options_.mask_depth.unresolved_margin_scale;
  }
}

void DynamicFilter::TrackFlow(FrameWork* w) {
  const FilterInput& input = w->input;
  const size_t n = w->n;
  const cv::Mat& image = input.left_image;
  const PreviousFrame* previous = sequence_.previous ? &*sequence_.previous : nullptr;
  std::vector<cv::Point2f>& prev_uv = w->prev_uv;
  std::vector<uint8_t>& observed = w->observed;
  std::vector<int64_t>& track_ids = w->track_ids;
  std::vector<int>& continues = w->continues;
  prev_uv.assign(n, cv::Point2f(-1.0f, -1.0f));
  observed.assign(n, 0);
  track_ids.assign(n, -1);
  continues.assign(n, -1);
  if (w->matched_mode) {
    for (size_t i = 0; i < n; ++i) {
      const cv::Point2f p = input.previous_uv_px[i];
      if (p.x >= 0.0f && p.y >= 0.0f && std::isfinite(p.x) && std::isfinite(p.y)) {
        prev_uv[i] = p;
        observed[i] = 1;
      }
    }
  } else if (options_.use_lk && input.lk) {
    w->cur_pyramid = BuildLkPyramid(image, options_.lk);
    std::vector<cv::Mat> given_previous;
    const std::vector<cv::Mat>* prev_pyramid = nullptr;
    if (!input.previous_left_image.empty()) {
      given_previous = BuildLkPyramid(input.previous_left_image, options_.lk);
      prev_pyramid = &given_previous;
    } else if (previous && previous->size == image.size() && !previous->pyramid.empty()) {
      prev_pyramid = &previous->pyramid;
    }
    if (prev_pyramid) {
      // Start LK at the static prediction under the caller's prior or, failing that, the last
      // frame's motion (constant velocity): near points flow too fast to be found from zero.
      std::vector<cv::Point2f> guess;
      const SE3* guess_motion = input.cur_from_prev                   ? &*input.cur_from_prev
                                : previous && previous->cur_from_prev ? &*previous->cur_from_prev
                                                                      : nullptr;
      if (options_.lk_predict_initial_flow && guess_motion) {
        guess = PredictPreviousPixels(w->camera, w->cur_uv, w->depth, guess_motion->inverse());
      }
      const FlowTracks tracks = TrackIntoPrevious(*prev_pyramid, w->cur_pyramid, w->cur_uv,
                                                  options_.lk, guess, flow_.get());
      prev_uv = tracks.prev_uv_px;
      observed = tracks.valid;
      // Each tracked keypoint continues the previous keypoint nearest to where LK found it
      // (within the radius): its temporal state and track id. Several keypoints may continue
      // the same one (the same corner found at several octaves).
      if (previous && input.previous_left_image.empty() && !previous->uv_px.empty()) {
        const std::vector<cv::Point2f>& previous_uv = previous->uv_px;
        const double cell = std::max(4.0, 2.0 * options_.track_match_radius_px);
        const int cols = static_cast<int>(image.cols / cell) + 1;
        const int rows = static_cast<int>(image.rows / cell) + 1;
        std::vector<std::vector<int>> grid(static_cast<size_t>(cols * rows));
        for (size_t j = 0; j < previous_uv.size(); ++j) {
          const int cu = std::clamp(static_cast<int>(previous_uv[j].x / cell), 0, cols - 1);
          const int cv = std::clamp(static_cast<int>(previous_uv[j].y / cell), 0, rows - 1);
          grid[cv * cols + cu].push_back(static_cast<int>(j));
        }
        const double r2 = options_.track_match_radius_px * options_.track_match_radius_px;
        for (size_t i = 0; i < n; ++i) {
          if (!observed[i]) continue;
          const int cu = static_cast<int>(prev_uv[i].x / cell);
          const int cv = static_cast<int>(prev_uv[i].y / cell);
          double best_d2 = r2;
          for (int y = std::max(0, cv - 1); y <= std::min(rows - 1, cv + 1); ++y) {
            for (int x = std::max(0, cu - 1); x <= std::min(cols - 1, cu + 1); ++x) {
              for (int j : grid[y * cols + x]) {
                const cv::Point2f d = previous_uv[j] - prev_uv[i];
                const double d2 = d.x * d.x + d.y * d.y;
                if (d2 <= best_d2) {
                  best_d2 = d2;
                  continues[i] = j;
                }
              }
            }
          }
          if (continues[i] >= 0) {
            track_ids[i] = previous->track_ids[continues[i]];
            ++w->out.num_continued;
          }
        }
      }
    }
    for (size_t i = 0; i < n; ++i) {
      if (track_ids[i] < 0) track_ids[i] = next_track_id_++;
    }
  }
  for (size_t i = 0; i < n; ++i) w->out.num_tracked += observed[i] ? 1 : 0;
}

void DynamicFilter::EstimateCameraMotion(FrameWork* w) const {
  const FilterInput& input = w->input;
  FilterOutput& out = w->out;
  const size_t n = w->n;
  const SE3* prior = input.cur_from_prev ? &*input.cur_from_prev : nullptr;
  const bool want_pnp = options_.motion_source == MotionSourcePolicy::kPnpElsePrior ||
                        (options_.motion_source == MotionSourcePolicy::kPriorElsePnp && !prior);
  if (want_pnp && w->bf > 0.0 && out.num_tracked > 0) {
    std::vector<uint8_t> usable(n, 0);
    for (size_t i = 0; i < n; ++i) {
      usable[i] = w->observed[i] && w->depth[i] > 0.0f &&
                  w->confidence[i] < options_.pnp_max_dynamic_confidence && !w->sky_instance[i];
    }
    const EgoMotionEstimate pnp = EstimateCurFromPrev(w->camera, w->cur_uv, w->depth, w->prev_uv,
                                                      usable, prior, options_.ego_motion);
    out.pnp_candidates = pnp.num_candidates;
    out.pnp_inliers = pnp.num_inliers;
    if (pnp.success && prior) {
      // A PnP far from the prior is more likely locked on a large moving object than right.
      const SE3 delta = prior->inverse() * pnp.cur_from_prev;
      const double dt_m = delta.translation().norm();
      const double dr_rad = RotationAngleRad(delta.linear());
      if (dt_m > options_.max_prior_deviation_m || dr_rad > options_.max_prior_deviation_rad) {
        out.motion_note = "PnP rejected: " + std::to_string(dt_m) + " m / " +
                          std::to_string(RadToDeg(dr_rad)) + " deg from the prior";
      } else {
        out.motion_source = MotionSource::kPnp;
        out.cur_from_prev = pnp.cur_from_prev;
      }
    } else if (pnp.success) {
      out.motion_source = MotionSource::kPnp;
      out.cur_from_prev = pnp.cur_from_prev;
    } else {
      out.motion_note = pnp.failure_reason;
    }
  }
  if (out.motion_source == MotionSource::kNone && prior) {
    out.motion_source = MotionSource::kPrior;
    out.cur_from_prev = *prior;
  }
}

void DynamicFilter::ExtendLongBaseline(FrameWork* w) const {
  // Long-baseline tracks: each tracked keypoint's positions 1..K frames back (K =
  // long_baseline_frames), from LK into the previous frame and, before that, the history of the
  // previous keypoint it continues (shifted by the continuation offset), and the chained camera
  // motion current <- those frames.
  const size_t n = w->n;
  const FilterOutput& out = w->out;
  const PreviousFrame* previous = sequence_.previous ? &*sequence_.previous : nullptr;
  std::vector<std::array<cv::Point2f, kMaxLongBaseline>>& history = w->history;
  std::vector<SE3>& cur_from_past = w->cur_from_past;
  const int max_history = options_.long_baseline_frames >= 2 ? options_.long_baseline_frames : 0;
  history.resize(max_history > 0 ? n : 0);
  w->history_count.assign(n, 0);
  if (max_history > 0 && out.motion_source != MotionSource::kNone) {
    cur_from_past.push_back(out.cur_from_prev);
    if (previous) {
      for (const SE3& prev_from_past : previous->from_past) {
        if (static_cast<int>(cur_from_past.size()) >= max_history) break;
        cur_from_past.push_back(out.cur_from_prev * prev_from_past);
      }
    }
    for (size_t i = 0; i < n; ++i) {
      if (!w->observed[i]) continue;
      history[i][0] = w->prev_uv[i];
      int count = 1;
      const int j = w->continues[i];
      if (j >= 0 && static_cast<size_t>(j) < previous->history_count.size()) {
        const cv::Point2f offset = w->prev_uv[i] - previous->uv_px[j];
        const int older = std::min<int>(previous->history_count[j], max_history - 1);
        for (int m = 0; m < older; ++m) history[i][m + 1] = previous->history_px[j][m] + offset;
        count += older;
      }
      w->history_count[i] = static_cast<uint8_t>(std::min<int>(count, cur_from_past.size()));
    }
  }
  // The chained motion to the oldest frame accumulates every frame's rotation error (the
  // largest term for far points): PnP on the long tracks themselves measures it directly.
  const int longest = static_cast<int>(cur_from_past.size());
  if (longest >= 2 && w->bf > 0.0 && options_.long_baseline_pnp) {
    std::vector<cv::Point2f> past_uv(n, cv::Point2f(-1.0f, -1.0f));
    std::vector<uint8_t> usable(n, 0);
    for (size_t i = 0; i < n; ++i) {
      if (w->history_count[i] != longest) continue;
      past_uv[i] = history[i][longest - 1];
      usable[i] = w->depth[i] > 0.0f && w->confidence[i] < options_.pnp_max_dynamic_confidence &&
                  !w->sky_instance[i];
    }
    const SE3 chained = cur_from_past[longest - 1];
    const EgoMotionEstimate pnp = EstimateCurFromPrev(w->camera, w->cur_uv, w->depth, past_uv,
                                                      usable, &chained, options_.ego_motion);
    if (pnp.success) {
      const SE3 delta = chained.inverse() * pnp.cur_from_prev;
      if (delta.translation().norm() <= options_.max_prior_deviation_m &&
          RotationAngleRad(delta.linear()) <= options_.max_prior_deviation_rad) {
        cur_from_past[longest - 1] = pnp.cur_from_prev;
        w->long_pnp = true;
      }
    }
  }
}

void DynamicFilter::EstimateGround(FrameWork* w) {
  const size_t n = w->n;
  const PinholeCamera& camera = w->camera;
  FilterOutput& out = w->out;
  w->points.assign(n, Eigen::Vector3d::Zero());
  w->has_depth.assign(n, 0);
  for (size_t i = 0; i < n; ++i) {
    if (w->depth[i] <= 0.0f) continue;
    w->points[i] = camera.Unproject(Eigen::Vector2d(w->cur_uv[i].x, w->cur_uv[i].y), w->depth[i]);
    w->has_depth[i] = 1;
  }
  std::optional<Plane>& last_plane = sequence_.last_plane;
  if (w->bf > 0.0) {
    out.ground = EstimateGroundPlane(w->points, w->has_depth, last_plane ? last_plane->d : 0.0,
                                     options_.ground);
  } else {
    out.ground.failure_reason = "monocular rig";
  }
  if (out.ground.success) {
    out.ground_plane = out.ground.plane;
    last_plane = out.ground.plane;
    sequence_.last_plane_frame = w->frame;
  } else if (last_plane && w->frame - sequence_.last_plane_frame <= options_.max_plane_age_frames) {
    out.ground_plane = last_plane;
    out.ground_from_previous = true;
  }
  if (out.ground_plane) {
    out.horizon = HorizonFromPlane(camera, *out.ground_plane);
  } else {
    Plane prior_plane;
    prior_plane.normal = Eigen::Vector3d(0.0, -1.0, 0.0);
    prior_plane.d = options_.ground.prior_height_m;
    out.horizon = HorizonFromPlane(camera, prior_plane);
    out.horizon.from_prior = true;
  }
}

void DynamicFilter::ReleaseRoadMargins(FrameWork* w) const {
  // The road beside a car's wheels is at the car's depth: a margin point on the ground plane is
  // road, not the car.
  if (!w->out.ground_plane) return;
  for (size_t i = 0; i < w->n; ++i) {
    if (w->margin[i] == kMarginJoined && w->has_depth[i] &&
        IsGroundPoint(*w->out.ground_plane, w->points[i], w->bf, options_.ground)) {
      w->confidence[i] *= options_.mask_depth.ground_margin_scale;
      if (w->confidence[i] < options_.mask_depth.margin_min_confidence) w->instance[i] = 0;
    }
  }
}

void DynamicFilter::ScoreMotion(FrameWork* w) const {
  const FilterInput& input = w->input;
  FilterOutput& out = w->out;
  const size_t n = w->n;
  const PinholeCamera& camera = w->camera;
  const double bf = w->bf;
  const std::vector<cv::Point2f>& cur_uv = w->cur_uv;
  const std::vector<cv::Point2f>& prev_uv = w->prev_uv;
  const std::vector<float>& depth = w->depth;
  const std::vector<float>& confidence = w->confidence;
  const PreviousFrame* previous = sequence_.previous ? &*sequence_.previous : nullptr;
  double dt_s = options_.default_frame_dt_s;
  if (previous && input.t_ns > previous->t_ns) dt_s = NsToSeconds(input.t_ns - previous->t_ns);
  const double displacement_m = options_.motion.reference_speed_mps * dt_s;
  const SE3 prev_from_cur = out.cur_from_prev.inverse();
  Eigen::Vector3d travel_dir(0.0, 0.0, 1.0);  // camera travel in the current frame
  const Eigen::Vector3d travel = -out.cur_from_prev.translation();
  if (travel.norm() > 1e-3) travel_dir = travel.normalized();
  const PoseSigma pose_sigma = out.motion_source == MotionSource::kPnp ? options_.motion.pnp_pose
                                                                       : options_.motion.prior_pose;
  const int longest = static_cast<int>(w->cur_from_past.size());

  std::vector<PointMotion>& motions = w->motions;
  motions.assign(n, PointMotion());
  std::vector<PointMotion> suspect_alternative(n);  // epipolar verdicts of suspect depth tests
  std::vector<uint8_t> suspect(n, 0);
  for (size_t i = 0; i < n; ++i) {
    PointMotion& pm = motions[i];
    if (w->observed[i] && out.motion_source != MotionSource::kNone) {
      PointNoise noise;
      if (w->matched_mode) {
        noise.cur_sigma_px = options_.keypoint_sigma_px * w->scale[i];
        noise.prev_sigma_px = options_.keypoint_sigma_px * w->scale[i];
      } else {
        noise.cur_sigma_px = 0.0;  // LK tracks the patch at the keypoint itself
        noise.prev_sigma_px = options_.lk_sigma_px;
      }
      noise.disparity_sigma_px = options_.motion.disparity_sigma_px * w->scale[i];
      // The previous keypoint this track continues, when LK landed on it, brings its disparity.
      if (options_.use_previous_disparity && w->continues[i] >= 0 && bf > 0.0) {
        const size_t j = static_cast<size_t>(w->continues[i]);
        const cv::Point2f gap = previous->uv_px[j] - prev_uv[i];
        if (j < previous->depth_m.size() && previous->depth_m[j] > 0.0f &&
            gap.x * gap.x + gap.y * gap.y <=
                options_.previous_disparity_radius_px * options_.previous_disparity_radius_px)
          noise.prev_disparity_px = bf / previous->depth_m[j];
      }
      const std::vector<uint16_t>& instance = w->instance;
      const double class_speed_mps = instance[i] > 0 && instance[i] < w->instance_speed_mps.size()
                                         ? w->instance_speed_mps[instance[i]]
                                         : 0.0;
      const double object_step_m = class_speed_mps > 0.0 ? class_speed_mps * dt_s : displacement_m;
      pm = ScorePointMotion(camera, bf, Eigen::Vector2d(cur_uv[i].x, cur_uv[i].y), depth[i],
                            Eigen::Vector2d(prev_uv[i].x, prev_uv[i].y), prev_from_cur, pose_sigma,
                            noise, object_step_m, travel_dir, options_.motion);
      const int k = w->history_count[i];
      if (k >= 2 && depth[i] > 0.0f && !w->matched_mode) {
        // The same test k frames back: displacement x k, tracking and pose noise x sqrt(k).
        const double root_k = std::sqrt(static_cast<double>(k));
        PointNoise long_noise = noise;
        long_noise.prev_sigma_px = noise.prev_sigma_px * root_k;
        long_noise.prev_disparity_px = -1.0;  // the previous disparity is one frame back, not k
        // Chained motions add their errors; a PnP over the long tracks has a single one.
        const double pose_factor = w->long_pnp && k == longest ? 1.0 : root_k;
        const PoseSigma long_sigma{pose_sigma.rotation_rad * pose_factor,
                                   pose_sigma.translation_m * pose_factor};
        const cv::Point2f past = w->history[i][k - 1];
        const PointMotion long_pm = ScorePointMotion(
            camera, bf, Eigen::Vector2d(cur_uv[i].x, cur_uv[i].y), depth[i],
            Eigen::Vector2d(past.x, past.y), w->cur_from_past[k - 1].inverse(), long_sigma,
            long_noise, object_step_m * k, travel_dir, options_.motion);
        if (long_pm.valid() && long_pm.observability >= pm.observability) pm = long_pm;
      }
      // Outside any mask, a depth test that sees motion where the depth-free epipolar test sees
      // none is more often a wrong stereo match (repetitive road texture) than a moving object:
      // the point's motion evidence is dropped (its depth is suspect, not the point).
      if (options_.cross_check_depth_motion && pm.test == MotionTest::kDepth &&
          pm.static_prob < 0.5 && confidence[i] < options_.scoring.mask_evidence_below) {
        const PointMotion epipolar =
            ScorePointMotion(camera, bf, Eigen::Vector2d(cur_uv[i].x, cur_uv[i].y), -1.0,
                             Eigen::Vector2d(prev_uv[i].x, prev_uv[i].y), prev_from_cur, pose_sigma,
                             noise, object_step_m, travel_dir, options_.motion);
        if (epipolar.valid() && epipolar.static_prob >= 0.5) {
          suspect[i] = 1;
          suspect_alternative[i] = epipolar;
        }
      }
    }
  }
  const Segmentation* seg = input.segmentation;
  // With a segmenter, the epipolar test alone (no depth) does not call an unmasked point moving:
  // LK sliding along edges and stripes fools it more often than a detector misses an object
  // (a missed mask is bridged by the temporal vote).
  if (seg != nullptr && options_.cross_check_depth_motion) {
    for (size_t i = 0; i < n; ++i) {
      if (motions[i].test == MotionTest::kEpipolar && motions[i].static_prob < 0.5 &&
          confidence[i] < options_.scoring.mask_evidence_below) {
        motions[i].static_prob = 0.5;
        ++out.num_depth_suspect;
      }
    }
  }
  // A suspect is a wrong depth when it moves alone: a moving object moves its neighbours too.
  if (options_.cross_check_depth_motion) {
    const double r2 = options_.cross_check_radius_px * options_.cross_check_radius_px;
    for (size_t i = 0; i < n; ++i) {
      if (!suspect[i]) continue;
      // With a segmenter, an object that moves is expected under a mask: any unmasked suspect
      // is a suspect depth. Without one, only a lone suspect is.
      if (seg != nullptr) {
        motions[i] = suspect_alternative[i];
        ++out.num_depth_suspect;
        continue;
      }
      int moving_neighbours = 0;
      for (size_t j = 0; j < n && moving_neighbours < options_.cross_check_min_neighbours; ++j) {
        if (j == i || !motions[j].valid() || motions[j].static_prob >= 0.5) continue;
        const cv::Point2f dd = cur_uv[j] - cur_uv[i];
        if (dd.x * dd.x + dd.y * dd.y > r2 || !(depth[j] > 0.0f)) continue;
        // Neighbours on the same surface: at about the suspect's (stereo) depth.
        if (std::abs(depth[j] - depth[i]) <= std::max(1.0, 0.15 * depth[i])) ++moving_neighbours;
      }
      if (moving_neighbours < options_.cross_check_min_neighbours) {
        motions[i] = suspect_alternative[i];
        ++out.num_depth_suspect;
      }
    }
  }
}

void DynamicFilter::VoteTemporally(FrameWork* w) {
  const FilterInput& input = w->input;
  const size_t n = w->n;
  w->has_motion.assign(n, 0);
  w->static_prob.assign(n, 0.5f);
  w->observability.assign(n, 0.0f);
  w->from_instance.assign(n, 0);
  w->votes.assign(n, TrackVote());
  w->states.assign(n, TrackState());
  for (size_t i = 0; i < n; ++i) {
    KeypointDiagnostics& d = w->out.points[i];
    d.track_id = w->track_ids[i];
    d.instance = w->instance[i];
    d.mask_depth_outlier = w->mask_outlier[i];
    const PointMotion& pm = w->motions[i];
    d.test = pm.test;
    if (pm.valid()) {
      d.frame_static_prob = static_cast<float>(pm.static_prob);
      d.observability = static_cast<float>(pm.observability);
      d.residual_px = static_cast<float>(pm.residual_px);
      d.chi2 = static_cast<float>(pm.chi2);
    }
    // Temporal state: the map point's when it has one, else the state carried along the LK
    // track, else a fresh one.
    const int64_t map_id = input.point_ids.empty() ? -1 : input.point_ids[i];
    TrackState state;
    const TrackState* stored = map_id >= 0 ? sequence_.voting.Find(map_id) : nullptr;
    if (stored) {
      state = *stored;
    } else if (w->continues[i] >= 0) {
      state = sequence_.previous->states[w->continues[i]];
    }
    const MotionEvidence evidence{pm.static_prob, pm.observability};
    TrackVote& vote = w->votes[i];
    vote = sequence_.voting.Advance(&state, w->frame, pm.valid() ? &evidence : nullptr);
    if (map_id >= 0) sequence_.voting.Store(map_id, state);
    w->states[i] = state;
    d.vote_log_odds = static_cast<float>(vote.log_odds);
    if (vote.window_count > 0) {
      w->has_motion[i] = 1;
      w->static_prob[i] = static_cast<float>(vote.window_static_prob);
      w->observability[i] = static_cast<float>(vote.window_observability);
    }
  }
}

void DynamicFilter::ApplyInstanceMotion(FrameWork* w) {
  // Instance-level motion: unobserved points of a confirmed static (parked) or moving instance
  // take the instance's verdict.
  const int num_instances = w->num_instances;
  if (num_instances <= 0) return;
  const FilterInput& input = w->input;
  const Segmentation* seg = input.segmentation;
  const std::vector<uint16_t>& instance = w->instance;
  std::vector<uint8_t>& has_motion = w->has_motion;
  std::vector<float>& static_prob = w->static_prob;
  std::vector<float>& observability = w->observability;
  std::vector<InstanceMotion> summary = SummarizeInstances(
      instance, num_instances, has_motion, static_prob, observability, options_.instances);
  std::vector<cv::Rect2f> boxes(num_instances);
  std::vector<std::string> class_names(num_instances);
  for (int k = 1; k <= num_instances; ++k) {
    if (w->instance_speed_mps.size() > static_cast<size_t>(k) &&
        options_.classes.Find(seg->instances[k - 1].class_name)) {
      boxes[k - 1] = seg->instances[k - 1].box_px;
      class_names[k - 1] = seg->instances[k - 1].class_name;
    }
  }
  w->out.num_recalled_instances = RecallInstanceVerdicts(
      boxes, class_names, w->frame, options_.instance_memory, &summary, &sequence_.instance_memory);
  for (size_t i = 0; i < w->n; ++i) {
    if (instance[i] == 0) continue;
    const InstanceMotion& m = summary[instance[i]];
    if (m.state == InstanceState::kUnknown) continue;
    // Unobserved points, and points whose own test could not have seen a motion (no depth, far
    // ahead), take the instance's verdict.
    const bool own_blind =
        observability[i] < options_.instances.static_min_observability &&
        (m.state == InstanceState::kMoving ? static_prob[i] >= options_.instances.moving_below
                                           : true);
    if (!has_motion[i] || own_blind) {
      has_motion[i] = 1;
      w->from_instance[i] = 1;
      static_prob[i] = static_cast<float>(
          m.state == InstanceState::kMoving
              ? std::min<double>(m.median_static_prob, options_.instances.moving_below * 0.5)
              : m.median_static_prob);
      observability[i] =
          static_cast<float>(m.state == InstanceState::kMoving ? 1.0 : m.median_observability);
    } else if (m.state == InstanceState::kStatic) {
      // A point of a confirmed static instance whose own test saw no motion shares the
      // instance's confirmation (e.g. a point without depth: epipolar test only).
      observability[i] = std::max(observability[i], static_cast<float>(m.median_observability));
    }
    // A point of a moving instance carries "moving" along its track: a frame where the
    // detector misses the object, or where the point's own test is blind, still excludes it.
    if (m.state == InstanceState::kMoving && options_.instance_vote) {
      const double floor =
          std::min(options_.voting.max_log_odds,
                   options_.voting.dynamic_threshold + options_.voting.max_evidence);
      TrackState& state = w->states[i];
      if (state.log_odds < floor) {
        state.log_odds = floor;
        const int64_t map_id = input.point_ids.empty() ? -1 : input.point_ids[i];
        if (map_id >= 0) sequence_.voting.Store(map_id, state);
      }
    }
  }
}

std::vector<PointTerms> DynamicFilter::ScorePointTerms(const FrameWork& w) const {
  const cv::Mat& image = w.input.left_image;
  std::vector<PointTerms> terms(w.n);
  for (size_t i = 0; i < w.n; ++i) {
    PointTerms& t = terms[i];
    const Eigen::Vector2d uv(w.cur_uv[i].x, w.cur_uv[i].y);
    t.s_mask = 1.0 - w.confidence[i];
    t.has_motion = w.has_motion[i];
    t.first_frame = !sequence_.previous && options_.keep_first_frame_masks;
    if (w.has_motion[i]) {
      t.m_motion = GateByObservability(w.static_prob[i], w.observability[i]);
      t.own_static_prob = w.static_prob[i];
      t.motion_from_instance = w.from_instance[i];
    }
    if (w.out.ground_plane && w.has_depth[i] &&
        IsGroundPoint(*w.out.ground_plane, w.points[i], w.bf, options_.ground)) {
      t.ground = true;
      t.g_ground = options_.ground.ground_score;
    }
    t.e_edge = EdgeScore(uv, image.size(), options_.edge);
    t.hard_edge = BorderDistancePx(uv, image.size()) < options_.edge.exclude_within_px;
    t.sky = w.sky_instance[i] || IsSkyPoint(image, uv, w.depth[i], w.out.horizon, options_.sky);
    if (t.sky) t.e_edge = 0.0;
  }
  return terms;
}

void DynamicFilter::Decide(const std::vector<PointTerms>& terms, FrameWork* w) const {
  const size_t n = w->n;
  FilterOutput& out = w->out;
  std::vector<uint8_t> seeds(n, 0), candidates(n, 0), weak(n, 0), road(n, 0);
  for (size_t i = 0; i < n; ++i) {
    KeypointDiagnostics& d = out.points[i];
    const PointTerms& t = terms[i];
    const double score = StaticScore(t, options_.scoring.weights);
    FilterReason reason = DecidePoint(t, score, options_.scoring, options_.ground.remove_ground);
    road[i] = IsRoadPoint(t, options_.scoring);
    // A vote does not exclude an unresolved margin point (beside a mask, no depth to tell the
    // object from the background): background there earns votes while the object covers it or
    // drags its track, and keeps them after the object has passed.
    if (reason == FilterReason::kKept && w->votes[i].dynamic && w->margin[i] != kMarginUnresolved)
      reason = road[i] ? FilterReason::kGroundMotion : FilterReason::kVote;
    d.s_mask = static_cast<float>(t.s_mask);
    d.m_motion = static_cast<float>(t.m_motion);
    d.has_motion = t.has_motion;
    d.g_ground = static_cast<float>(t.g_ground);
    d.e_edge = static_cast<float>(t.e_edge);
    d.ground = t.ground;
    d.sky = t.sky;
    d.score = static_cast<float>(score);
    d.reason = reason;
    // An instance's motion verdict seeds clusters as the point's own motion would.
    seeds[i] = reason == FilterReason::kMaskMotion || reason == FilterReason::kMotion ||
               reason == FilterReason::kVote ||
               (reason == FilterReason::kCluster && t.motion_from_instance);
    // kMask points may be relabelled: cluster evidence says more than the mask alone.
    candidates[i] = (reason == FilterReason::kKept || reason == FilterReason::kMask) &&
                    !(t.has_motion && t.m_motion >= options_.cluster.protect_static_above);
    weak[i] = t.has_motion && t.m_motion < options_.scoring.motion_evidence_below;
  }
  const std::vector<uint8_t> joined = ClusterExclusions(
      w->camera, w->cur_uv, w->depth,
      w->input.segmentation ? std::span<const uint16_t>(w->instance) : std::span<const uint16_t>(),
      seeds, candidates, options_.cluster, weak);

  out.filter.weight.resize(n);
  out.filter.excluded.resize(n);
  for (size_t i = 0; i < n; ++i) {
    KeypointDiagnostics& d = out.points[i];
    if (joined[i]) d.reason = road[i] ? FilterReason::kGroundMotion : FilterReason::kCluster;
    out.filter.excluded[i] = d.reason != FilterReason::kKept;
    out.filter.weight[i] = WeightFromScore(d.score, options_.scoring);
    ++out.reason_counts[static_cast<int>(d.reason)];
    if (out.filter.excluded[i]) ++out.num_excluded;
    if (IsMovingReason(d.reason)) ++out.num_moving;
  }
}

void DynamicFilter::StoreForNextFrame(FrameWork* w) {
  sequence_.voting.Prune(w->frame);
  PreviousFrame next;
  next.frame = w->frame;
  next.t_ns = w->input.t_ns;
  next.size = w->input.left_image.size();
  next.pyramid = std::move(w->cur_pyramid);
  next.uv_px = std::move(w->cur_uv);
  next.depth_m = std::move(w->depth);
  next.track_ids = std::move(w->track_ids);
  next.states = std::move(w->states);
  next.history_px = std::move(w->history);
  next.history_count = std::move(w->history_count);
  next.from_past = std::move(w->cur_from_past);
  if (w->out.motion_source != MotionSource::kNone) next.cur_from_prev = w->out.cur_from_prev;
  sequence_.previous = std::move(next);
}

}  // namespace pcr
