#pragma once
// The scoring/filter stage: joins a frame's stereo features with its segmentation result, picks
// the mask to apply (the frame's own, an older one carried forward and marked stale, or none),
// and asks a FrameScorer which keypoints to exclude and how to weight the rest.
// Stateful (the carried mask, and whatever a scorer keeps across frames, e.g. optical flow or
// temporal votes): thread-compatible, called once per frame in frame order.
#include <memory>
#include <string>

#include "nodes/messages.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/mask_propagation.h"

namespace pcr::nodes {

struct ScoringInput {
  const FrameTicket& ticket;
  const ImagesMsg& images;
  const OrbFeatures& left;
  const StereoMatches& stereo;
  const MaskMsg& mask;  // kSkipped: no mask for this frame
};

// A scorer's answer for one frame: per left keypoint, excluded flags and static-confidence
// weights (empty vectors: none), and the dynamic filter's whole output when it ran (for audits).
struct ScoredFrame {
  KeypointFilter filter;
  std::shared_ptr<const FilterOutput> details;
};

// The dynamic-point filter plugs in here (paper Eq. 2 / Alg. 3). Called in frame order.
class FrameScorer {
 public:
  virtual ~FrameScorer() = default;
  virtual ScoredFrame Score(const ScoringInput& input) = 0;
  virtual std::string Name() const = 0;
  // For scorers with work on a device (the dynamic filter's LK flow on a GPU): how Score() waits
  // for it (empty: block). Not to be called while Score() runs.
  virtual void SetDeviceWait(DeviceWait wait) { (void)wait; }
};

// The multi-stage dynamic-point filter (pcr::DynamicFilter: motion, ground, sky/edge, temporal
// votes, mask with depth check) as the pipeline's scorer. Keeps the filter's state across frames.
class DynamicFilterScorer final : public FrameScorer {
 public:
  DynamicFilterScorer(const StereoRig& rig, double scale_factor,
                      const DynamicFilterOptions& options = {});
  ScoredFrame Score(const ScoringInput& input) override;
  std::string Name() const override { return "dynamic-filter"; }
  void SetDeviceWait(DeviceWait wait) override { filter_.SetDeviceWait(std::move(wait)); }
  // Where the filter's LK flow runs (FlowEngine::Name).
  std::string FlowEngineName() const { return filter_.flow_engine().Name(); }
  // Keypoints of the last scored frame that the filter's LK flow tracked into the previous
  // image (0 when the frame's quality settings switched the flow off).
  int last_tracked() const { return last_tracked_; }

 private:
  StereoRig rig_;
  double scale_factor_;
  DynamicFilter filter_;
  int last_tracked_ = 0;
};

struct MaskScorerOptions {
  float exclude_threshold = 0.5f;  // dynamic confidence at which a keypoint is excluded
  bool weights = true;             // also weight kept keypoints by 1 - dynamic confidence
  bool IsValid(std::string* why) const;
};

// The segmentation-only scorer: samples the mask's dynamic-confidence map at each keypoint
// (nearest pixel, as SlamSystem::SampleFilter does). Nothing is filtered without a mask.
class MaskScorer final : public FrameScorer {
 public:
  explicit MaskScorer(const MaskScorerOptions& options = {});
  ScoredFrame Score(const ScoringInput& input) override;
  std::string Name() const override { return "mask"; }

 private:
  MaskScorerOptions options_;
};

struct MaskCarryOptions {
  bool use_stale = true;   // carry an older frame's mask forward when a frame has none
  int max_age_frames = 5;  // ... if it is at most this many frames (seq) older
  // ... moved by its objects' motion (when the frame's quality settings allow it and the mask
  // kept its image), else as it was (marked stale: the filter scales its confidence down).
  bool propagate = true;
  MaskPropagationOptions propagation;
  bool IsValid(std::string* why) const;
};

// Chooses the mask of each frame, in frame order: a fresh segmentation is used and remembered;
// otherwise the mask of the newest earlier computation among the message's fallback and the last
// one seen here (within max_age_frames) is moved onto this frame (kPropagated; from the previous
// frame's propagated copy when that is the newest, so each step is one frame of motion) or used as
// it was (kStale); else kSkipped.
class MaskCarry {
 public:
  explicit MaskCarry(const MaskCarryOptions& options = {});
  // grey: this frame's left image (CV_8UC1; empty: no propagation).
  MaskMsg Resolve(const SegmentationMsg& msg, const cv::Mat& grey = {});

 private:
  MaskCarryOptions options_;
  std::shared_ptr<const Segmentation> last_;  // fresh, or propagated onto the previous frame
  int64_t last_source_seq_ = -1;              // the frame last_ was computed on
  int last_steps_ = 0;
};

class FilterNode {
 public:
  // scorer may be null (not owned): no keypoint is filtered, as when SLAM runs without a filter.
  FilterNode(FrameScorer* scorer, const MaskCarryOptions& carry);
  // Throws std::invalid_argument when the two messages belong to different frames, and when the
  // scorer's vectors do not match the keypoint count.
  FilteredPtr operator()(const StereoPtr& stereo, const SegmentationPtr& segmentation);

 private:
  FrameScorer* scorer_;
  MaskCarry carry_;
};

}  // namespace pcr::nodes
