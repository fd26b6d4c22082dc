#include "slam/dynamic/point_scorer.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "slam/common/validation.h"

namespace pcr {
namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  double m = values[mid];
  if (values.size() % 2 == 0) {
    m = 0.5 * (m + *std::max_element(values.begin(), values.begin() + mid));
  }
  return m;
}

Eigen::Vector3d Backproject(const PinholeCamera& camera, const cv::Point2f& uv, double z) {
  return camera.Unproject(Eigen::Vector2d(uv.x, uv.y), z);
}

}  // namespace

const char* FilterReasonName(FilterReason reason) {
  switch (reason) {
    case FilterReason::kKept:
      return "kept";
    case FilterReason::kMaskMotion:
      return "mask+motion";
    case FilterReason::kMotion:
      return "motion";
    case FilterReason::kMask:
      return "mask";
    case FilterReason::kLowScore:
      return "low-score";
    case FilterReason::kGround:
      return "ground";
    case FilterReason::kSky:
      return "sky";
    case FilterReason::kEdge:
      return "edge";
    case FilterReason::kVote:
      return "vote";
    case FilterReason::kCluster:
      return "cluster";
    case FilterReason::kGroundMotion:
      return "ground-motion";
  }
  return "unknown";
}

bool IsMovingReason(FilterReason reason) {
  return reason == FilterReason::kMaskMotion || reason == FilterReason::kMotion ||
         reason == FilterReason::kVote || reason == FilterReason::kCluster;
}

bool ScoreWeights::IsValid(std::string* why) const {
  if (!(mask >= 0.0 && motion >= 0.0 && ground >= 0.0 && edge >= 0.0)) {
    return Fail(why, "weights must be >= 0");
  }
  if (std::abs(mask + motion + ground + edge - 1.0) > 1e-6) {
    return Fail(why, "weights must sum to 1");
  }
  if (!(motion < 1.0)) return Fail(why, "the motion weight must leave room for other terms");
  return true;
}

bool ScoringOptions::IsValid(std::string* why) const {
  if (!weights.IsValid(why)) return false;
  if (!(exclude_below > 0.0 && exclude_below < 1.0)) return Fail(why, "exclude_below in (0, 1)");
  if (!(min_weight > 0.0f && min_weight <= 1.0f)) return Fail(why, "min_weight in (0, 1]");
  if (!(motion_evidence_below > 0.0 && motion_evidence_below < 1.0)) {
    return Fail(why, "motion_evidence_below in (0, 1)");
  }
  if (!(mask_evidence_below > 0.0 && mask_evidence_below < 1.0)) {
    return Fail(why, "mask_evidence_below in (0, 1)");
  }
  if (!(keep_masked_static_above > 0.5)) return Fail(why, "keep_masked_static_above must be > 0.5");
  return true;
}

bool InstanceMotionOptions::IsValid(std::string* why) const {
  if (min_evidence < 1) return Fail(why, "min_evidence must be >= 1");
  if (!(moving_below > 0.0 && moving_below < 1.0)) return Fail(why, "moving_below in (0, 1)");
  if (!(static_max_moving_fraction >= 0.0 && static_max_moving_fraction < moving_min_fraction &&
        moving_min_fraction <= 1.0)) {
    return Fail(why, "need 0 <= static_max_moving_fraction < moving_min_fraction <= 1");
  }
  if (!(informative_observability >= 0.0 && informative_observability <= 1.0)) {
    return Fail(why, "informative_observability in [0, 1]");
  }
  if (!(static_min_observability >= 0.0 && static_min_observability <= 1.0)) {
    return Fail(why, "static_min_observability in [0, 1]");
  }
  return true;
}

bool InstanceMemoryOptions::IsValid(std::string* why) const {
  if (!(min_iou > 0.0 && min_iou <= 1.0)) return Fail(why, "min_iou in (0, 1]");
  if (max_age_frames < 1) return Fail(why, "max_age_frames must be >= 1");
  return true;
}

int RecallInstanceVerdicts(std::span<const cv::Rect2f> boxes,
                           std::span<const std::string> class_names, int64_t frame_index,
                           const InstanceMemoryOptions& options,
                           std::vector<InstanceMotion>* summary,
                           std::vector<RememberedInstance>* memory) {
  if (class_names.size() != boxes.size() || summary->size() != boxes.size() + 1) {
    throw std::invalid_argument("RecallInstanceVerdicts: inputs of different sizes");
  }
  std::erase_if(*memory, [&](const RememberedInstance& r) {
    return frame_index - r.frame_index > options.max_age_frames || frame_index <= r.frame_index;
  });
  if (!options.enabled) {
    memory->clear();
    return 0;
  }
  auto iou = [](const cv::Rect2f& a, const cv::Rect2f& b) {
    const float inter = (a & b).area();
    const float uni = a.area() + b.area() - inter;
    return uni > 0.0f ? static_cast<double>(inter / uni) : 0.0;
  };
  // Each remembered entry matches at most one current instance (its best overlap).
  std::vector<int> best_of(boxes.size() + 1, -1);
  std::vector<double> best_iou(boxes.size() + 1, 0.0);
  std::vector<int> taken(memory->size(), 0);
  for (size_t k = 1; k <= boxes.size(); ++k) {
    const cv::Rect2f& box = boxes[k - 1];
    if (box.area() <= 0.0f) continue;
    for (size_t r = 0; r < memory->size(); ++r) {
      const RememberedInstance& m = (*memory)[r];
      if (m.class_name != class_names[k - 1]) continue;
      const double o = iou(box, m.box_px);
      if (o >= options.min_iou && o > best_iou[k]) {
        best_iou[k] = o;
        best_of[k] = static_cast<int>(r);
      }
    }
  }
  int adopted = 0;
  for (size_t k = 1; k <= boxes.size(); ++k) {
    if (best_of[k] < 0) continue;
    taken[best_of[k]] = 1;
    InstanceMotion& m = (*summary)[k];
    if (m.state != InstanceState::kUnknown) continue;
    const InstanceMotion& old = (*memory)[best_of[k]].motion;
    m.state = old.state;
    m.median_static_prob = old.median_static_prob;
    m.median_observability = old.median_observability;
    ++adopted;
  }
  std::vector<RememberedInstance> next;
  for (size_t r = 0; r < memory->size(); ++r) {
    if (!taken[r]) next.push_back((*memory)[r]);
  }
  for (size_t k = 1; k <= boxes.size(); ++k) {
    const InstanceMotion& m = (*summary)[k];
    if (boxes[k - 1].area() <= 0.0f || m.state == InstanceState::kUnknown) continue;
    next.push_back({boxes[k - 1], class_names[k - 1], m, frame_index});
  }
  *memory = std::move(next);
  return adopted;
}

bool MaskDepthOptions::IsValid(std::string* why) const {
  if (!(gate_rel >= 0.0 && gate_min_m > 0.0)) return Fail(why, "gate_rel >= 0, gate_min_m > 0");
  if (min_points < 1) return Fail(why, "min_points must be >= 1");
  if (!(box_margin_px >= 0.0)) return Fail(why, "box_margin_px must be >= 0");
  if (!(margin_min_confidence > 0.0f && margin_min_confidence <= 1.0f)) {
    return Fail(why, "margin_min_confidence must be in (0, 1]");
  }
  if (!(unresolved_margin_scale >= 0.0f && unresolved_margin_scale <= 1.0f &&
        ground_margin_scale >= 0.0f && ground_margin_scale <= 1.0f)) {
    return Fail(why, "margin scales must be in [0, 1]");
  }
  return true;
}

MaskMembership ResolveMaskMembership(std::span<const cv::Point2f> uv_px,
                                     std::span<const float> depth_m,
                                     std::span<const uint16_t> instance,
                                     std::span<const float> confidence,
                                     std::span<const cv::Rect2f> boxes,
                                     const MaskDepthOptions& options) {
  const size_t n = uv_px.size();
  if (depth_m.size() != n || instance.size() != n || confidence.size() != n) {
    throw std::invalid_argument("ResolveMaskMembership: inputs of different sizes");
  }
  MaskMembership out;
  out.instance.assign(instance.begin(), instance.end());
  out.depth_outlier.assign(n, 0);
  out.margin.assign(n, kNotMargin);
  if (!options.enabled || n == 0) return out;
  const size_t num = boxes.size();
  std::vector<std::vector<double>> depths(num + 1);
  for (size_t i = 0; i < n; ++i) {
    const size_t k = instance[i];
    if (k >= 1 && k <= num && depth_m[i] > 0.0f) depths[k].push_back(depth_m[i]);
  }
  std::vector<double> median(num + 1, -1.0);
  for (size_t k = 1; k <= num; ++k) {
    if (static_cast<int>(depths[k].size()) >= options.min_points) median[k] = Median(depths[k]);
  }
  auto gate = [&](size_t k) { return std::max(options.gate_min_m, options.gate_rel * median[k]); };
  const float m = static_cast<float>(options.box_margin_px);
  for (size_t i = 0; i < n; ++i) {
    const double z = depth_m[i];
    const size_t own = instance[i];
    if (own >= 1 && own <= num) {
      if (z > 0.0 && median[own] > 0.0 && std::abs(z - median[own]) > gate(own)) {
        out.instance[i] = 0;
        out.depth_outlier[i] = 1;
      }
      continue;
    }
    if (!(confidence[i] >= options.margin_min_confidence)) continue;
    int best = 0, first = 0;
    bool any_depth_model = false;
    double best_error = 0.0;
    for (size_t k = 1; k <= num; ++k) {
      const cv::Rect2f& b = boxes[k - 1];
      if (b.width <= 0.0f || b.height <= 0.0f) continue;
      const cv::Rect2f grown(b.x - m, b.y - m, b.width + 2 * m, b.height + 2 * m);
      if (!grown.contains(cv::Point2f(uv_px[i].x + 0.5f, uv_px[i].y + 0.5f))) continue;
      if (first == 0) first = static_cast<int>(k);
      if (!(z > 0.0) || median[k] <= 0.0) continue;
      any_depth_model = true;
      const double error = std::abs(z - median[k]);
      if (error <= gate(k) && (best == 0 || error < best_error)) {
        best = static_cast<int>(k);
        best_error = error;
      }
    }
    if (best > 0) {
      out.instance[i] = static_cast<uint16_t>(best);
      out.margin[i] = kMarginJoined;
    } else if (any_depth_model) {
      out.depth_outlier[i] = 1;
    } else if (first > 0) {
      out.margin[i] = kMarginUnresolved;
    }
  }
  return out;
}

bool ClusterOptions::IsValid(std::string* why) const {
  if (!(majority >= 0.0 && majority < 1.0)) return Fail(why, "majority in [0, 1)");
  if (!(weak_majority >= 0.0 && weak_majority < 1.0)) return Fail(why, "weak_majority in [0, 1)");
  if (min_excluded < 1) return Fail(why, "min_excluded must be >= 1");
  if (!(depth_gate_rel >= 0.0 && depth_gate_min_m >= 0.0)) return Fail(why, "depth gates >= 0");
  if (!(spatial_radius_m > 0.0 && spatial_radius_rel >= 0.0)) {
    return Fail(why, "spatial_radius_m > 0, spatial_radius_rel >= 0");
  }
  if (!(max_image_radius_px >= 1.0)) return Fail(why, "max_image_radius_px must be >= 1");
  if (spatial_min_neighbours < 1) return Fail(why, "spatial_min_neighbours must be >= 1");
  if (!(protect_static_above > 0.5 && protect_static_above <= 1.0)) {
    return Fail(why, "protect_static_above must be in (0.5, 1]");
  }
  return true;
}

double StaticScore(const PointTerms& terms, const ScoreWeights& weights) {
  double sum =
      weights.mask * terms.s_mask + weights.ground * terms.g_ground + weights.edge * terms.e_edge;
  double total = weights.mask + weights.ground + weights.edge;
  if (terms.has_motion) {
    sum += weights.motion * terms.m_motion;
    total += weights.motion;
  }
  return total > 0.0 ? std::clamp(sum / total, 0.0, 1.0) : 1.0;
}

FilterReason DecidePoint(const PointTerms& terms, double score, const ScoringOptions& options,
                         bool remove_ground) {
  if (terms.hard_edge) return FilterReason::kEdge;
  if (terms.sky) return FilterReason::kSky;
  if (remove_ground && terms.ground) return FilterReason::kGround;
  // Inside a dynamic mask with nothing to say it is static (no motion test, no instance verdict):
  // the mask decides, whatever the other (static-looking) terms say.
  // The first frame of a run has no motion evidence anywhere: the mask alone would cut every
  // parked car out of the initial map. Its points are kept (weighted by their score) and the
  // next frames decide.
  if (terms.first_frame && !terms.has_motion) return FilterReason::kKept;
  if (!terms.has_motion && terms.s_mask < options.mask_evidence_below) return FilterReason::kMask;
  if (score >= options.exclude_below) return FilterReason::kKept;
  const bool motion = terms.has_motion && terms.m_motion < options.motion_evidence_below;
  const bool mask = terms.s_mask < options.mask_evidence_below;
  // Motion that the point's own test did not see is its instance's: the reason says so rather
  // than claim the point's own motion evidence (the score is the same either way).
  if (motion && terms.motion_from_instance)
    return IsRoadPoint(terms, options) ? FilterReason::kGroundMotion : FilterReason::kCluster;
  if (motion && mask) return FilterReason::kMaskMotion;
  if (motion)
    return IsRoadPoint(terms, options) ? FilterReason::kGroundMotion : FilterReason::kMotion;
  if (mask && terms.has_motion && terms.own_static_prob >= options.keep_masked_static_above)
    return FilterReason::kKept;  // no motion seen, none the images could show: weighted
  if (mask) return FilterReason::kMask;
  return FilterReason::kLowScore;
}

bool IsRoadPoint(const PointTerms& terms, const ScoringOptions& options) {
  return options.ground_motion_unreliable && terms.ground &&
         terms.s_mask >= options.mask_evidence_below;
}

float WeightFromScore(double score, const ScoringOptions& options) {
  // Relative to an uninformed point (no mask, motion untested, not ground, not at the border:
  // score 1 - w_motion / 2): lack of evidence costs no weight, evidence against a point does.
  const double uninformed =
      options.weight_relative_to_uninformed ? 1.0 - 0.5 * options.weights.motion : 1.0;
  return std::clamp(static_cast<float>(score / uninformed), options.min_weight, 1.0f);
}

std::vector<InstanceMotion> SummarizeInstances(std::span<const uint16_t> instance,
                                               int num_instances, std::span<const uint8_t> observed,
                                               std::span<const float> static_prob,
                                               std::span<const float> observability,
                                               const InstanceMotionOptions& options) {
  const size_t n = instance.size();
  if (observed.size() != n || static_prob.size() != n || observability.size() != n) {
    throw std::invalid_argument("SummarizeInstances: inputs of different sizes");
  }
  std::vector<InstanceMotion> out(static_cast<size_t>(std::max(0, num_instances)) + 1);
  std::vector<std::vector<double>> probs(out.size()), obs(out.size());
  for (size_t i = 0; i < n; ++i) {
    const int k = instance[i];
    if (k <= 0 || k > num_instances) continue;
    ++out[k].num_points;
    if (!observed[i]) continue;
    ++out[k].num_observed;
    const bool moving = static_prob[i] < options.moving_below;
    if (moving) ++out[k].num_moving;
    if (moving || observability[i] >= options.informative_observability) ++out[k].num_informative;
    probs[k].push_back(static_prob[i]);
    obs[k].push_back(observability[i]);
  }
  for (size_t k = 1; k < out.size(); ++k) {
    InstanceMotion& m = out[k];
    if (m.num_observed == 0) continue;
    m.median_static_prob = Median(probs[k]);
    m.median_observability = Median(obs[k]);
    if (m.num_informative >= options.min_evidence &&
        m.num_moving >= options.moving_min_fraction * m.num_informative) {
      m.state = InstanceState::kMoving;
      continue;
    }
    if (m.num_observed < options.min_evidence) continue;
    const double moving_fraction = static_cast<double>(m.num_moving) / m.num_observed;
    if (moving_fraction <= options.static_max_moving_fraction &&
        m.median_observability >= options.static_min_observability) {
      m.state = InstanceState::kStatic;
    }
  }
  return out;
}

std::vector<uint8_t> ClusterExclusions(
    const PinholeCamera& camera, std::span<const cv::Point2f> uv_px, std::span<const float> depth_m,
    std::span<const uint16_t> instance, std::span<const uint8_t> seeds,
    std::span<const uint8_t> candidates, const ClusterOptions& options,
    std::span<const uint8_t> weak) {
  const size_t n = uv_px.size();
  if (depth_m.size() != n || seeds.size() != n || candidates.size() != n ||
      (!instance.empty() && instance.size() != n) || (!weak.empty() && weak.size() != n)) {
    throw std::invalid_argument("ClusterExclusions: inputs of different sizes");
  }
  auto majority_of = [&](size_t i) {
    return !weak.empty() && weak[i] ? std::min(options.majority, options.weak_majority)
                                    : options.majority;
  };
  std::vector<uint8_t> add(n, 0);
  if (n == 0) return add;

  if (options.use_instances && !instance.empty()) {
    const int max_id = *std::max_element(instance.begin(), instance.end());
    std::vector<int> total(max_id + 1, 0), excluded(max_id + 1, 0);
    std::vector<std::vector<double>> seed_depths(max_id + 1);
    for (size_t i = 0; i < n; ++i) {
      const int k = instance[i];
      if (k == 0) continue;
      ++total[k];
      if (seeds[i]) {
        ++excluded[k];
        if (depth_m[i] > 0.0f) seed_depths[k].push_back(depth_m[i]);
      }
    }
    std::vector<double> median_depth(max_id + 1, -1.0);
    for (int k = 1; k <= max_id; ++k) {
      if (!seed_depths[k].empty()) median_depth[k] = Median(seed_depths[k]);
    }
    for (size_t i = 0; i < n; ++i) {
      const int k = instance[i];
      if (k == 0 || !candidates[i]) continue;
      if (excluded[k] < options.min_excluded || !(excluded[k] > majority_of(i) * total[k])) {
        continue;
      }
      if (median_depth[k] > 0.0 && depth_m[i] > 0.0f) {
        const double gate =
            std::max(options.depth_gate_min_m, options.depth_gate_rel * median_depth[k]);
        if (std::abs(depth_m[i] - median_depth[k]) > gate) continue;
      }
      add[i] = 1;
    }
  }

  if (options.use_spatial) {
    // Image grid of the stereo points for the neighbourhood search.
    constexpr double kCellPx = 32.0;
    const int cols = std::max(1, static_cast<int>(std::ceil(camera.width_px / kCellPx)) + 1);
    const int rows = std::max(1, static_cast<int>(std::ceil(camera.height_px / kCellPx)) + 1);
    std::vector<std::vector<int>> grid(static_cast<size_t>(cols * rows));
    auto cell_of = [&](double u, double v, int* cu, int* cv) {
      *cu = std::clamp(static_cast<int>(std::floor(u / kCellPx)), 0, cols - 1);
      *cv = std::clamp(static_cast<int>(std::floor(v / kCellPx)), 0, rows - 1);
    };
    bool any_seed = false;
    for (size_t i = 0; i < n; ++i) {
      if (!(depth_m[i] > 0.0f)) continue;
      int cu, cv;
      cell_of(uv_px[i].x, uv_px[i].y, &cu, &cv);
      grid[cv * cols + cu].push_back(static_cast<int>(i));
      any_seed = any_seed || seeds[i];
    }
    if (any_seed) {
      for (size_t i = 0; i < n; ++i) {
        if (!candidates[i] || add[i] || !(depth_m[i] > 0.0f)) continue;
        const double z = depth_m[i];
        const double radius_m = options.spatial_radius_m + options.spatial_radius_rel * z;
        const double radius_px = std::min(options.max_image_radius_px, camera.fx * radius_m / z);
        const Eigen::Vector3d p = Backproject(camera, uv_px[i], z);
        int cu0, cv0, cu1, cv1;
        cell_of(uv_px[i].x - radius_px, uv_px[i].y - radius_px, &cu0, &cv0);
        cell_of(uv_px[i].x + radius_px, uv_px[i].y + radius_px, &cu1, &cv1);
        int neighbours = 0, excluded = 0;
        for (int cv = cv0; cv <= cv1; ++cv) {
          for (int cu = cu0; cu <= cu1; ++cu) {
            for (int j : grid[cv * cols + cu]) {
              if (static_cast<size_t>(j) == i) continue;
              const double du = uv_px[j].x - uv_px[i].x, dv = uv_px[j].y - uv_px[i].y;
              if (du * du + dv * dv > radius_px * radius_px) continue;
              const Eigen::Vector3d q = Backproject(camera, uv_px[j], depth_m[j]);
              if ((q - p).squaredNorm() > radius_m * radius_m) continue;
              ++neighbours;
              if (seeds[j]) ++excluded;
            }
          }
        }
        if (neighbours >= options.spatial_min_neighbours && excluded >= options.min_excluded &&
            excluded > majority_of(i) * neighbours) {
          add[i] = 1;
        }
      }
    }
  }
  return add;
}

}  // namespace pcr
