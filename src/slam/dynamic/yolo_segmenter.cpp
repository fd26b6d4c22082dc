#include "slam/dynamic/yolo_segmenter.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <opencv2/core/cuda.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/log.h"
#include "slam/common/timing.h"

namespace pcr {
namespace {

// ---- Misc helpers ----

std::string ShapeString(const std::vector<int>& shape) {
  std::string s;
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i) s += 'x';
    s += std::to_string(shape[i]);
  }
  return s.empty() ? "(scalar)" : s;
}

std::string ShapesString(const std::vector<std::vector<int>>& shapes) {
  std::string s;
  for (size_t i = 0; i < shapes.size(); ++i) {
    if (i) s += ", ";
    s += ShapeString(shapes[i]);
  }
  return "[" + s + "]";
}

std::vector<std::string> ReadClassNames(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open the class names file");
  std::vector<std::string> names;
  std::string line;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) {
      line.pop_back();
    }
    names.push_back(line);
  }
  while (!names.empty() && names.back().empty()) names.pop_back();
  for (size_t i = 0; i < names.size(); ++i) {
    if (names[i].empty()) throw InputError(path, static_cast<int>(i + 1), "empty class name");
  }
  if (names.empty()) throw InputError(path, 0, "no class names");
  return names;
}

std::vector<uint8_t> ReadBytes(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, 0, "model file not found");
  if (!fs::is_regular_file(path, ec)) throw InputError(path, 0, "model path is not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open the model file");
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  if (bytes.empty()) throw InputError(path, 0, "model file is empty");
  return bytes;
}

// OpenCV's multi-line exception text ("> ..." lines) as one line.
std::string OneLine(const std::string& text) {
  std::string out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    size_t b = line.find_first_not_of("> \t");
    if (b == std::string::npos) continue;
    if (!out.empty()) out += "; ";
    out += line.substr(b);
  }
  return out;
}

bool CudaDnnAvailable() {
  try {
    if (cv::cuda::getCudaEnabledDeviceCount() <= 0) return false;
  } catch (const cv::Exception&) {
    return false;  // OpenCV built without CUDA support
  }
  for (const auto& [backend, target] : cv::dnn::getAvailableBackends()) {
    if (backend == cv::dnn::DNN_BACKEND_CUDA && target == cv::dnn::DNN_TARGET_CUDA) return true;
  }
  return false;
}

}  // namespace

// ---- Options ----

bool YoloOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why) *why = "YoloOptions: " + message;
    return false;
  };
  if (model_path.empty()) return fail("model_path is empty");
  if (!IsThresholdInRange(conf_threshold)) return fail("conf_threshold not in (0,1)");
  if (!(nms_iou > 0.0f && nms_iou <= 1.0f)) return fail("nms_iou not in (0,1]");
  if (max_detections < 1) return fail("max_detections < 1");
  if (dilation_px < 0 || dilation_px > 100) return fail("dilation_px not in [0,100]");
  if (!std::isfinite(smooth_sigma_px) || smooth_sigma_px < 0 || smooth_sigma_px > 50) {
    return fail("smooth_sigma_px not in [0,50]");
  }
  if (!IsThresholdInRange(mask_threshold)) return fail("mask_threshold not in (0,1)");
  if (dynamic_input_size.width <= 0 || dynamic_input_size.height <= 0 ||
      dynamic_input_size.width % 32 != 0 || dynamic_input_size.height % 32 != 0) {
    return fail("dynamic_input_size must be positive multiples of 32");
  }
  std::string class_why;
  if (!classes.IsValid(&class_why)) return fail(class_why);
  return true;
}

const std::vector<std::string>& CocoClassNames() {
  static const std::vector<std::string> kNames = {"person",        "bicycle",      "car",
                                                  "motorcycle",    "airplane",     "bus",
                                                  "train",         "truck",        "boat",
                                                  "traffic light", "fire hydrant", "stop sign",
                                                  "parking meter", "bench",        "bird",
                                                  "cat",           "dog",          "horse",
                                                  "sheep",         "cow",          "elephant",
                                                  "bear",          "zebra",        "giraffe",
                                                  "backpack",      "umbrella",     "handbag",
                                                  "tie",           "suitcase",     "frisbee",
                                                  "skis",          "snowboard",    "sports ball",
                                                  "kite",          "baseball bat", "baseball glove",
                                                  "skateboard",    "surfboard",    "tennis racket",
                                                  "bottle",        "wine glass",   "cup",
                                                  "fork",          "knife",        "spoon",
                                                  "bowl",          "banana",       "apple",
                                                  "sandwich",      "orange",       "broccoli",
                                                  "carrot",        "hot dog",      "pizza",
                                                  "donut",         "cake",         "chair",
                                                  "couch",         "potted plant", "bed",
                                                  "dining table",  "toilet",       "tv",
                                                  "laptop",        "mouse",        "remote",
                                                  "keyboard",      "cell phone",   "microwave",
                                                  "oven",          "toaster",      "sink",
                                                  "refrigerator",  "book",         "clock",
                                                  "vase",          "scissors",     "teddy bear",
                                                  "hair drier",    "toothbrush"};
  return kNames;
}

// ---- Output layout ----

std::vector<int> ShapeOf(const cv::Mat& m) {
  std::vector<int> shape;
  for (int i = 0; i < m.dims; ++i) shape.push_back(m.size[i]);
  return shape;
}

YoloOutputLayout InspectYoloOutputs(const std::vector<std::vector<int>>& output_shapes,
                                    int num_class_names, const std::string& model_path) {
  const std::string shapes = ShapesString(output_shapes);
  auto error = [&](const std::string& what) {
    return InputError(model_path, 0,
                      "unexpected YOLOv8 output layout " + shapes + ": " + what +
                          " (expected 1x(4+nc+nm)xN and, for segmentation, 1xnmxHpxWp)");
  };
  YoloOutputLayout layout;
  layout.detection_output = -1;
  for (size_t i = 0; i < output_shapes.size(); ++i) {
    const std::vector<int>& s = output_shapes[i];
    if (s.size() == 3 && layout.detection_output < 0) {
      layout.detection_output = static_cast<int>(i);
    } else if (s.size() == 4 && layout.prototype_output < 0) {
      layout.prototype_output = static_cast<int>(i);
    } else {
      throw error("output " + std::to_string(i) + " has shape " + ShapeString(s));
    }
  }
  if (layout.detection_output < 0) throw error("no 3-D detection output");
  const std::vector<int>& det = output_shapes[layout.detection_output];
  if (det[0] != 1) throw error("batch must be 1");
  const int channels = det[1];
  layout.num_anchors = det[2];
  if (layout.num_anchors < 1) throw error("no anchors");
  if (layout.prototype_output >= 0) {
    const std::vector<int>& proto = output_shapes[layout.prototype_output];
    if (proto[0] != 1 || proto[1] < 1 || proto[2] < 1 || proto[3] < 1) {
      throw error("bad prototype shape " + ShapeString(proto));
    }
    layout.num_mask_coeffs = proto[1];
    layout.proto_size = cv::Size(proto[3], proto[2]);
  }
  layout.num_classes = channels - 4 - layout.num_mask_coeffs;
  if (layout.num_classes != num_class_names) {
    throw error(std::to_string(channels) + " detection channels = 4 + " +
                std::to_string(layout.num_classes) + " classes + " +
                std::to_string(layout.num_mask_coeffs) + " mask coefficients, but there are " +
                std::to_string(num_class_names) + " class names");
  }
  return layout;
}

// ---- Decoding ----

namespace {
// C x N view of a 1 x C x N (or C x N) CV_32F tensor; throws on mismatch with the layout.
cv::Mat DetectionView(const cv::Mat& detections, const YoloOutputLayout& layout) {
  const int channels = 4 + layout.num_classes + layout.num_mask_coeffs;
  const std::vector<int> s = ShapeOf(detections);
  const bool ok = detections.type() == CV_32F && detections.isContinuous() &&
                  ((s.size() == 3 && s[0] == 1 && s[1] == channels && s[2] == layout.num_anchors) ||
                   (s.size() == 2 && s[0] == channels && s[1] == layout.num_anchors));
  if (!ok) {
    throw std::invalid_argument("detection tensor " + ShapeString(s) +
                                " does not match the layout 1x" + std::to_string(channels) + "x" +
                                std::to_string(layout.num_anchors));
  }
  return cv::Mat(channels, layout.num_anchors, CV_32F, const_cast<float*>(detections.ptr<float>()));
}
}  // namespace

std::vector<YoloCandidate> DecodeYoloCandidates(const cv::Mat& detections,
                                                const YoloOutputLayout& layout,
                                                float conf_threshold) {
  const cv::Mat det = DetectionView(detections, layout);
  const int n = layout.num_anchors;
  std::vector<float> best(n, -1.0f);
  std::vector<int> best_class(n, 0);
  for (int c = 0; c < layout.num_classes; ++c) {
    const float* row = det.ptr<float>(4 + c);
    for (int i = 0; i < n; ++i) {
      if (row[i] > best[i]) {
        best[i] = row[i];
        best_class[i] = c;
      }
    }
  }
  const float* cx = det.ptr<float>(0);
  const float* cy = det.ptr<float>(1);
  const float* w = det.ptr<float>(2);
  const float* h = det.ptr<float>(3);
  std::vector<YoloCandidate> out;
  for (int i = 0; i < n; ++i) {
    if (!(best[i] > conf_threshold)) continue;
    YoloCandidate c;
    c.box_input_px = cv::Rect2f(cx[i] - 0.5f * w[i], cy[i] - 0.5f * h[i], w[i], h[i]);
    c.class_id = best_class[i];
    c.score = best[i];
    c.anchor = i;
    out.push_back(c);
  }
  return out;
}

float BoxIou(const cv::Rect2f& a, const cv::Rect2f& b) {
  const float iw = std::min(a.x + a.width, b.x + b.width) - std::max(a.x, b.x);
  const float ih = std::min(a.y + a.height, b.y + b.height) - std::max(a.y, b.y);
  if (iw <= 0 || ih <= 0) return 0.0f;
  const float inter = iw * ih;
  const float uni = a.width * a.height + b.width * b.height - inter;
  return uni > 0 ? inter / uni : 0.0f;
}

std::vector<int> NonMaxSuppression(const std::vector<cv::Rect2f>& boxes,
                                   const std::vector<float>& scores,
                                   const std::vector<int>& class_ids, float iou_threshold,
                                   bool class_agnostic, int max_keep) {
  if (boxes.size() != scores.size() || boxes.size() != class_ids.size()) {
    throw std::invalid_argument("NonMaxSuppression: boxes, scores and class ids differ in size");
  }
  std::vector<int> order(boxes.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return scores[a] > scores[b]; });
  std::vector<int> kept;
  for (int i : order) {
    if (static_cast<int>(kept.size()) >= max_keep) break;
    bool suppressed = false;
    for (int k : kept) {
      if ((class_agnostic || class_ids[k] == class_ids[i]) &&
          BoxIou(boxes[k], boxes[i]) > iou_threshold) {
        suppressed = true;
        break;
      }
    }
    if (!suppressed) kept.push_back(i);
  }
  return kept;
}

std::vector<Instance> DecodeYoloOutputs(const cv::Mat& detections, const cv::Mat& prototypes,
                                        const YoloOutputLayout& layout,
                                        const LetterboxInfo& letterbox,
                                        const std::vector<std::string>& class_names,
                                        const YoloDecodeParams& params) {
  if (static_cast<int>(class_names.size()) != layout.num_classes) {
    throw std::invalid_argument("DecodeYoloOutputs: class names do not match the layout");
  }
  cv::Mat protos;  // nm x (Hp * Wp)
  if (layout.has_prototypes()) {
    const std::vector<int> s = ShapeOf(prototypes);
    const std::vector<int> want = {1, layout.num_mask_coeffs, layout.proto_size.height,
                                   layout.proto_size.width};
    if (s != want || prototypes.type() != CV_32F || !prototypes.isContinuous()) {
      throw std::invalid_argument("prototype tensor " + ShapeString(s) +
                                  " does not match the layout " + ShapeString(want));
    }
    protos = cv::Mat(layout.num_mask_coeffs, layout.proto_size.area(), CV_32F,
                     const_cast<float*>(prototypes.ptr<float>()));
  }
  const cv::Mat det = DetectionView(detections, layout);
  const std::vector<YoloCandidate> candidates =
      DecodeYoloCandidates(detections, layout, params.conf_threshold);
  // Boxes entirely in the letterbox's padding are dropped before the suppression, so that they
  // neither suppress a box of the frame nor take a slot of max_detections.
  std::vector<cv::Rect2f> boxes;
  std::vector<float> scores;
  std::vector<int> classes;
  std::vector<int> candidate_of;
  for (size_t i = 0; i < candidates.size(); ++i) {
    const YoloCandidate& c = candidates[i];
    const cv::Rect2f in_image =
        ClipBox(letterbox.ImageFromInput(c.box_input_px), letterbox.image_size);
    if (PixelsInBox(in_image, letterbox.image_size).empty()) continue;  // in the padding
    candidate_of.push_back(static_cast<int>(i));
    boxes.push_back(c.box_input_px);
    scores.push_back(c.score);
    classes.push_back(c.class_id);
  }
  const std::vector<int> kept = NonMaxSuppression(boxes, scores, classes, params.nms_iou,
                                                  params.class_agnostic_nms, params.max_detections);
  const cv::Point2d input_per_proto =
      layout.has_prototypes()
          ? cv::Point2d(static_cast<double>(letterbox.input_size.width) / layout.proto_size.width,
                        static_cast<double>(letterbox.input_size.height) / layout.proto_size.height)
          : cv::Point2d(1, 1);
  std::vector<Instance> instances;
  std::vector<float> coeffs(layout.num_mask_coeffs);
  for (int k : kept) {
    const YoloCandidate& c = candidates[candidate_of[k]];
    Instance inst;
    inst.class_id = c.class_id;
    inst.class_name = class_names[c.class_id];
    inst.confidence = c.score;
    inst.box_px = ClipBox(letterbox.ImageFromInput(c.box_input_px), letterbox.image_size);
    if (layout.has_prototypes()) {
      const int first = 4 + layout.num_classes;
      for (int m = 0; m < layout.num_mask_coeffs; ++m) {
        coeffs[m] = det.at<float>(first + m, c.anchor);
      }
      const cv::Rect roi = ProtoRoiForBox(c.box_input_px, input_per_proto, layout.proto_size);
      const cv::Mat prob = MaskProbabilities(coeffs.data(), protos, layout.proto_size, roi);
      inst.mask = ProtoMaskToImage(prob, roi, input_per_proto, letterbox, inst.box_px,
                                   params.mask_threshold);
    } else {
      inst.mask = BoxMask(letterbox.image_size, inst.box_px);
    }
    inst.instance_id = static_cast<int>(instances.size());
    instances.push_back(std::move(inst));
  }
  return instances;
}

cv::Mat BlobFromLetterboxed(const cv::Mat& letterboxed_bgr, YoloOptions::Normalization norm) {
  if (letterboxed_bgr.type() != CV_8UC3) {
    throw std::invalid_argument("BlobFromLetterboxed: expected CV_8UC3");
  }
  cv::Mat blob = cv::dnn::blobFromImage(letterboxed_bgr, 1.0 / 255.0, cv::Size(), cv::Scalar(),
                                        /*swapRB=*/true, /*crop=*/false, CV_32F);
  if (norm == YoloOptions::Normalization::kMeanStd) {
    // ImageNet statistics, RGB order (the blob's channel order).
    constexpr double kMean[3] = {0.485, 0.456, 0.406};
    constexpr double kStd[3] = {0.229, 0.224, 0.225};
    const int h = blob.size[2], w = blob.size[3];
    for (int c = 0; c < 3; ++c) {
      cv::Mat plane(h, w, CV_32F, blob.ptr<float>(0, c));
      plane.convertTo(plane, CV_32F, 1.0 / kStd[c], -kMean[c] / kStd[c]);
    }
  }
  return blob;
}

namespace {

// ---- OpenCV DNN engine ----

class OpenCvDnnEngine final : public InferenceEngine {
 public:
  OpenCvDnnEngine(const std::vector<uint8_t>& bytes, cv::Size input_size, bool allow_cuda) {
    try {
      // OpenCV logs its own "[ERROR:0@...]" line before throwing; the exception, rethrown below
      // with the file's name by the caller, says the same.
      const cv::utils::logging::LogLevel level =
          cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
      try {
        net_ = cv::dnn::readNetFromONNX(bytes);
      } catch (...) {
        cv::utils::logging::setLogLevel(level);
        throw;
      }
      cv::utils::logging::setLogLevel(level);
    } catch (const cv::Exception& e) {
      throw std::invalid_argument("OpenCV " CV_VERSION " DNN cannot load this ONNX model: " +
                                  OneLine(e.err));
    }
    if (net_.empty()) throw std::invalid_argument("OpenCV DNN loaded an empty network");
    // Output shapes by OpenCV's shape inference at the model's input size (no forward pass).
    output_names_ = net_.getUnconnectedOutLayersNames();
    const cv::dnn::MatShape input_shape = {1, 3, input_size.height, input_size.width};
    for (const std::string& name : output_names_) {
      std::vector<cv::dnn::MatShape> in_shapes, out_shapes;
      try {
        net_.getLayerShapes(input_shape, net_.getLayerId(name), in_shapes, out_shapes);
      } catch (const cv::Exception& e) {
        throw std::invalid_argument("the layers do not accept the input size " +
                                    ShapeString(input_shape) + ": " + OneLine(e.err));
      }
      if (out_shapes.size() != 1) {
        throw std::invalid_argument("output layer " + name + " has " +
                                    std::to_string(out_shapes.size()) + " outputs");
      }
      output_shapes_.push_back(out_shapes[0]);
    }
    if (allow_cuda && CudaDnnAvailable()) {
      net_.setPreferableBackend(cv::dnn::DNN_BACKEND_CUDA);
      net_.setPreferableTarget(cv::dnn::DNN_TARGET_CUDA);
      backend_ = "opencv-dnn-cuda";
    } else {
      net_.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
      net_.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
      backend_ = "opencv-dnn-cpu";
    }
  }

  std::vector<std::vector<int>> OutputShapes() const override { return output_shapes_; }

  std::vector<cv::Mat> Forward(const cv::Mat& blob) override {
    net_.setInput(blob);
    std::vector<cv::Mat> raw;
    net_.forward(raw, output_names_);
    for (cv::Mat& m : raw) m = m.clone();  // raw aliases the network's buffers
    return raw;
  }

  std::string Backend() const override { return backend_; }

 private:
  cv::dnn::Net net_;
  std::vector<std::string> output_names_;
  std::vector<std::vector<int>> output_shapes_;
  std::string backend_;
};

}  // namespace

std::unique_ptr<InferenceEngine> MakeOpenCvDnnEngine(const std::vector<uint8_t>& model_bytes,
                                                     cv::Size input_size, bool allow_cuda) {
  return std::make_unique<OpenCvDnnEngine>(model_bytes, input_size, allow_cuda);
}

// ---- YoloSegmenter ----

YoloSegmenter::YoloSegmenter(const YoloOptions& options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError(why);
  const std::string& path = options_.model_path;
  const std::vector<uint8_t> bytes = ReadBytes(path);

  // Also checks every initializer's data against its dims, for every engine: OpenCV DNN would
  // read past a short tensor without a word.
  std::vector<int64_t> dims;
  try {
    dims = OnnxGraphInputShape(bytes);
  } catch (const std::invalid_argument& e) {
    throw InputError(path, 0, std::string("cannot read it as an ONNX model: ") + e.what());
  }
  const std::string dims_text = OnnxDimsText(dims);
  if (dims.size() != 4 || (dims[1] > 0 && dims[1] != 3) || (dims[0] > 1)) {
    throw InputError(path, 0, "model input is " + dims_text + ", expected 1x3xHxW");
  }
  if (dims[2] > 0 && dims[3] > 0) {
    if (dims[2] > 16384 || dims[3] > 16384) {
      throw InputError(path, 0, "model input " + dims_text + " is implausibly large");
    }
    input_size_ = cv::Size(static_cast<int>(dims[3]), static_cast<int>(dims[2]));
  } else {
    input_size_ = options_.dynamic_input_size;
    Logger().warn("YoloSegmenter: {} has a symbolic input size ({}), using {}x{}", path, dims_text,
                  input_size_.width, input_size_.height);
  }

  try {
    engine_ = options_.engine_factory
                  ? options_.engine_factory(bytes, input_size_)
                  : MakeOpenCvDnnEngine(bytes, input_size_, options_.allow_cuda);
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(path, 0, OneLine(e.what()));
  }
  if (!engine_) throw InputError(path, 0, "the inference engine factory returned no engine");
  const std::vector<std::vector<int>> output_shapes = engine_->OutputShapes();
  backend_ = engine_->Backend();

  class_names_ =
      options_.names_path.empty() ? CocoClassNames() : ReadClassNames(options_.names_path);
  layout_ = InspectYoloOutputs(output_shapes, static_cast<int>(class_names_.size()), path);
  output_shapes_count_ = output_shapes.size();
  if (!layout_.has_prototypes()) {
    Logger().warn(
        "YoloSegmenter: {} is a detection-only model (outputs {}); masks fall back to "
        "the detection boxes",
        path, ShapesString(output_shapes));
  }
  for (const DynamicClass& c : options_.classes.classes) {
    if (std::find(class_names_.begin(), class_names_.end(), c.name) == class_names_.end()) {
      Logger().warn("YoloSegmenter: dynamic class '{}' is not among the model's classes", c.name);
    }
  }

  Logger().info("YoloSegmenter: {} input {}x{}, outputs {}, {} classes, {} on {}", path,
                input_size_.width, input_size_.height, ShapesString(output_shapes),
                layout_.num_classes, layout_.has_prototypes() ? "masks" : "box masks", backend_);
}

std::string YoloSegmenter::Name() const {
  return "yolov8-seg(" + std::filesystem::path(options_.model_path).filename().string() + ", " +
         std::to_string(input_size_.width) + "x" + std::to_string(input_size_.height) + ", " +
         backend_ +
         (options_.crop_top_to_fill_width
              ? ", fills the width, top rows cut when the frame is taller"
              : "") +
         ")";
}

cv::Mat YoloSegmenter::Preprocess(const cv::Mat& image, LetterboxInfo* letterbox) const {
  if (image.empty() || (image.type() != CV_8UC1 && image.type() != CV_8UC3)) {
    throw std::invalid_argument("YoloSegmenter: expected a grey CV_8UC1 or BGR CV_8UC3 image");
  }
  const LetterboxInfo info =
      ComputeLetterbox(image.size(), input_size_, options_.crop_top_to_fill_width);
  if (letterbox) *letterbox = info;
  return BlobFromLetterboxed(LetterboxImage(image, info), options_.normalization);
}

std::vector<cv::Mat> YoloSegmenter::Forward(const cv::Mat& blob) {
  std::vector<cv::Mat> raw = engine_->Forward(blob);
  if (raw.size() != output_shapes_count_) {
    throw std::runtime_error("YoloSegmenter: the " + backend_ + " engine returned " +
                             std::to_string(raw.size()) + " outputs, expected " +
                             std::to_string(output_shapes_count_));
  }
  std::vector<cv::Mat> out(2);
  out[0] = raw[layout_.detection_output];
  if (layout_.has_prototypes()) out[1] = raw[layout_.prototype_output];
  return out;
}

std::vector<Instance> YoloSegmenter::Decode(const std::vector<cv::Mat>& outputs,
                                            const LetterboxInfo& letterbox) const {
  if (outputs.size() != 2) throw std::invalid_argument("YoloSegmenter::Decode: need 2 outputs");
  YoloDecodeParams params;
  params.conf_threshold = options_.conf_threshold;
  params.nms_iou = options_.nms_iou;
  params.class_agnostic_nms = options_.class_agnostic_nms;
  params.max_detections = options_.max_detections;
  params.mask_threshold = options_.mask_threshold;
  return DecodeYoloOutputs(outputs[0], outputs[1], layout_, letterbox, class_names_, params);
}

cv::Mat YoloSegmenter::DynamicConfidence(const std::vector<Instance>& instances,
                                         cv::Size image_size) const {
  return DynamicConfidenceMap(instances, image_size, options_.classes, options_.dilation_px,
                              options_.smooth_sigma_px);
}

Segmentation YoloSegmenter::Segment(const cv::Mat& image) {
  auto t = std::chrono::steady_clock::now();
  LetterboxInfo letterbox;
  const cv::Mat blob = Preprocess(image, &letterbox);
  last_times_.preprocess_ms = MsSince(t);

  t = std::chrono::steady_clock::now();
  const std::vector<cv::Mat> outputs = Forward(blob);
  last_times_.forward_ms = MsSince(t);

  t = std::chrono::steady_clock::now();
  Segmentation seg;
  seg.instances = Decode(outputs, letterbox);
  seg.instance_map = BuildInstanceMap(seg.instances, image.size());
  last_times_.decode_ms = MsSince(t);

  t = std::chrono::steady_clock::now();
  seg.dynamic_confidence = DynamicConfidence(seg.instances, image.size());
  last_times_.confidence_ms = MsSince(t);
  seg.backend = backend_;
  return seg;
}

}  // namespace pcr
