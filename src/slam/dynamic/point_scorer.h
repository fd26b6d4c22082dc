#pragma once
// The per-keypoint static-confidence score (paper Eq. 2) and the decisions built on it:
//   score = w1 S_mask + w2 M_motion + w3 G_ground + w4 E_edge,  every term in [0, 1], 1 = static,
// renormalised over the available terms when there is no motion observation (so an unobserved
// point is neither punished nor confirmed by the motion term). A keypoint is excluded when its
// score is below a threshold, or outright at the image border or in the sky; the decision
// carries the reason. Instance-level motion summaries give the reverse protection (a dynamic-class
// instance whose observed points show no motion confirms its unobserved points as static: a
// parked car) and cluster filtering extends motion-based exclusions to the rest of an instance,
// or of a 3-D neighbourhood, when most of it is excluded.
//
// Default weights put the motion term first: with S_mask = 0 (dynamic-class mask) a point is kept
// only with confirmed static motion (M >= 0.7), and without any mask a point is excluded only on
// clear motion evidence (M < 0.3). Pure functions; thread-compatible.
#include <cstdint>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "slam/common/camera.h"

namespace pcr {

enum class FilterReason : uint8_t {
  kKept = 0,
  kMaskMotion,  // low score with dynamic-class mask and motion evidence
  kMotion,      // low score on motion evidence alone (no mask)
  kMask,        // low score with a dynamic-class mask and no confirmation of static motion
  kLowScore,    // low score otherwise (e.g. ground plus border)
  kGround,      // ground point with GroundOptions::remove_ground
  kSky,
  kEdge,  // within the outermost border pixels
  kVote,  // temporal vote for motion (kept by this frame's score)
  // Same instance / 3-D cluster as a majority of motion-excluded points, or a point whose motion
  // term is its moving instance's verdict (PointTerms::motion_from_instance): its own motion test
  // saw no motion (none, or blind), so the motion is the instance's, not the point's.
  kCluster,
  // Motion evidence (own test, vote or cluster) on a road point outside every dynamic-class mask:
  // the road does not move, so what moves there is a shadow, a reflection or a track slipping on
  // road texture. Excluded as unreliable; not a moving object and no cluster seed.
  kGroundMotion,
};
inline constexpr int kNumFilterReasons = 11;

const char* FilterReasonName(FilterReason reason);
// Reasons that mean "on a moving object": kMaskMotion, kMotion, kVote, kCluster.
bool IsMovingReason(FilterReason reason);

struct ScoreWeights {
  double mask = 0.2;                     // w1 S_mask
  double motion = 0.5;                   // w2 M_motion
  double ground = 0.15;                  // w3 G_ground
  double edge = 0.15;                    // w4 E_edge
  bool IsValid(std::string* why) const;  // non-negative, sum 1
};

struct ScoringOptions {
  ScoreWeights weights;
  double exclude_below = 0.65;  // scores below this exclude the keypoint
  float min_weight = 0.05f;     // optimiser weight = max(score / uninformed, min_weight)
  // The weight is the score relative to that of an uninformed point (1 - w_motion / 2): an
  // untested motion term does not down-weight far points (the rotation's best constraints).
  // false: the weight is the score itself.
  bool weight_relative_to_uninformed = true;
  double motion_evidence_below = 0.5;  // M_motion below: the reason names motion
  double mask_evidence_below = 0.5;    // S_mask below: the reason names the mask
  // A masked point whose motion test saw no motion (P(static) before the observability gate at
  // least this) but could not have seen a car driving along the travel direction (far ahead, no
  // depth) is kept, weighted by its score: a motion that the images cannot show biases the pose
  // no more than the test's noise, and far points are the rotation's best constraints. > 1: off
  // (the mask decides).
  double keep_masked_static_above = 0.9;
  // Motion on a road point (ground, no mask evidence) gives kGroundMotion rather than kMotion,
  // kVote or kCluster. false: it is a moving object like any other.
  bool ground_motion_unreliable = true;
  bool IsValid(std::string* why) const;
};

struct PointTerms {
  double s_mask = 1.0;           // 1 - dynamic confidence at the keypoint
  double m_motion = 0.5;         // static probability, gated by observability
  double own_static_prob = 0.5;  // the same before the gate (has_motion only)
  bool has_motion = false;       // m_motion comes from an observation (this frame or the window)
  // m_motion and own_static_prob are the instance's verdict, not the point's own evidence (the
  // point has no observation, or its own test could not have seen a motion).
  bool motion_from_instance = false;
  double g_ground = 1.0;
  double e_edge = 1.0;     // 0 for sky points
  bool hard_edge = false;  // within EdgeOptions::exclude_within_px
  bool sky = false;
  bool ground = false;
  bool first_frame = false;  // no previous frame: no motion evidence anywhere yet
};

// A ground point without mask evidence, when ScoringOptions::ground_motion_unreliable.
bool IsRoadPoint(const PointTerms& terms, const ScoringOptions& options);

// Eq. 2, renormalised over the terms present (the motion term only when has_motion).
double StaticScore(const PointTerms& terms, const ScoreWeights& weights);
// The decision for one keypoint from its terms and score (remove_ground: GroundOptions').
FilterReason DecidePoint(const PointTerms& terms, double score, const ScoringOptions& options,
                         bool remove_ground);
// Weight for the optimiser, in (0, 1].
float WeightFromScore(double score, const ScoringOptions& options);

struct InstanceMotionOptions {
  int min_evidence = 4;                     // observed points needed for a verdict
  double moving_below = 0.5;                // a point's static probability below: moving
  double static_max_moving_fraction = 0.2;  // static: at most this fraction moving ...
  double static_min_observability = 0.5;    // ... and median observability at least this
  double moving_min_fraction = 0.5;         // moving: at least this fraction moving ...
  // ... of the informative points: those whose test shows motion or had at least this
  // observability (a blind test that sees no motion says nothing; counted, it would outvote the
  // points that can see the object move). 0: every observed point.
  double informative_observability = 0.3;
  bool IsValid(std::string* why) const;
};

enum class InstanceState : uint8_t { kUnknown, kStatic, kMoving };

struct InstanceMotion {
  int num_points = 0;
  int num_observed = 0;
  int num_moving = 0;
  int num_informative = 0;  // observed and moving, or observability >= informative_observability
  double median_static_prob = 0.5;
  double median_observability = 0.0;
  InstanceState state = InstanceState::kUnknown;
};

// One summary per instance id 1..num_instances (index 0 unused). instance[i]: the keypoint's
// instance id (0 = none); observed[i] != 0 when static_prob[i] / observability[i] come from an
// observation. All spans of one size, else std::invalid_argument.
std::vector<InstanceMotion> SummarizeInstances(std::span<const uint16_t> instance,
                                               int num_instances, std::span<const uint8_t> observed,
                                               std::span<const float> static_prob,
                                               std::span<const float> observability,
                                               const InstanceMotionOptions& options);

// Instance memory: an instance without a verdict of its own this frame (occluded last frame, no
// tracks yet, too far to test) takes the verdict of the remembered instance of its class whose
// box overlaps its own most (IoU >= min_iou), remembered at most max_age_frames ago.
struct InstanceMemoryOptions {
  bool enabled = true;
  double min_iou = 0.3;
  int max_age_frames = 10;
  bool IsValid(std::string* why) const;
};

struct RememberedInstance {
  cv::Rect2f box_px;
  std::string class_name;
  InstanceMotion motion;  // the verdict (state != kUnknown) and its medians
  int64_t frame_index = 0;
};

// summary: SummarizeInstances' result (index k for instance k = 1..boxes.size()); boxes[k - 1] and
// class_names[k - 1] of instance k (an empty box: not a dynamic-class instance). Adopts
// remembered verdicts into the unknown entries of summary, then updates memory with this frame's
// verdicts and forgets the entries older than max_age_frames. Returns the number adopted.
int RecallInstanceVerdicts(std::span<const cv::Rect2f> boxes,
                           std::span<const std::string> class_names, int64_t frame_index,
                           const InstanceMemoryOptions& options,
                           std::vector<InstanceMotion>* summary,
                           std::vector<RememberedInstance>* memory);

// Mask depth consistency: a keypoint inside a dynamic-class mask, or in the dilated margin around
// one, whose stereo depth is far (either way) from that instance's median depth is background
// seen through the mask or an occluder in front of it: its mask does not apply.
struct MaskDepthOptions {
  bool enabled = true;
  double gate_rel = 0.3;  // consistent within max(gate_min_m, gate_rel * median depth)
  double gate_min_m = 3.0;
  int min_points = 5;                  // instance points with depth needed for a median
  double box_margin_px = 15.0;         // margin points: within the instance box grown by this ...
  float margin_min_confidence = 0.2f;  // ... and at least this dynamic confidence
  // Dynamic confidence kept by an unresolved margin point (no depth to tell object from
  // background), and by a depth-joined margin point that lies on the ground plane (the road
  // beside a car's wheels is at the car's depth).
  float unresolved_margin_scale = 0.5f;
  float ground_margin_scale = 0.0f;
  bool IsValid(std::string* why) const;
};

// MaskMembership::margin values.
enum MarginKind : uint8_t {
  kNotMargin = 0,
  kMarginJoined = 1,      // in the dilated margin, joined an instance by its depth
  kMarginUnresolved = 2,  // in the margin, no depth to decide with
};

struct MaskMembership {
  std::vector<uint16_t> instance;      // per keypoint: dynamic-class instance id, 0: none
  std::vector<uint8_t> depth_outlier;  // per keypoint: the mask does not apply (depth)
  std::vector<uint8_t> margin;         // per keypoint: a MarginKind
};

// Instance membership of the keypoints under MaskDepthOptions. instance[i]: the dynamic-class
// instance under the keypoint (0: none); confidence[i]: the sampled dynamic confidence (high in
// the dilated margin too); boxes[k - 1]: box of instance k (an empty box for instances that are not
// of a dynamic class). A keypoint on an instance whose depth is inconsistent with it becomes an
// outlier (instance 0); a margin keypoint (confidence >= margin_min_confidence, no instance) joins
// the instance whose grown box holds it and whose depth it matches (the nearest median depth)
// (margin 1), stays unresolved without depth (margin 2: no instance), and is an outlier when it has
// a depth that matches none of them. Spans of one size (boxes aside), else std::invalid_argument.
MaskMembership ResolveMaskMembership(std::span<const cv::Point2f> uv_px,
                                     std::span<const float> depth_m,
                                     std::span<const uint16_t> instance,
                                     std::span<const float> confidence,
                                     std::span<const cv::Rect2f> boxes,
                                     const MaskDepthOptions& options);

struct ClusterOptions {
  bool use_instances = true;   // segmentation instances as clusters
  bool use_spatial = true;     // 3-D neighbourhoods of stereo points
  double majority = 0.5;       // excluded fraction (strictly above) that takes the cluster
  double weak_majority = 0.3;  // ... for a candidate with weak motion evidence of its own
  int min_excluded = 3;        // and at least this many excluded points
  // Instance clusters: a candidate joins only at a depth within max(depth_gate_min_m,
  // depth_gate_rel * z) of the excluded points' median (background seen through a mask stays).
  double depth_gate_rel = 0.2;
  double depth_gate_min_m = 1.5;
  // Spatial clusters: neighbours within spatial_radius_m + spatial_radius_rel * z in 3-D (image
  // search radius capped at max_image_radius_px), at least spatial_min_neighbours of them.
  double spatial_radius_m = 1.0;
  double spatial_radius_rel = 0.05;
  double max_image_radius_px = 60.0;
  int spatial_min_neighbours = 4;
  // Used by DynamicFilter: a point whose own (gated) static probability reaches this is not
  // taken by a cluster (its own evidence beats its neighbours').
  double protect_static_above = 0.8;
  bool IsValid(std::string* why) const;
};

// Cluster filtering (paper Alg. 3, ClusterFiltering): flags (non-zero) of the candidates that
// join the exclusion. seeds: points excluded on motion evidence; candidates: points that may
// join. weak (may be empty): candidates with weak motion evidence of their own (static
// probability below 0.5 but not low enough to exclude them alone), which join at weak_majority.
// instance may be empty (no segmentation). depth_m <= 0: no depth. All non-empty spans of one
// size, else std::invalid_argument.
std::vector<uint8_t> ClusterExclusions(
    const PinholeCamera& camera, std::span<const cv::Point2f> uv_px, std::span<const float> depth_m,
    std::span<const uint16_t> instance, std::span<const uint8_t> seeds,
    std::span<const uint8_t> candidates, const ClusterOptions& options,
    std::span<const uint8_t> weak = {});

}  // namespace pcr
