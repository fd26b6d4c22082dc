#pragma once
// Messages exchanged by the pipeline stages. Each is immutable once sent
// (std::shared_ptr<const T>) and stamped with the frame's ticket: `seq` is the admission order
// (0, 1, 2, ... without gaps, the key of joins and sequencers), `frame_index` the dataset frame.
// Every branch emits one message per admitted frame; "nothing to say" is a value (a skipped or
// stale mask), so a join never waits for a message that will not come.
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "nodes/quality.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/segmenter.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/stereo_matcher.h"
#include "slam/map/frame.h"
#include "slam/system/slam_system.h"
#include "slam/tracking/keyframe_decision.h"
#include "slam/tracking/tracker.h"

namespace pcr::nodes {

// Identity and per-frame decisions of one admitted frame, fixed by the source.
struct FrameTicket {
  int64_t seq = -1;          // admission order, contiguous from 0
  int64_t frame_index = -1;  // dataset frame
  int64_t t_ns = 0;          // capture timestamp (dataset clock)
  QualityLevel quality = QualityLevel::kHigh;
  QualitySettings settings;   // what the stages use for this frame
  bool run_inference = true;  // false: the segmentation branch emits "not run" for this frame
};

struct ImagesMsg {
  FrameTicket ticket;
  cv::Mat left, right;  // CV_8UC1 rectified pair (monocular runs: right is empty)
  // CV_8UC3 BGR left image, for the segmenter: set when the source has colour images and the
  // frame is segmented (empty otherwise: the segmenter then gets the grey image).
  cv::Mat left_color;
  double load_ms = 0;
};

enum class Side { kLeft, kRight };

struct FeaturesMsg {
  FrameTicket ticket;
  Side side = Side::kLeft;
  std::shared_ptr<const ImagesMsg> images;
  OrbFeatures features;
  double extract_ms = 0;
};

struct StereoMsg {
  FrameTicket ticket;
  std::shared_ptr<const ImagesMsg> images;
  std::shared_ptr<const FeaturesMsg> left;
  StereoMatches stereo;
  double orb_right_ms = 0;  // extraction time of the right features (not kept)
  double match_ms = 0;
};

// What the segmentation branch says about one frame.
enum class SegmentationOutcome {
  kFresh,         // this frame's segmentation
  kNoSegmenter,   // the pipeline runs without a segmenter
  kNotScheduled,  // the quality level skips inference on this frame
  kBusy,          // realtime: the network was busy with an older frame
  kLate,          // realtime: not ready by the mask deadline
};
const char* ToString(SegmentationOutcome outcome);

struct SegmentationMsg {
  FrameTicket ticket;
  SegmentationOutcome outcome = SegmentationOutcome::kNoSegmenter;
  std::shared_ptr<const Segmentation> segmentation;  // set when kFresh
  // When not kFresh: the newest segmentation of an earlier frame known to whoever emitted the
  // message (may be null), and that frame's seq.
  std::shared_ptr<const Segmentation> fallback;
  int64_t fallback_seq = -1;
  std::string model;  // segmenter that ran (kFresh)
  double segment_ms = 0;
};

// The mask the filter applied to a frame.
// kPropagated: an earlier mask moved onto this frame by its objects' motion
// (slam/dynamic/mask_propagation.h); kStale: an earlier mask as it was.
enum class MaskStatus { kFresh, kPropagated, kStale, kSkipped };
const char* ToString(MaskStatus status);

struct MaskMsg {
  MaskStatus status = MaskStatus::kSkipped;
  std::shared_ptr<const Segmentation> segmentation;  // null when kSkipped
  int64_t source_seq = -1;                           // frame the mask was computed on
  int propagation_steps = 0;  // kPropagated: frames it was carried through since source_seq
  double propagate_ms = 0;    // time spent moving it onto this frame
};

// What the dynamic filter decided for one frame, kept with the frame's record for audits
// (confusion against ground truth, per-keypoint dumps): the keypoints the decisions refer to,
// their stereo depth and the filter's whole output.
struct FilterReport {
  std::vector<cv::KeyPoint> keypoints;         // left keypoints, index = FilterOutput::points index
  std::vector<float> depth_m;                  // per keypoint (<= 0: none); empty in monocular runs
  std::vector<uint8_t> grey;                   // per keypoint: the left image's grey level there
  std::shared_ptr<const FilterOutput> output;  // never null
};
using FilterReportPtr = std::shared_ptr<const FilterReport>;

struct FilteredMsg {
  FrameTicket ticket;
  std::shared_ptr<const StereoMsg> stereo;
  SegmentationOutcome segmentation = SegmentationOutcome::kNoSegmenter;  // what the branch said
  MaskMsg mask;
  KeypointFilter filter;   // empty vectors: nothing excluded, unit weights
  FilterReportPtr report;  // set when the scorer is the dynamic filter
  int num_excluded = 0;
  double filter_ms = 0;
};

struct TrackedMsg {
  FrameTicket ticket;
  std::shared_ptr<const FilteredMsg> filtered;
  FramePtr frame;
  TrackingResult tracking;
  KeyframeDecision keyframe;  // whether local mapping inserts this frame
  FrameOutput output;         // filled up to tracking (times_ms.orb_*, stereo, tracking)
};

struct FrameResultMsg {
  FrameTicket ticket;
  SegmentationOutcome segmentation = SegmentationOutcome::kNoSegmenter;
  MaskStatus mask = MaskStatus::kSkipped;
  int64_t mask_source_seq = -1;  // the frame the mask was computed on (-1: none)
  double propagate_ms = 0;       // kPropagated: time spent moving it onto this frame
  int num_excluded = 0;
  double filter_ms = 0;
  FilterReportPtr filter_report;  // the filter's decisions (null without the dynamic filter)
  FrameOutput output;             // complete, as SlamSystem::ProcessFrame would return it
};

using ImagesPtr = std::shared_ptr<const ImagesMsg>;
using FeaturesPtr = std::shared_ptr<const FeaturesMsg>;
using StereoPtr = std::shared_ptr<const StereoMsg>;
using SegmentationPtr = std::shared_ptr<const SegmentationMsg>;
using FilteredPtr = std::shared_ptr<const FilteredMsg>;
using TrackedPtr = std::shared_ptr<const TrackedMsg>;
using FrameResultPtr = std::shared_ptr<const FrameResultMsg>;

}  // namespace pcr::nodes
