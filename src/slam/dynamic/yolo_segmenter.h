#pragma once
// YOLOv8-seg instance segmentation on OpenCV DNN (paper section 3.2, Alg. 1 and 2).
//
// Accepts any Ultralytics YOLOv8 ONNX export (`nms=False`):
//   detections  1 x (4 + nc + nm) x N: cx, cy, w, h (input pixels), nc class scores (already
//               sigmoid-ed, no objectness), nm mask coefficients (0 for detection-only models);
//   prototypes  1 x nm x Hp x Wp (segmentation models only).
// The input size is read from the ONNX graph itself: the graph input's dims are taken from the
// model file's protobuf (OpenCV 4.6 does not expose them), then OpenCV's shape inference with
// that size gives the output shapes, which are checked before the first frame. Detection-only
// models run with box-shaped masks (a warning is logged).
#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

#include "slam/dynamic/mask_utils.h"
#include "slam/dynamic/onnx_model.h"
#include "slam/dynamic/segmenter.h"

namespace pcr {

// Runs a YOLOv8 network: a blob in, the raw output tensors out. OpenCV DNN is the default
// engine; src/gpu provides one that runs the network on CUDA or on its CPU twin.
// Thread-compatible: one Forward() at a time.
class InferenceEngine {
 public:
  virtual ~InferenceEngine() = default;
  // Shapes of the outputs (e.g. {1, 116, 2940} and {1, 32, 56, 160}), in the order Forward()
  // returns them.
  virtual std::vector<std::vector<int>> OutputShapes() const = 0;
  // blob: CV_32F 1 x 3 x H x W at the size the engine was made for. Returns CV_32F tensors owned
  // by the caller.
  virtual std::vector<cv::Mat> Forward(const cv::Mat& blob) = 0;
  virtual std::string Backend() const = 0;  // e.g. "opencv-dnn-cpu", "pcr-cuda:0 (...)"
  // Engines that run on a device wait for it with `wait` in Forward() (segmenter.h); engines that
  // compute on the calling thread ignore it.
  virtual void SetDeviceWait(DeviceWait wait) { (void)wait; }
};

// Makes an engine for the serialized ONNX model at a 1 x 3 x H x W input. Throws
// std::invalid_argument (or InputError) saying why the model cannot run on it.
using InferenceEngineFactory = std::function<std::unique_ptr<InferenceEngine>(
    const std::vector<uint8_t>& model_bytes, cv::Size input_size)>;

// OpenCV DNN (its CUDA backend when allow_cuda, OpenCV was built with CUDA and a GPU exists).
std::unique_ptr<InferenceEngine> MakeOpenCvDnnEngine(const std::vector<uint8_t>& model_bytes,
                                                     cv::Size input_size, bool allow_cuda);

struct YoloOptions {
  std::string model_path;        // ONNX file
  std::string names_path;        // optional class names, one per line (line index = class id);
                                 // empty: the 80 COCO names built in
  float conf_threshold = 0.25f;  // best class score must exceed this
  float nms_iou = 0.45f;         // boxes overlapping more than this are suppressed
  bool class_agnostic_nms = false;
  int max_detections = 300;
  enum class Normalization {
    kUltralytics,  // x / 255 (what Ultralytics weights expect)
    kMeanStd,      // (x / 255 - mean) / std, ImageNet statistics (paper Eq. 1)
  };
  Normalization normalization = Normalization::kUltralytics;
  int dilation_px = 5;           // base dilation radius of the dynamic map, scaled per policy
  double smooth_sigma_px = 2.0;  // Gaussian smoothing of the dynamic map (0 = none)
  // On sigmoid(coeffs . protos). 0.3 rather than the usual 0.5: the prototypes are a quarter of
  // the input's resolution, so an object's edge (where ORB puts its keypoints) falls in the soft
  // part of the sigmoid. Drive 0005, 224x640 (`pcr_orb run --filter on --segmenter yolo
  // --truth-labels` at 1990, 2000 and 2010 features): filter recall 0.672 against 0.628,
  // precision 0.959-0.962 against 0.958-0.963, mean ATE 0.555 against 0.560 m (GPS truth); KITTI 06
  // mean ATE 0.0627 against 0.0625 m.
  float mask_threshold = 0.3f;
  // Used only when the model's input height/width are symbolic (a `dynamic=True` export).
  cv::Size dynamic_input_size{640, 640};
  bool allow_cuda = true;  // use the OpenCV DNN CUDA backend when OpenCV has it and a GPU exists
  // A wide input (e.g. 128x512 for KITTI's 375x1242 frames) takes the frame at its full width and
  // cuts the top rows that do not fit (ComputeLetterbox's crop_top_to_fill_width) instead of
  // shrinking the frame into padding: the objects below keep the scale of a taller input at its
  // cost per row. Nothing is detected in the cut rows.
  bool crop_top_to_fill_width = false;
  InferenceEngineFactory engine_factory;  // empty: OpenCV DNN
  DynamicClassPolicy classes;

  bool IsValid(std::string* why) const;
  // The range of conf_threshold and mask_threshold, (0, 1); IsValid checks both with it.
  static bool IsThresholdInRange(double value) { return value > 0.0 && value < 1.0; }
};

// The 80 COCO class names in Ultralytics order (index = class id).
const std::vector<std::string>& CocoClassNames();

// The layout of a YOLOv8 model's outputs, from their shapes.
struct YoloOutputLayout {
  int detection_output = 0;   // index of the 1 x (4 + nc + nm) x N output
  int prototype_output = -1;  // index of the 1 x nm x Hp x Wp output, -1 if none
  int num_classes = 0;
  int num_mask_coeffs = 0;  // nm; 0 for detection-only models
  int num_anchors = 0;      // N
  cv::Size proto_size;      // Wp x Hp; empty for detection-only models
  bool has_prototypes() const { return num_mask_coeffs > 0; }
};

// Checks output shapes (one 3-D detection tensor, optionally one 4-D prototype tensor) against
// num_class_names classes. Throws InputError(model_path, 0, ...) naming the shapes when the layout
// is anything else (e.g. a channel count that is not 4 + num_class_names + nm).
YoloOutputLayout InspectYoloOutputs(const std::vector<std::vector<int>>& output_shapes,
                                    int num_class_names, const std::string& model_path);

// Shape of a cv::Mat as a dims vector (e.g. {1, 116, 8400}).
std::vector<int> ShapeOf(const cv::Mat& m);

// A detection before NMS: best class only (as Ultralytics does by default).
struct YoloCandidate {
  cv::Rect2f box_input_px;
  int class_id = 0;
  float score = 0.0f;
  int anchor = 0;  // column of the detection tensor
};

// Candidates whose best class score exceeds conf_threshold, in anchor order.
// detections: CV_32F 1 x C x N (or C x N) matching `layout`.
std::vector<YoloCandidate> DecodeYoloCandidates(const cv::Mat& detections,
                                                const YoloOutputLayout& layout,
                                                float conf_threshold);

float BoxIou(const cv::Rect2f& a, const cv::Rect2f& b);

// Greedy NMS: indices of kept boxes by decreasing score (ties by index). A box is dropped when
// its IoU with a kept box exceeds iou_threshold and (class_agnostic or the classes are equal).
// At most max_keep indices.
std::vector<int> NonMaxSuppression(const std::vector<cv::Rect2f>& boxes,
                                   const std::vector<float>& scores,
                                   const std::vector<int>& class_ids, float iou_threshold,
                                   bool class_agnostic, int max_keep);

struct YoloDecodeParams {
  float conf_threshold = 0.25f;
  float nms_iou = 0.45f;
  bool class_agnostic_nms = false;
  int max_detections = 300;
  float mask_threshold = 0.5f;
};

// Instances (sorted by decreasing confidence, instance_id = index) from raw outputs:
// threshold, NMS, boxes to image pixels (clipped; boxes entirely in the padding are dropped),
// masks sigmoid(coeffs . protos) evaluated only around each box, resampled to the image and
// cut to the box. prototypes may be empty when the layout has none: masks are then the boxes.
// Throws std::invalid_argument when the tensors do not match `layout`.
std::vector<Instance> DecodeYoloOutputs(const cv::Mat& detections, const cv::Mat& prototypes,
                                        const YoloOutputLayout& layout,
                                        const LetterboxInfo& letterbox,
                                        const std::vector<std::string>& class_names,
                                        const YoloDecodeParams& params);

// NCHW CV_32F 1 x 3 x H x W blob, RGB order, from a letterboxed BGR CV_8UC3 image.
cv::Mat BlobFromLetterboxed(const cv::Mat& letterboxed_bgr, YoloOptions::Normalization norm);

struct YoloStageTimes {
  double preprocess_ms = 0, forward_ms = 0, decode_ms = 0, confidence_ms = 0;
};

// Thread-compatible (one caller at a time): Segment() runs the network.
class YoloSegmenter final : public Segmenter {
 public:
  // Throws ConfigError when options are invalid, InputError naming the model (or names) file when
  // it is missing, not ONNX, damaged (an initializer's data does not match its dims: refused,
  // naming the tensor, before any engine is made), not loadable by the engine, or has an
  // unexpected output layout.
  explicit YoloSegmenter(const YoloOptions& options);

  Segmentation Segment(const cv::Mat& image) override;
  std::string Name() const override;
  void SetDeviceWait(DeviceWait wait) override { engine_->SetDeviceWait(std::move(wait)); }

  // The stages of Segment(), public for benchmarks and tests.
  // Letterboxed, normalized NCHW blob of a CV_8UC1 / CV_8UC3 image.
  cv::Mat Preprocess(const cv::Mat& image, LetterboxInfo* letterbox) const;
  // {detections, prototypes (empty for detection-only models)}; copies owned by the caller.
  std::vector<cv::Mat> Forward(const cv::Mat& blob);
  std::vector<Instance> Decode(const std::vector<cv::Mat>& outputs,
                               const LetterboxInfo& letterbox) const;
  cv::Mat DynamicConfidence(const std::vector<Instance>& instances, cv::Size image_size) const;

  cv::Size input_size() const { return input_size_; }  // W x H of the network input
  const YoloOutputLayout& layout() const { return layout_; }
  const std::vector<std::string>& class_names() const { return class_names_; }
  const std::string& backend() const { return backend_; }
  const YoloOptions& options() const { return options_; }
  const YoloStageTimes& last_stage_times() const { return last_times_; }  // of the last Segment()

 private:
  YoloOptions options_;
  std::unique_ptr<InferenceEngine> engine_;
  cv::Size input_size_;
  YoloOutputLayout layout_;
  size_t output_shapes_count_ = 0;
  std::vector<std::string> class_names_;
  std::string backend_;
  YoloStageTimes last_times_;
};

}  // namespace pcr
