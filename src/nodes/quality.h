#pragma once
// Adaptive quality control (paper Eq. 9): the processing parameters of a frame come from one of
// three levels, and a controller picks the level from the time still available per frame:
//   Q_high   if T_available > T_threshold
//   Q_medium if T_available > 0.5 * T_threshold
//   Q_low    otherwise,
// with T_available = frame period - measured busy time per frame, smoothed, plus a hysteresis
// band and a dwell time so the level does not flap. Pure and thread-compatible.
#include <array>
#include <string>

namespace pcr::nodes {

enum class QualityLevel { kLow = 0, kMedium = 1, kHigh = 2 };
inline constexpr int kNumQualityLevels = 3;
const char* ToString(QualityLevel level);
// "low", "medium", "high" (case-sensitive); false for anything else.
bool ParseQualityLevel(const std::string& text, QualityLevel* level);

// Which network the segmentation branch runs (the pipeline holds one segmenter per slot; a slot
// without a segmenter falls back to the other).
// kLight: a cheaper export (a smaller input, e.g. 160x512 made by tools/yolo_resize.py) that the
// low level can afford on every frame; without one the low level uses the fast network on every
// inference_every-th frame.
enum class SegmenterSlot { kAccurate = 0, kFast = 1, kLight = 2 };

struct QualitySettings {
  int orb_features = 2000;  // keypoints per image
  SegmenterSlot segmenter = SegmenterSlot::kFast;
  int inference_every = 1;     // segment every n-th frame at this level (>= 1)
  bool optical_flow = true;    // LK flow in the dynamic filter (its scorer)
  int ba_max_iterations = 10;  // cap of local BA iterations for keyframes made at this level
  // Keyframes at most this often at this level (seconds; 0: as the SLAM options decide), unless
  // tracking is weak: local mapping holds the map token, so a burst of keyframes (one per frame,
  // 55-160 ms of mapping each on drive 0005) delays every frame behind it.
  double min_keyframe_interval_s = 0;
  // Frames without a fresh mask carry the newest one along by its objects' motion (else they
  // use it where it was, as a stale mask).
  bool propagate_masks = true;
  // Realtime: how long tracking waits, once the frame's features are ready, for the frame's own
  // mask (< 0: PipelineOptions::mask_deadline_ms).
  double mask_wait_ms = -1;
  bool IsValid(std::string* why) const;
  bool operator==(const QualitySettings&) const = default;
};

// The three levels, defaults as in the issue: High = YOLO 384x1280 every frame, 2000 features,
// LK flow on; Medium = YOLO 224x640; Low = the light network (when there is one; on every frame,
// see PipelineOptions::levels) or the fast one on every second frame, 1200 features, LK flow on
// (with an 11 px window the filter stage costs 25-50 ms a frame in the pipeline on 2 cores;
// without it the filter cannot tell parked from moving cars in a mask), fewer BA iterations, at
// most 5 keyframes a second. Frames without a fresh mask carry the newest one along by its
// objects' motion at every level.
struct QualityLevels {
  QualitySettings high{2000, SegmenterSlot::kAccurate, 1, true, 10};
  QualitySettings medium{2000, SegmenterSlot::kFast, 1, true, 10};
  QualitySettings low{1200, SegmenterSlot::kLight, 2, true, 5, 0.2};
  const QualitySettings& At(QualityLevel level) const;
  bool IsValid(std::string* why) const;
};

struct QualityControllerOptions {
  // T_threshold as a fraction of the frame period.
  double threshold_fraction = 0.3;
  // Half-width of the band around each boundary, as a fraction of T_threshold: moving up needs
  // T_available above the boundary plus the band, moving down below it minus the band.
  double hysteresis_fraction = 0.15;
  // Frames spent at a level before the controller may move up again (moving down is immediate:
  // a late frame costs more than a lower quality).
  int min_dwell_frames = 5;
  // Weight of the newest sample in the exponential moving average of the busy time (1 = none).
  double smoothing = 0.3;
  // The first frames' level. Medium (the fast network) rather than high: realtime frames before
  // the first mask wait for their own, and on the high level's 384x1280 network that wait made
  // a run's worst latencies (drive 0005, realtime+adaptive on 2 cores with onednn: p99 to the
  // pose 173-362 ms starting high, 123 ms starting medium, both at 97-100% fresh masks). The
  // controller still moves up when the budget allows.
  QualityLevel initial = QualityLevel::kMedium;
  bool IsValid(std::string* why) const;
};

class QualityController {
 public:
  // Throws ConfigError when options are invalid.
  explicit QualityController(const QualityControllerOptions& options = {});

  // Eq. 9 without hysteresis.
  static QualityLevel Classify(double available_ms, double threshold_ms);

  // One finished frame: the frame period and the time the frame kept the pipeline busy
  // (max(T_slam, T_inference) + T_sync, milliseconds). Returns the level for the next frames.
  QualityLevel Update(double period_ms, double busy_ms);

  QualityLevel level() const { return level_; }
  double available_ms() const { return available_ms_; }  // after smoothing, last update
  double threshold_ms() const { return threshold_ms_; }  // last update
  int changes() const { return changes_; }
  int frames_at_level() const { return frames_at_level_; }
  const QualityControllerOptions& options() const { return options_; }

 private:
  QualityControllerOptions options_;
  QualityLevel level_;
  bool has_average_ = false;
  double busy_average_ms_ = 0;
  double available_ms_ = 0;
  double threshold_ms_ = 0;
  int changes_ = 0;
  int frames_at_level_ = 0;
};

}  // namespace pcr::nodes
