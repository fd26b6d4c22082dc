// YOLOv8n-seg stages per shipped model on the KITTI test frame, OpenCV with 2 threads:
// preprocess (letterbox + blob), forward (OpenCV DNN), decode (threshold, NMS, masks, instance
// map) and the dynamic-confidence map (dilation + smoothing).
//   bench_yolo [--inference opencv|twin|cuda[:N]|auto] [--benchmark_filter=...]
//   (models and image from PCR_SHARED_DIR/models; --inference picks the engine of the forward
//   pass, as in `pcr_orb pipeline`)
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>

#include "bench_args.h"
#include "bench_main.h"
#include "driver/inference.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace {

using pcr::bench::SharedDir;

std::string& Inference() {
  static std::string inference = "opencv";
  return inference;
}

// One segmenter per model plus the intermediate results of one frame, so that each stage is
// timed on its real input.
struct ModelState {
  std::unique_ptr<pcr::YoloSegmenter> segmenter;
  cv::Mat blob;
  pcr::LetterboxInfo letterbox;
  std::vector<cv::Mat> outputs;
  std::vector<pcr::Instance> instances;
};

const cv::Mat& Frame() {
  static const cv::Mat frame = [] {
    const std::string path = SharedDir() + "/models/test_images/kitti_000008.png";
    cv::Mat image = cv::imread(path, cv::IMREAD_COLOR);
    if (image.empty()) throw std::runtime_error("cannot read " + path);
    return image;
  }();
  return frame;
}

ModelState& State(const std::string& model) {
  static std::map<std::string, ModelState> states;
  auto it = states.find(model);
  if (it != states.end()) return it->second;
  ModelState& s = states[model];
  pcr::YoloOptions options;
  options.model_path = SharedDir() + "/models/" + model;
  pcr::driver::ApplyInference(Inference(), &options);
  s.segmenter = std::make_unique<pcr::YoloSegmenter>(options);
  s.blob = s.segmenter->Preprocess(Frame(), &s.letterbox);
  s.outputs = s.segmenter->Forward(s.blob);  // also warms the network up
  s.instances = s.segmenter->Decode(s.outputs, s.letterbox);
  return s;
}

void BM_Preprocess(benchmark::State& state, const std::string& model) {
  ModelState& s = State(model);
  pcr::LetterboxInfo letterbox;
  for (auto _ : state) benchmark::DoNotOptimize(s.segmenter->Preprocess(Frame(), &letterbox));
}

void BM_Forward(benchmark::State& state, const std::string& model) {
  ModelState& s = State(model);
  for (auto _ : state) benchmark::DoNotOptimize(s.segmenter->Forward(s.blob));
}

void BM_DecodeMasks(benchmark::State& state, const std::string& model) {
  ModelState& s = State(model);
  size_t instances = 0;
  for (auto _ : state) {
    const std::vector<pcr::Instance> decoded = s.segmenter->Decode(s.outputs, s.letterbox);
    benchmark::DoNotOptimize(pcr::BuildInstanceMap(decoded, Frame().size()));
    instances = decoded.size();
  }
  state.counters["instances"] = static_cast<double>(instances);
}

void BM_ConfidenceMap(benchmark::State& state, const std::string& model) {
  ModelState& s = State(model);
  for (auto _ : state) {
    benchmark::DoNotOptimize(s.segmenter->DynamicConfidence(s.instances, Frame().size()));
  }
}

void BM_Segment(benchmark::State& state, const std::string& model) {
  ModelState& s = State(model);
  for (auto _ : state) benchmark::DoNotOptimize(s.segmenter->Segment(Frame()));
}

}  // namespace

int main(int argc, char** argv) {
  cv::setNumThreads(2);
  for (int i = 1; i + 1 < argc; ++i) {  // --inference VALUE, removed before Google Benchmark
    if (std::string(argv[i]) != "--inference") continue;
    Inference() = argv[i + 1];
    for (int k = i; k + 2 <= argc; ++k) argv[k] = argv[k + 2];
    argc -= 2;
    break;
  }
  const char* const kModels[] = {"yolov8n-seg_coco_640x640.onnx", "yolov8n-seg_coco_384x1280.onnx",
                                 "yolov8n-seg_coco_224x640.onnx"};
  for (const char* model : kModels) {
    const std::string name = std::string(model).substr(std::string("yolov8n-seg_coco_").size());
    const std::string tag = name.substr(0, name.find('.'));
    benchmark::RegisterBenchmark(("Preprocess/" + tag).c_str(), BM_Preprocess, model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(0.5);
    benchmark::RegisterBenchmark(("Forward/" + tag).c_str(), BM_Forward, model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(5)
        ->Repetitions(3)
        ->ReportAggregatesOnly(true);
    benchmark::RegisterBenchmark(("DecodeMasks/" + tag).c_str(), BM_DecodeMasks, model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(0.5);
    benchmark::RegisterBenchmark(("ConfidenceMap/" + tag).c_str(), BM_ConfidenceMap, model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->MinTime(0.5);
    benchmark::RegisterBenchmark(("Segment/" + tag).c_str(), BM_Segment, model)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(5);
  }
  return pcr::bench::RunBenchmarks("bench_yolo", argc, argv);
}
