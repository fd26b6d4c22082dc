// YOLOv8-seg models at other input sizes (tools/yolo_resize.py) against the shipped 224x640
// model: forward time per OpenCV thread count, and what the masks lose.
//
//   bench_masks [--models FILE,FILE,...] [--threads 1,2] [--frames A:B] [--sequence DIR]
//               [--labels FILE|none] [--reference FILE] [--runs N] [--detail] [--int8]
//               [--crop-top] [--engines opencv,onednn]
//
// --crop-top runs the added models with YoloOptions::crop_top_to_fill_width (a wide export, e.g.
// 128x512, takes the frame at full width and cuts its top rows); the reference as always.
//
// --engines runs every model on each engine named (opencv: OpenCV DNN; onednn: the project's
// executor with oneDNN's convolutions; twin), one table row per model and engine; the reference
// itself stays OpenCV's.
//
// --int8 adds the reference quantised to int8 by OpenCV DNN itself (cv::dnn::Net::quantize,
// OpenCV 4.6's int8 path, calibrated on the reference's blob of the sequence's first frame: it
// takes one blob per input, and the graph's reshapes fix the batch at 1) as one more model, run
// through the same segmenter code.
//
// The reference (default PCR_SHARED_DIR/models/yolov8n-seg_coco_224x640.onnx) is always the first
// model; --models adds more. Four markdown tables:
// 1. speed: net.forward() only, on the blob of the KITTI test image, median and p90 of --runs
//    passes per thread count (cv::setNumThreads). The models take turns pass by pass, so a drift
//    in the machine's speed hits them alike.
// 2. masks on the KITTI test image (models/test_images/kitti_000008.png) and
// 3. masks on every frame of the sequence (default: raw drive 0005, its left image: image_02
//    colour when the drive has it, else image_00 grey), against the reference model: every
//    reference instance of a dynamic class (DynamicClassPolicy's default classes) is matched to
//    the model's instance of the same class with the highest mask IoU (pixels; not exclusive).
//    "mean IoU" averages that best IoU over all reference instances (0 when the model has no
//    instance of the class); "matched" is the fraction with IoU >= 0.5; "ref conf>=0.5" gives both
//    for the reference instances of confidence >= 0.5 only (those near the detection threshold come
//    and go with any change of the input). "conf IoU" is the IoU of the dynamic-confidence maps'
//    pixels >= 0.5 (pixels summed over the frames).
// 4. recall against the KITTI tracking labels' 2-D boxes (label_02; frame k = dataset frame k;
//    the boxes are image_02 pixels, a few pixels off image_00): a box counts as found when an
//    instance of a matching COCO class has box IoU >= 0.5 with it. DontCare, truncation > 1,
//    occlusion >= 2 and boxes under 25 px high are ignored. Groups: vehicles (Car, Van, Truck,
//    Tram: car/truck/bus), cyclists (Cyclist: bicycle/person/motorcycle), pedestrians
//    (Pedestrian, Person_sitting: person). One more column counts a cyclist also found when the
//    joint box of an overlapping person and bicycle/motorcycle has IoU >= 0.5 with it (the model
//    reports rider and bicycle apart).
// --detail prints every reference instance of the test image with its best match per model.
// Exits 1 naming the file when a model, the image, the sequence or the labels are missing.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_args.h"
#include "bench_cli.h"
#include "driver/inference.h"
#include "driver/run_slam.h"
#include "io/dataset.h"
#include "io/kitti_tracking.h"
#include "slam/common/error.h"
#include "slam/common/timing.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace {

using pcr::bench::SharedDir;

struct Args {
  std::string reference = SharedDir() + "/models/yolov8n-seg_coco_224x640.onnx";
  std::vector<std::string> models;  // besides the reference
  std::vector<int> threads = {1, 2};
  std::string frames;
  std::string sequence = SharedDir() + "/data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync";
  std::string labels = SharedDir() + "/data/kitti_tracking/training/label_02/0000.txt";
  std::string image = SharedDir() + "/models/test_images/kitti_000008.png";
  int runs = 15;
  bool detail = false;    // per-instance matches on the test image
  bool int8 = false;      // also the reference quantised to int8 by OpenCV DNN
  bool crop_top = false;  // the added models fill the width and cut the frame's top rows
  std::vector<std::string> engines{"opencv"};  // each model runs on each of these
};

// OpenCV DNN's own int8 network (Net::quantize) as the segmenter's engine.
class QuantizedEngine final : public pcr::InferenceEngine {
 public:
  QuantizedEngine(const std::vector<uint8_t>& bytes, const std::vector<cv::Mat>& calibration,
                  std::vector<std::vector<int>> output_shapes)
      : output_shapes_(std::move(output_shapes)) {
    // One blob per network input, and the graph's reshapes fix the batch at 1: one frame.
    cv::dnn::Net net = cv::dnn::readNetFromONNX(bytes);
    net_ = net.quantize(std::vector<cv::Mat>{calibration.front()}, CV_32F, CV_32F);
    net_.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
    net_.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
    names_ = net_.getUnconnectedOutLayersNames();
  }
  std::vector<std::vector<int>> OutputShapes() const override { return output_shapes_; }
  std::vector<cv::Mat> Forward(const cv::Mat& blob) override {
    net_.setInput(blob);
    std::vector<cv::Mat> raw;
    net_.forward(raw, names_);
    for (cv::Mat& m : raw) m = m.clone();
    return raw;
  }
  std::string Backend() const override { return "opencv-dnn-cpu-int8"; }

 private:
  cv::dnn::Net net_;
  std::vector<std::string> names_;
  std::vector<std::vector<int>> output_shapes_;
};

// Reads the command line into *a. Returns -1 when the benchmark is to run, else its exit status
// (0 after --help). A bad value throws std::invalid_argument naming the option.
int ParseArgs(int argc, char** argv, Args* a) {
  CLI::App app{
      "YOLOv8-seg models at other input sizes against the shipped 224x640 model (the "
      "reference, always the first model): forward time per OpenCV thread count, masks against "
      "the reference's, recall against the KITTI tracking labels (see the top of "
      "bench/bench_masks.cpp)"};
  app.add_option_function<std::string>(
         "--models", [a](const std::string& text) { a->models = pcr::bench::SplitList(text); },
         "models (ONNX) to compare with the reference, comma-separated")
      ->type_name("FILE,FILE,...");
  app.add_option("--reference", a->reference, "the reference model (ONNX)")
      ->type_name("FILE")
      ->capture_default_str();
  app.add_option_function<std::string>(
         "--threads",
         [a](const std::string& text) {
           a->threads.clear();
           for (const std::string& t : pcr::bench::SplitList(text))
             a->threads.push_back(pcr::bench::ParseInt(t, "--threads", 1, 256));
           if (a->threads.empty()) throw std::invalid_argument("--threads needs a count");
         },
         "OpenCV thread counts of the speed table (cv::setNumThreads), each 1 to 256")
      ->type_name("N,N,...")
      ->default_str("1,2");
  app.add_option("--frames", a->frames, "frames A:B of the sequence (default: all)")
      ->type_name("A:B");
  app.add_option("--sequence", a->sequence, "KITTI raw or odometry sequence folder")
      ->type_name("DIR")
      ->capture_default_str();
  app.add_option("--labels", a->labels,
                 "KITTI tracking labels (label_02) of the sequence, for the recall table (none: "
                 "no recall table)")
      ->type_name("FILE|none")
      ->capture_default_str();
  pcr::bench::AddInt(app, "--runs", &a->runs, 1, 1000, "N",
                     "forward passes per model and thread count in the speed table");
  app.add_flag("--detail", a->detail,
               "every reference instance of the test image with its best match per model");
  app.add_flag("--int8", a->int8,
               "also the reference quantised to int8 by OpenCV DNN (Net::quantize)");
  app.add_flag("--crop-top", a->crop_top,
               "the added models fill the frame's width and cut its top rows "
               "(YoloOptions::crop_top_to_fill_width)");
  app.add_option_function<std::string>(
         "--engines",
         [a](const std::string& text) {
           a->engines = pcr::bench::SplitList(text);
           if (a->engines.empty()) throw std::invalid_argument("--engines needs a name");
           for (const std::string& engine : a->engines) {
             // The driver's check of an engine, whose message names pcr_orb's --inference.
             try {
               pcr::YoloOptions probe;
               pcr::driver::ApplyInference(engine, &probe);
             } catch (const pcr::ConfigError& e) {
               const std::string why = e.what(), flag = "--inference";
               throw std::invalid_argument(
                   why.rfind(flag, 0) == 0 ? "--engines" + why.substr(flag.size()) : why);
             }
           }
         },
         "engines every model runs on, one table row each: opencv (OpenCV DNN), onednn (the "
         "project's executor with oneDNN's convolutions), twin; the reference stays OpenCV's")
      ->type_name("opencv,onednn,twin")
      ->default_str("opencv");
  const int status = pcr::bench::Parse(app, argc, argv);
  if (status >= 0) return status;
  // The reference once, first.
  a->models.erase(std::remove(a->models.begin(), a->models.end(), a->reference), a->models.end());
  a->models.insert(a->models.begin(), a->reference);
  return -1;
}

// Exits 1 naming the path when it is not there.
void Require(const std::string& path, const char* what, bool directory = false) {
  std::error_code ec;
  const bool ok = directory ? std::filesystem::is_directory(path, ec)
                            : std::filesystem::is_regular_file(path, ec);
  if (!ok) {
    std::fprintf(stderr, "bench_masks: %s not found: %s\n", what, path.c_str());
    std::exit(1);
  }
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t k = static_cast<size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

std::string Basename(const std::string& path) {
  return std::filesystem::path(path).filename().string();
}

// Mask IoU of two instances (masks non-zero only inside their boxes).
double MaskIou(const pcr::Instance& a, const pcr::Instance& b) {
  const cv::Size size = a.mask.size();
  const cv::Rect ra = pcr::PixelsInBox(a.box_px, size);
  const cv::Rect rb = pcr::PixelsInBox(b.box_px, size);
  const cv::Rect roi = (ra | rb) & cv::Rect(0, 0, size.width, size.height);
  if (roi.empty()) return 0;
  const cv::Mat ma = a.mask(roi) != 0, mb = b.mask(roi) != 0;
  const int inter = cv::countNonZero(ma & mb);
  const int uni = cv::countNonZero(ma | mb);
  return uni > 0 ? static_cast<double>(inter) / uni : 0.0;
}

// Mask agreement of a model with the reference, accumulated over frames.
struct MaskStats {
  size_t frames = 0;
  size_t ref_instances = 0;    // dynamic-class instances of the reference
  size_t model_instances = 0;  // dynamic-class instances of the model
  double iou_sum = 0;          // best same-class IoU per reference instance
  size_t matched = 0;          // ... >= 0.5
  // The same for the reference instances of confidence >= 0.5 (those near the detection
  // threshold come and go with any change of the input).
  size_t ref_confident = 0, matched_confident = 0;
  double iou_sum_confident = 0;
  double conf_inter = 0, conf_union = 0;
  std::vector<double> segment_ms;

  void Add(const pcr::Segmentation& ref, const pcr::Segmentation& seg,
           const pcr::DynamicClassPolicy& policy) {
    ++frames;
    for (const pcr::Instance& m : seg.instances)
      if (policy.Find(m.class_name)) ++model_instances;
    for (const pcr::Instance& r : ref.instances) {
      if (!policy.Find(r.class_name)) continue;
      ++ref_instances;
      double best = 0;
      for (const pcr::Instance& m : seg.instances)
        if (m.class_name == r.class_name) best = std::max(best, MaskIou(r, m));
      iou_sum += best;
      if (best >= 0.5) ++matched;
      if (r.confidence >= 0.5f) {
        ++ref_confident;
        iou_sum_confident += best;
        if (best >= 0.5) ++matched_confident;
      }
    }
    const cv::Mat a = ref.dynamic_confidence >= 0.5f, b = seg.dynamic_confidence >= 0.5f;
    conf_inter += cv::countNonZero(a & b);
    conf_union += cv::countNonZero(a | b);
  }
  std::string MeanIou() const {
    return ref_instances ? fmt::format("{:.3f}", iou_sum / static_cast<double>(ref_instances))
                         : std::string("-");
  }
  std::string Matched() const {
    return ref_instances ? fmt::format("{:.1f}% ({}/{})",
                                       100.0 * static_cast<double>(matched) /
                                           static_cast<double>(ref_instances),
                                       matched, ref_instances)
                         : std::string("-");
  }
  std::string Confident() const {
    return ref_confident ? fmt::format("{:.3f} / {:.1f}% ({}/{})",
                                       iou_sum_confident / static_cast<double>(ref_confident),
                                       100.0 * static_cast<double>(matched_confident) /
                                           static_cast<double>(ref_confident),
                                       matched_confident, ref_confident)
                         : std::string("-");
  }
  std::string ConfIou() const {
    return conf_union > 0 ? fmt::format("{:.3f}", conf_inter / conf_union) : std::string("-");
  }
};

// Per reference instance of a dynamic class: its best same-class match in `seg`.
void PrintDetail(const std::string& name, const pcr::Segmentation& ref,
                 const pcr::Segmentation& seg, const pcr::DynamicClassPolicy& policy) {
  std::printf("%s: reference instance -> best %s instance of the same class\n", name.c_str(),
              name.c_str());
  for (const pcr::Instance& r : ref.instances) {
    if (!policy.Find(r.class_name)) continue;
    const pcr::Instance* best = nullptr;
    double best_iou = 0;
    for (const pcr::Instance& m : seg.instances) {
      if (m.class_name != r.class_name) continue;
      const double iou = MaskIou(r, m);
      if (!best || iou > best_iou) best = &m, best_iou = iou;
    }
    std::printf("  %-10s conf %.2f box [%.0f %.0f %.0f %.0f] %d px", r.class_name.c_str(),
                r.confidence, r.box_px.x, r.box_px.y, r.box_px.br().x, r.box_px.br().y,
                cv::countNonZero(r.mask));
    if (best) {
      std::printf(" -> conf %.2f box [%.0f %.0f %.0f %.0f] %d px, mask IoU %.3f, box IoU %.3f\n",
                  best->confidence, best->box_px.x, best->box_px.y, best->box_px.br().x,
                  best->box_px.br().y, cv::countNonZero(best->mask), best_iou,
                  pcr::BoxIou(r.box_px, best->box_px));
    } else {
      std::printf(" -> none\n");
    }
  }
  for (const pcr::Instance& m : seg.instances) {
    if (!policy.Find(m.class_name)) continue;
    bool same_class = false;
    for (const pcr::Instance& r : ref.instances) same_class |= r.class_name == m.class_name;
    if (!same_class)
      std::printf("  (model only: %s conf %.2f)\n", m.class_name.c_str(), m.confidence);
  }
}

// Recall against the tracking labels, per group.
enum Group { kVehicles, kCyclists, kPedestrians, kGroups };
constexpr const char* kGroupNames[kGroups] = {"vehicles", "cyclists", "pedestrians"};

int GroupOf(const pcr::TrackedObject& o) {
  if (o.type == "Car" || o.type == "Van" || o.type == "Truck" || o.type == "Tram") return kVehicles;
  if (o.type == "Cyclist") return kCyclists;
  if (o.type == "Pedestrian" || o.type == "Person_sitting") return kPedestrians;
  return -1;
}

bool ClassFits(int group, const std::string& coco) {
  switch (group) {
    case kVehicles:
      return coco == "car" || coco == "truck" || coco == "bus";
    case kCyclists:
      return coco == "bicycle" || coco == "person" || coco == "motorcycle";
    case kPedestrians:
      return coco == "person";
    default:
      return false;
  }
}

// Labelled objects of one frame that count: not DontCare, truncation <= 1, occlusion < 2, box at
// least 25 px high, of a known group.
std::vector<const pcr::TrackedObject*> Countable(const std::vector<pcr::TrackedObject>& objects) {
  std::vector<const pcr::TrackedObject*> out;
  for (const pcr::TrackedObject& o : objects) {
    if (o.IsDontCare() || o.truncated > 1 || o.occluded >= 2) continue;
    if (o.bbox_px[3] - o.bbox_px[1] < 25) continue;
    if (GroupOf(o) < 0) continue;
    out.push_back(&o);
  }
  return out;
}

struct Recall {
  size_t found[kGroups] = {0, 0, 0}, total[kGroups] = {0, 0, 0};
  // Cyclists found by one instance or by the joint box of a person and an overlapping bicycle or
  // motorcycle (YOLO reports the rider and the bicycle apart; neither box alone covers a
  // cyclist's label box, rider and bicycle, at IoU 0.5 when close).
  size_t cyclists_joint = 0;

  void Add(const std::vector<const pcr::TrackedObject*>& objects,
           const std::vector<pcr::Instance>& instances) {
    for (const pcr::TrackedObject* o : objects) {
      const int g = GroupOf(*o);
      const cv::Rect2f box(static_cast<float>(o->bbox_px[0]), static_cast<float>(o->bbox_px[1]),
                           static_cast<float>(o->bbox_px[2] - o->bbox_px[0]),
                           static_cast<float>(o->bbox_px[3] - o->bbox_px[1]));
      ++total[g];
      bool hit = false;
      for (const pcr::Instance& m : instances) {
        if (ClassFits(g, m.class_name) && pcr::BoxIou(box, m.box_px) >= 0.5f) {
          hit = true;
          break;
        }
      }
      if (hit) ++found[g];
      if (g == kCyclists && (hit || JointHit(box, instances))) ++cyclists_joint;
    }
  }
  static bool JointHit(const cv::Rect2f& box, const std::vector<pcr::Instance>& instances) {
    for (const pcr::Instance& p : instances) {
      if (p.class_name != "person") continue;
      for (const pcr::Instance& b : instances) {
        if (b.class_name != "bicycle" && b.class_name != "motorcycle") continue;
        if ((p.box_px & b.box_px).area() <= 0) continue;
        if (pcr::BoxIou(box, p.box_px | b.box_px) >= 0.5f) return true;
      }
    }
    return false;
  }
  static std::string Cell(size_t hits, size_t of) {
    if (of == 0) return "- (0/0)";
    return fmt::format("{:.1f}% ({}/{})",
                       100.0 * static_cast<double>(hits) / static_cast<double>(of), hits, of);
  }
  std::string Cell(int g) const { return Cell(found[g], total[g]); }
  std::string CyclistsJoint() const { return Cell(cyclists_joint, total[kCyclists]); }
};

struct Model {
  std::string path, name;
  std::unique_ptr<pcr::YoloSegmenter> segmenter;
  std::string Input() const {
    return fmt::format("{}x{}", segmenter->input_size().height, segmenter->input_size().width);
  }
};

}  // namespace

int main(int argc, char** argv) {
  try {
    Args args;
    if (const int status = ParseArgs(argc, argv, &args); status >= 0) return status;
    spdlog::set_level(spdlog::level::warn);
    for (const std::string& m : args.models) Require(m, "model");
    Require(args.image, "test image");
    Require(args.sequence, "sequence directory", /*directory=*/true);
    const bool with_labels = args.labels != "none";
    if (with_labels) Require(args.labels, "labels file");

    const pcr::DynamicClassPolicy policy;
    const cv::Mat image = cv::imread(args.image, cv::IMREAD_COLOR);
    if (image.empty()) {
      std::fprintf(stderr, "bench_masks: cannot read the test image %s\n", args.image.c_str());
      return 1;
    }
    std::vector<Model> models;
    for (const std::string& path : args.models) {
      for (const std::string& engine : args.engines) {
        const bool reference = path == args.reference;
        if (reference && engine != "opencv" && models.empty()) {
          // The reference on OpenCV first, whatever the engines.
          pcr::YoloOptions options;
          options.model_path = path;
          options.allow_cuda = false;
          models.push_back({path, Basename(path), std::make_unique<pcr::YoloSegmenter>(options)});
        }
        pcr::YoloOptions options;
        options.model_path = path;
        options.allow_cuda = false;
        options.crop_top_to_fill_width = args.crop_top && !reference;
        pcr::driver::ApplyInference(engine, &options);
        auto segmenter = std::make_unique<pcr::YoloSegmenter>(options);
        std::string name = Basename(path);
        const int cut = pcr::ComputeLetterbox(image.size(), segmenter->input_size(),
                                              options.crop_top_to_fill_width)
                            .crop_top_px;  // of the test image, for the tables
        if (cut > 0) name += " (top " + std::to_string(cut) + " rows cut)";
        if (engine != "opencv") name += " on " + engine;
        models.push_back({path, name, std::move(segmenter)});
      }
    }
    const pcr::Dataset dataset = pcr::OpenDataset(args.sequence);
    const pcr::driver::FrameRange range =
        pcr::driver::FrameRange::Parse(args.frames, dataset.size());
    if (args.int8) {
      // Calibration blobs: the reference's own preprocessing of the sequence's first frames.
      const pcr::YoloSegmenter& reference = *models.front().segmenter;
      std::vector<cv::Mat> calibration;
      pcr::LetterboxInfo letterbox;
      calibration.push_back(reference.Preprocess(
          dataset.has_color() ? dataset.LoadLeftColor(range.first) : dataset.LoadLeft(range.first),
          &letterbox));
      pcr::YoloOptions options;
      options.model_path = args.reference;
      options.allow_cuda = false;
      options.engine_factory = [&](const std::vector<uint8_t>& bytes, cv::Size) {
        auto engine = pcr::MakeOpenCvDnnEngine(bytes, reference.input_size(), false);
        return std::make_unique<QuantizedEngine>(bytes, calibration, engine->OutputShapes());
      };
      const auto start = std::chrono::steady_clock::now();
      models.push_back({args.reference, Basename(args.reference) + " int8",
                        std::make_unique<pcr::YoloSegmenter>(options)});
      std::fprintf(stderr, "int8: quantised on %zu frames in %.0f ms\n", calibration.size(),
                   pcr::MsSince(start));
    }
    pcr::TrackingLabels labels;
    if (with_labels) labels = pcr::ReadTrackingLabels(args.labels);

    std::printf(
        "bench_masks: reference %s; %zu model(s); test image %s; sequence %s (%s), frames "
        "%zu:%zu; labels %s; load average at start %s\n\n",
        models.front().name.c_str(), models.size(), Basename(args.image).c_str(),
        dataset.name.c_str(), dataset.has_color() ? "image_02 colour" : "image_00 grey",
        range.first, range.end, with_labels ? args.labels.c_str() : "none",
        pcr::bench::LoadAverage().c_str());

    // 1. Speed: net.forward() on the test image's blob, models in turn pass by pass.
    std::vector<cv::Mat> blobs;
    for (Model& m : models) {
      pcr::LetterboxInfo letterbox;
      blobs.push_back(m.segmenter->Preprocess(image, &letterbox));
    }
    // times[thread index][model] = forward ms per pass
    std::vector<std::vector<std::vector<double>>> times(
        args.threads.size(), std::vector<std::vector<double>>(models.size()));
    for (size_t ti = 0; ti < args.threads.size(); ++ti) {
      cv::setNumThreads(args.threads[ti]);
      for (size_t k = 0; k < models.size(); ++k)
        for (int w = 0; w < 2; ++w) models[k].segmenter->Forward(blobs[k]);  // warm-up
      for (int r = 0; r < args.runs; ++r) {
        std::fprintf(stderr, "\rspeed: %d thread(s), pass %d/%d   ", args.threads[ti], r + 1,
                     args.runs);
        for (size_t k = 0; k < models.size(); ++k) {
          const auto t = std::chrono::steady_clock::now();
          models[k].segmenter->Forward(blobs[k]);
          times[ti][k].push_back(pcr::MsSince(t));
        }
      }
    }
    std::fprintf(stderr, "\n");
    std::string header = "| model | input HxW | anchors |";
    std::string rule = "|---|---|---|";
    for (int t : args.threads) {
      header += fmt::format(" fwd {0} thr median ms | fwd {0} thr p90 ms | vs ref ({0} thr) |", t);
      rule += "---|---|---|";
    }
    std::printf("### Forward time (net.forward() on %s, %d passes per thread count)\n\n%s\n%s\n",
                Basename(args.image).c_str(), args.runs, header.c_str(), rule.c_str());
    for (size_t k = 0; k < models.size(); ++k) {
      std::string row = fmt::format("| {} | {} | {} |", models[k].name, models[k].Input(),
                                    models[k].segmenter->layout().num_anchors);
      for (size_t ti = 0; ti < args.threads.size(); ++ti) {
        const double median = Percentile(times[ti][k], 0.5);
        const double ref = Percentile(times[ti][0], 0.5);
        row += fmt::format(" {:.1f} | {:.1f} | {:.2f}x |", median, Percentile(times[ti][k], 0.9),
                           median > 0 ? ref / median : 0.0);
      }
      std::printf("%s\n", row.c_str());
    }
    std::printf("\n(vs ref: the reference's median over the model's, > 1 is faster)\n\n");

    // 2. Masks on the test image.
    cv::setNumThreads(args.threads.back());
    {
      std::vector<MaskStats> stats(models.size());
      const pcr::Segmentation ref = models.front().segmenter->Segment(image);
      for (size_t k = 0; k < models.size(); ++k) {
        const pcr::Segmentation seg = k == 0 ? ref : models[k].segmenter->Segment(image);
        stats[k].Add(ref, seg, policy);
        if (args.detail && k > 0) PrintDetail(models[k].name, ref, seg, policy);
      }
      std::printf(
          "### Masks on %s against %s (dynamic classes)\n\n| model | input HxW | instances | "
          "ref instances | mean IoU | matched IoU>=0.5 | ref conf>=0.5: mean IoU / matched | conf "
          "IoU "
          "|\n|---|---|---|---|---|---|---|---|\n",
          Basename(args.image).c_str(), models.front().name.c_str());
      for (size_t k = 0; k < models.size(); ++k) {
        const MaskStats& s = stats[k];
        std::printf("| %s | %s | %zu | %zu | %s | %s | %s | %s |\n", models[k].name.c_str(),
                    models[k].Input().c_str(), s.model_instances, s.ref_instances,
                    s.MeanIou().c_str(), s.Matched().c_str(), s.Confident().c_str(),
                    s.ConfIou().c_str());
      }
      std::printf("\n");
    }

    // 3. + 4. Every frame of the sequence.
    std::vector<MaskStats> stats(models.size());
    std::vector<Recall> recall(models.size());
    size_t labelled_frames = 0;
    const size_t n = range.end - range.first;
    for (size_t i = range.first; i < range.end; ++i) {
      std::fprintf(stderr, "\rsequence: frame %zu (%zu/%zu)   ", i, i - range.first + 1, n);
      const cv::Mat frame = dataset.has_color() ? dataset.LoadLeftColor(i) : dataset.LoadLeft(i);
      std::vector<const pcr::TrackedObject*> objects;
      if (with_labels && i < labels.frames.size()) {
        objects = Countable(labels.frames[i]);
        ++labelled_frames;
      }
      pcr::Segmentation ref;
      for (size_t k = 0; k < models.size(); ++k) {
        const auto t = std::chrono::steady_clock::now();
        pcr::Segmentation seg = models[k].segmenter->Segment(frame);
        stats[k].segment_ms.push_back(pcr::MsSince(t));
        if (k == 0) ref = seg;
        stats[k].Add(ref, seg, policy);
        recall[k].Add(objects, seg.instances);
      }
    }
    std::fprintf(stderr, "\n");
    std::printf(
        "### Masks on %s frames %zu:%zu (%zu) against %s (dynamic classes; Segment() with %d "
        "thread(s))\n\n| model | input HxW | Segment() median ms | instances | ref instances | "
        "mean IoU | matched IoU>=0.5 | ref conf>=0.5: mean IoU / matched | conf IoU |\n"
        "|---|---|---|---|---|---|---|---|---|\n",
        dataset.name.c_str(), range.first, range.end, n, models.front().name.c_str(),
        args.threads.back());
    for (size_t k = 0; k < models.size(); ++k) {
      const MaskStats& s = stats[k];
      std::printf("| %s | %s | %.1f | %zu | %zu | %s | %s | %s | %s |\n", models[k].name.c_str(),
                  models[k].Input().c_str(), Percentile(s.segment_ms, 0.5), s.model_instances,
                  s.ref_instances, s.MeanIou().c_str(), s.Matched().c_str(), s.Confident().c_str(),
                  s.ConfIou().c_str());
    }
    std::printf("\n");
    if (with_labels) {
      std::printf(
          "### Recall against %s (%zu labelled frames; box IoU >= 0.5 with an instance of a "
          "matching class)\n\n| model | input HxW | %s | %s | %s | cyclists, person+bicycle "
          "joint box too |\n|---|---|---|---|---|---|\n",
          Basename(args.labels).c_str(), labelled_frames, kGroupNames[0], kGroupNames[1],
          kGroupNames[2]);
      for (size_t k = 0; k < models.size(); ++k) {
        std::printf("| %s | %s | %s | %s | %s | %s |\n", models[k].name.c_str(),
                    models[k].Input().c_str(), recall[k].Cell(kVehicles).c_str(),
                    recall[k].Cell(kCyclists).c_str(), recall[k].Cell(kPedestrians).c_str(),
                    recall[k].CyclistsJoint().c_str());
      }
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_masks: %s\n", e.what());
    return 1;
  }
}
