#pragma once
// Instance segmentation interface used by the dynamic-point filter, and the per-class policy
// that says which classes count as dynamic and how hard their pixels are filtered.
// Pixel quantities refer to the image handed to Segment(): x right, y down. Masks and maps are
// indexed by pixel, mat.at(v, u), the same pixel (u, v) as a keypoint at integer (u, v) in the
// camera convention (slam/common/camera.h). Boxes (box_px) use continuous corner coordinates as
// detectors do: pixel (u, v) covers [u, u+1) x [v, v+1), so a camera-convention point (x, y) lies
// in a box when (x + 0.5, y + 0.5) does.
#include <cmath>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <set>
#include <string>
#include <vector>

namespace pcr {

// One detected object.
struct Instance {
  int class_id = -1;        // index into the segmenter's class names (COCO ids by default)
  std::string class_name;   // e.g. "car"
  float confidence = 0.0f;  // detector score in [0, 1]
  cv::Rect2f box_px;        // image pixels, clipped to the image
  cv::Mat mask;             // CV_8U 0/255, full image size; non-zero only inside box_px
                            // (released in pipeline messages: see nodes/segment_node.h)
  int instance_id = -1;     // index of this instance in Segmentation::instances of its frame
};

struct Segmentation {
  std::vector<Instance> instances;  // sorted by decreasing confidence
  // CV_32F in [0, 1], full image size: per-pixel confidence that the pixel belongs to an object
  // of a dynamic class, after per-policy dilation and Gaussian smoothing (the paper's Alg. 2).
  cv::Mat dynamic_confidence;
  // CV_16U, full image size: 0 = no instance, k = instances[k - 1]. Where masks overlap the
  // more confident instance wins.
  cv::Mat instance_map;
  bool stale = false;  // true when an asynchronous wrapper re-used an older frame's result
  // CV_8UC1: the grey image the maps describe, when whoever made them kept it (the pipeline does,
  // so that a mask can be carried to later frames by their motion; mask_propagation.h).
  cv::Mat source_grey;
  std::string backend;  // e.g. "opencv-dnn-cpu"
};

// How work handed to a device (a GPU) is waited for. wait(launch) calls launch(done) once;
// launch queues the device work and returns, and done() is called exactly once, from any thread,
// when the work has finished (or failed); wait returns after that, possibly on another thread
// than it was called on. Nothing may be touched by launch after it has arranged for done() to be
// called; launch may throw only before that, and the exception comes out of wait. A scheduler
// installs one that frees the calling thread for other work meanwhile (the
// flow graph: a TBB task suspension); without one, a device engine blocks its caller.
using DeviceDone = std::function<void()>;
using DeviceWait = std::function<void(const std::function<void(const DeviceDone&)>& launch)>;

// Thread-compatible: one caller at a time (Segment() may keep inference state).
class Segmenter {
 public:
  virtual ~Segmenter() = default;
  // image: grey CV_8UC1 or BGR CV_8UC3. Throws std::invalid_argument on anything else.
  virtual Segmentation Segment(const cv::Mat& image) = 0;
  // The same for a known frame of a sequence (frame_index: the dataset's frame). Segmenters that
  // look at the image alone ignore the index; ground-truth segmenters use it.
  virtual Segmentation SegmentFrame(int64_t frame_index, const cv::Mat& image) {
    (void)frame_index;
    return Segment(image);
  }
  virtual std::string Name() const = 0;
  // For segmenters that run on a device: how Segment() waits for it (empty: block). Segmenters
  // that compute on the calling thread ignore it. Not to be called while Segment() runs.
  virtual void SetDeviceWait(DeviceWait wait) { (void)wait; }
};

// How hard the pixels of a dynamic class are filtered (paper section 3.3.1, multi-class
// handling): fast movers (vehicles, cyclists) aggressively, slow movers (pedestrians, animals)
// conservatively, so that a medium-confidence pedestrian is left to geometric checks.
enum class DynamicPolicy { kAggressive, kConservative };

struct DynamicClass {
  std::string name;  // class name as the model names it (COCO: "person", "car", ...)
  DynamicPolicy policy = DynamicPolicy::kAggressive;
};

struct DynamicPolicyParams {
  double dilation_scale = 1.0;   // multiplies the segmenter's dilation radius (pixels), >= 0
  float confidence_scale = 1.0;  // multiplies the detector confidence, in (0, 1]
  // Speed the motion test must be able to see before it may call an object of this class static
  // (observability, see MotionScoreOptions::reference_speed_mps); 0: the filter's default.
  double reference_speed_mps = 0.0;
};

inline std::vector<DynamicClass> DefaultDynamicClasses() {
  using P = DynamicPolicy;
  return {
      {"person", P::kConservative},   {"bicycle", P::kAggressive},    {"car", P::kAggressive},
      {"motorcycle", P::kAggressive}, {"bus", P::kAggressive},        {"train", P::kAggressive},
      {"truck", P::kAggressive},      {"bird", P::kConservative},     {"cat", P::kConservative},
      {"dog", P::kConservative},      {"horse", P::kConservative},    {"sheep", P::kConservative},
      {"cow", P::kConservative},      {"elephant", P::kConservative}, {"bear", P::kConservative},
      {"zebra", P::kConservative},    {"giraffe", P::kConservative}};
}

struct DynamicClassPolicy {
  std::vector<DynamicClass> classes = DefaultDynamicClasses();
  // Aggressive: a wider margin (motion blur, mask edges lagging a fast object) at full confidence.
  DynamicPolicyParams aggressive{1.4, 1.0f, 0.0};
  // Conservative: a tighter margin and a reduced confidence; a person or an animal is called
  // static only where the test would see a walking pace.
  DynamicPolicyParams conservative{0.6, 0.8f, 1.2};

  // The class entry with this name, or nullptr when the class is static.
  const DynamicClass* Find(const std::string& name) const {
    for (const DynamicClass& c : classes) {
      if (c.name == name) return &c;
    }
    return nullptr;
  }
  const DynamicPolicyParams& Params(DynamicPolicy policy) const {
    return policy == DynamicPolicy::kAggressive ? aggressive : conservative;
  }

  bool IsValid(std::string* why) const {
    auto fail = [why](const std::string& message) {
      if (why) *why = message;
      return false;
    };
    std::set<std::string> seen;
    for (const DynamicClass& c : classes) {
      if (c.name.empty()) return fail("DynamicClassPolicy: empty class name");
      if (!seen.insert(c.name).second) return fail("DynamicClassPolicy: duplicate " + c.name);
    }
    for (const DynamicPolicyParams* p : {&aggressive, &conservative}) {
      const char* which = p == &aggressive ? "aggressive" : "conservative";
      if (!std::isfinite(p->dilation_scale) || p->dilation_scale < 0.0 ||
          p->dilation_scale > 100.0) {
        return fail(std::string("DynamicClassPolicy: ") + which +
                    ".dilation_scale must be in [0, 100]");
      }
      if (!(p->confidence_scale > 0.0f && p->confidence_scale <= 1.0f)) {
        return fail(std::string("DynamicClassPolicy: ") + which +
                    ".confidence_scale must be in (0, 1]");
      }
      if (!(p->reference_speed_mps >= 0.0 && p->reference_speed_mps <= 100.0)) {
        return fail(std::string("DynamicClassPolicy: ") + which +
                    ".reference_speed_mps must be in [0, 100]");
      }
    }
    return true;
  }
};

}  // namespace pcr
