// The network executor's CPU twin on the real YOLOv8n-seg model against OpenCV DNN: the same
// raw tensors (within float rounding) and the same instances on a real KITTI frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <iterator>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "gpu/executor.h"
#include "gpu/net_engine.h"
#include "slam/common/error.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "support/data_paths.h"
#include "support/device_wait.h"

namespace pcr::gpu {
namespace {

const char* const kFast = "models/yolov8n-seg_coco_224x640.onnx";
const char* const kImage = "models/test_images/kitti_000008.png";

// The 224x640 model on OpenCV DNN's CPU backend, or on the executor's `device` when given.
YoloOptions Options(const std::string& device = "") {
  YoloOptions options;
  options.model_path = test::SharedPath(kFast);
  options.allow_cuda = false;
  if (!device.empty()) options.engine_factory = NetEngineFactory(device);
  return options;
}

// Largest absolute difference over rows [row_begin, row_end) of two 1 x C x N tensors (or over
// everything when rows are -1).
float MaxDiff(const cv::Mat& a, const cv::Mat& b, int row_begin = -1, int row_end = -1) {
  EXPECT_EQ(a.total(), b.total());
  const float* pa = a.ptr<float>();
  const float* pb = b.ptr<float>();
  size_t begin = 0, end = a.total();
  if (row_begin >= 0) {
    const size_t n = static_cast<size_t>(a.size[2]);
    begin = row_begin * n;
    end = row_end * n;
  }
  float worst = 0.0f;
  for (size_t i = begin; i < end; ++i) worst = std::max(worst, std::abs(pa[i] - pb[i]));
  return worst;
}

using test::BlockingWait;

// The bytes of the 224x640 model (empty when it cannot be read).
std::vector<uint8_t> ModelBytes() {
  std::ifstream in(test::SharedPath(kFast), std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(in)),
                              std::istreambuf_iterator<char>());
}

// The same instances in the same order: class, confidence, box, mask (IoU), and the same
// confidence map. `want` must have the 8-9 cars of the test frame.
void ExpectSameInstances(const Segmentation& got, const Segmentation& want) {
  ASSERT_GE(want.instances.size(), 5u);  // the frame has 8-9 cars
  ASSERT_EQ(got.instances.size(), want.instances.size());
  for (size_t i = 0; i < want.instances.size(); ++i) {
    const Instance& a = got.instances[i];
    const Instance& b = want.instances[i];
    EXPECT_EQ(a.class_name, b.class_name) << i;
    EXPECT_NEAR(a.confidence, b.confidence, 1e-4f) << i;
    EXPECT_NEAR(a.box_px.x, b.box_px.x, 0.05f) << i;
    EXPECT_NEAR(a.box_px.y, b.box_px.y, 0.05f) << i;
    EXPECT_NEAR(a.box_px.width, b.box_px.width, 0.05f) << i;
    EXPECT_NEAR(a.box_px.height, b.box_px.height, 0.05f) << i;
    const double both = cv::countNonZero(a.mask & b.mask);
    const double either = cv::countNonZero(a.mask | b.mask);
    ASSERT_GT(either, 0) << i;
    EXPECT_GT(both / either, 0.99) << i;
  }
  EXPECT_LT(cv::norm(got.dynamic_confidence, want.dynamic_confidence, cv::NORM_INF), 1e-2);
}

bool BitwiseEqual(const cv::Mat& a, const cv::Mat& b) {
  return a.total() == b.total() &&
         std::equal(a.ptr<float>(), a.ptr<float>() + a.total(), b.ptr<float>(),
                    [](float x, float y) { return std::memcmp(&x, &y, sizeof x) == 0; });
}

// The CPU executors: the twin, and the twin with oneDNN's convolutions (where the build has it).
class CpuExecutor : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == kOneDnnDevice && !OneDnnBuilt()) GTEST_SKIP() << "no oneDNN in this build";
  }
  std::string Backend() const { return GetParam() == "twin" ? "pcr-cpu-twin" : "pcr-cpu-onednn"; }
};

INSTANTIATE_TEST_SUITE_P(YoloTwin, CpuExecutor, ::testing::Values("twin", "onednn"));

TEST_P(CpuExecutor, RawOutputsMatchOpenCvDnn) {
  const cv::Mat image = cv::imread(test::SharedPath(kImage), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty()) << test::SharedPath(kImage);
  YoloSegmenter reference(Options());
  YoloSegmenter twin(Options(GetParam()));
  EXPECT_EQ(twin.backend(), Backend());
  EXPECT_EQ(twin.layout().num_anchors, reference.layout().num_anchors);
  EXPECT_EQ(twin.layout().proto_size, reference.layout().proto_size);

  LetterboxInfo letterbox;
  const cv::Mat blob = reference.Preprocess(image, &letterbox);
  const std::vector<cv::Mat> want = reference.Forward(blob);
  const std::vector<cv::Mat> got = twin.Forward(blob);
  ASSERT_EQ(got.size(), 2u);
  const float box_diff = MaxDiff(got[0], want[0], 0, 4);
  const float score_diff = MaxDiff(got[0], want[0], 4, 84);
  const float coeff_diff = MaxDiff(got[0], want[0], 84, 116);
  const float proto_diff = MaxDiff(got[1], want[1]);
  std::printf("max |%s - opencv|: boxes %.5f px, scores %.6f, coeffs %.5f, protos %.5f\n",
              GetParam().c_str(), box_diff, score_diff, coeff_diff, proto_diff);
  // Measured: twin 0.0013 px, 7e-6, 5e-6, 1e-5 (summation order differs, nothing else);
  // onednn 0.0006 px, 3e-6, 1e-5, 2e-5.
  EXPECT_LT(box_diff, 0.01f);
  EXPECT_LT(score_diff, 1e-4f);
  EXPECT_LT(coeff_diff, 1e-3f);
  EXPECT_LT(proto_diff, 1e-3f);
}

TEST_P(CpuExecutor, SegmentFindsTheSameInstances) {
  const cv::Mat image = cv::imread(test::SharedPath(kImage), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(image.empty()) << test::SharedPath(kImage);
  YoloSegmenter reference(Options());
  YoloSegmenter twin(Options(GetParam()));
  const Segmentation want = reference.Segment(image);
  const Segmentation got = twin.Segment(image);
  EXPECT_EQ(got.backend, Backend());
  ExpectSameInstances(got, want);
}

TEST(YoloTwin, SharedStorageGivesBitwiseTheSameOutputsInAFractionOfTheMemory) {
  const std::vector<uint8_t> bytes = ModelBytes();
  ASSERT_FALSE(bytes.empty()) << test::SharedPath(kFast);
  auto shared = std::make_shared<const NetPlan>(BuildNetPlan(bytes, 224, 640, true));
  auto separate = std::make_shared<const NetPlan>(BuildNetPlan(bytes, 224, 640, false));
  EXPECT_EQ(shared->steps.size(), separate->steps.size());
  EXPECT_EQ(shared->tensors, separate->tensors);
  const double shared_mib = ActivationFloats(*shared) * 4.0 / (1 << 20);
  const double separate_mib = ActivationFloats(*separate) * 4.0 / (1 << 20);
  std::printf("activations: %.1f MiB shared, %.1f MiB one buffer per tensor (%d tensors)\n",
              shared_mib, separate_mib, shared->tensors);
  // Measured: 33.3 of 69.7 MiB at 224x640; 19.7 MiB of it is the scratch of the largest im2col
  // (the prototype head's 3x3 conv, 576 x 8960), the tensors' peak live set is 6.3 MiB.
  EXPECT_LT(shared_mib, 0.55 * separate_mib);
  std::vector<float> input(3 * 224 * 640);
  for (size_t i = 0; i < input.size(); ++i)
    input[i] = static_cast<float>((i * 7919) % 256) / 255.0f;
  const auto a = MakeTwinExecutor(shared)->Run(input.data());
  const auto b = MakeTwinExecutor(separate)->Run(input.data());
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) EXPECT_TRUE(a[k] == b[k]) << "output " << k;
}

// The row-wise copy, element-wise, resize and ConvTranspose steps of the oneDNN executor's CPU
// path compute the per-element functions' numbers exactly.
TEST(YoloTwin, RowStepsGiveBitwiseTheTwinsOutputs) {
  const std::vector<uint8_t> bytes = ModelBytes();
  ASSERT_FALSE(bytes.empty()) << test::SharedPath(kFast);
  const auto plan = std::make_shared<const NetPlan>(BuildNetPlan(bytes, 224, 640));
  std::vector<float> input(static_cast<size_t>(ShapeElements(plan->input.shape)));
  for (size_t i = 0; i < input.size(); ++i) input[i] = static_cast<float>((i * 7919) % 256) / 255;
  const auto a = MakeTwinExecutor(plan)->Run(input.data());
  const auto b = MakeTwinExecutor(plan, nullptr, /*row_steps=*/true)->Run(input.data());
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) EXPECT_TRUE(a[k] == b[k]) << "output " << k;
}

TEST(YoloTwin, ADeviceWaitGetsTheSameOutputsAndOneDonePerPass) {
  const cv::Mat image = cv::imread(test::SharedPath(kImage), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty()) << test::SharedPath(kImage);
  YoloSegmenter twin(Options("twin"));
  LetterboxInfo letterbox;
  const cv::Mat blob = twin.Preprocess(image, &letterbox);
  const std::vector<cv::Mat> blocking = twin.Forward(blob);
  BlockingWait wait;
  twin.SetDeviceWait(wait.Get());
  const std::vector<cv::Mat> waited = twin.Forward(blob);
  EXPECT_EQ(wait.waits, 1);
  EXPECT_EQ(wait.dones, 1);
  EXPECT_EQ(wait.done_thread, std::this_thread::get_id());  // the twin calls done itself
  ASSERT_EQ(waited.size(), blocking.size());
  for (size_t i = 0; i < waited.size(); ++i) EXPECT_TRUE(BitwiseEqual(waited[i], blocking[i]));
  twin.SetDeviceWait({});
  twin.Forward(blob);
  EXPECT_EQ(wait.waits, 1);  // removed: not called again
  // OpenCV DNN computes on the calling thread: it has no use for the wait; nor has the oneDNN
  // executor, CPU work of the calling stage like OpenCV's.
  YoloSegmenter opencv(Options());
  opencv.SetDeviceWait(wait.Get());
  opencv.Forward(blob);
  EXPECT_EQ(wait.waits, 1);
  if (OneDnnBuilt()) {
    YoloSegmenter onednn(Options(kOneDnnDevice));
    onednn.SetDeviceWait(wait.Get());
    onednn.Forward(blob);
    EXPECT_EQ(wait.waits, 1);
  }
}

// The threads of this process (Linux: /proc/self/task).
int ProcessThreads() {
  int n = 0;
  for ([[maybe_unused]] const auto& task : std::filesystem::directory_iterator("/proc/self/task"))
    ++n;
  return n;
}

// oneDNN fixes a convolution's thread count when its primitive is made. The kernels were made
// where cv::getNumThreads() was 2 and called from the flow graph's workers, where it is 1: each
// call still ran on 2 OpenMP threads, which on 2 busy cores made a forward pass up to 15x slower
// (1112 against 67 ms). A call now runs on the calling thread's count: on a fresh thread (its
// own OpenMP pool) a pass at 1 thread starts no thread, and one at 2 threads does (the count
// sees them).
TEST(YoloTwin, OneDnnCallsRunOnTheCallersThreadCountNotTheOneTheyWereMadeWith) {
  if (!OneDnnBuilt()) GTEST_SKIP() << "no oneDNN in this build";
  const std::vector<uint8_t> bytes = ModelBytes();
  ASSERT_FALSE(bytes.empty()) << test::SharedPath(kFast);
  const auto plan = std::make_shared<const NetPlan>(BuildNetPlan(bytes, 224, 640));
  std::vector<float> input(static_cast<size_t>(ShapeElements(plan->input.shape)));
  for (size_t i = 0; i < input.size(); ++i) input[i] = static_cast<float>((i * 7919) % 256) / 255;
  const int previous = cv::getNumThreads();
  cv::setNumThreads(2);
  const auto executor = MakeTwinExecutor(plan, MakeOneDnnConvKernels(plan), /*row_steps=*/true);
  // Threads started by one pass on a fresh thread with OpenCV's (and so oneDNN's) count `n`.
  auto started = [&](int n) {
    cv::setNumThreads(n);
    int before = 0, after = 0;
    std::vector<std::vector<float>> out;
    std::thread caller([&] {
      before = ProcessThreads();
      out = executor->Run(input.data());
      after = ProcessThreads();
    });
    caller.join();
    EXPECT_FALSE(out.empty());
    return after - before;
  };
  const int one = started(1);
  const int two = started(2);
  cv::setNumThreads(previous);
  EXPECT_EQ(one, 0) << "a pass at 1 thread started OpenMP threads";
  EXPECT_GE(two, 1) << "a pass at 2 threads started none: the count cannot see them";
}

TEST(YoloTwin, BadDeviceNamesAndUnrunnableModelsAreClearErrors) {
  EXPECT_THROW(NetEngineFactory("gpu0"), std::invalid_argument);
  EXPECT_THROW(NetEngineFactory("cuda:x"), std::invalid_argument);
  EXPECT_TRUE(IsNetEngineDevice("cuda:1"));
  EXPECT_FALSE(IsNetEngineDevice("opencv"));
  if (CudaDeviceCount() == 0) {
    try {
      YoloSegmenter segmenter(Options("cuda"));
      FAIL() << "a CUDA engine was made without a device";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("yolov8n-seg_coco_224x640.onnx"), std::string::npos) << what;
      EXPECT_NE(what.find("CUDA"), std::string::npos) << what;
    }
  }
}

// On a machine with a CUDA device (scripts/device_run.sh check): the CUDA executor against its twin
// on the real model. Skipped, saying why, elsewhere.
TEST(YoloCuda, MatchesTheTwinOnTheRealModel) {
  std::string why;
  if (CudaDeviceCount(&why) == 0) GTEST_SKIP() << "no CUDA device: " << why;
  const cv::Mat image = cv::imread(test::SharedPath(kImage), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  YoloSegmenter twin(Options("twin"));
  YoloSegmenter cuda(Options("cuda"));
  EXPECT_EQ(cuda.backend().rfind("pcr-cuda:0", 0), 0u) << cuda.backend();
  LetterboxInfo letterbox;
  const cv::Mat blob = twin.Preprocess(image, &letterbox);
  const std::vector<cv::Mat> want = twin.Forward(blob);
  for (int run = 0; run < 3; ++run) {  // buffers are reused between runs
    const std::vector<cv::Mat> got = cuda.Forward(blob);
    ASSERT_EQ(got.size(), 2u);
    // Rows as in RawOutputsMatchOpenCvDnn: boxes, class scores, mask coefficients; prototypes.
    EXPECT_LT(MaxDiff(got[0], want[0], 0, 4), 0.01f);
    EXPECT_LT(MaxDiff(got[0], want[0], 4, 84), 1e-4f);
    EXPECT_LT(MaxDiff(got[0], want[0], 84, 116), 1e-3f);
    EXPECT_LT(MaxDiff(got[1], want[1]), 1e-3f);
  }
  ExpectSameInstances(cuda.Segment(image), twin.Segment(image));
  // Through a device wait: done() comes from the CUDA runtime's callback thread.
  const std::vector<cv::Mat> blocking = cuda.Forward(blob);
  BlockingWait wait;
  cuda.SetDeviceWait(wait.Get());
  for (int run = 0; run < 3; ++run) {
    const std::vector<cv::Mat> got = cuda.Forward(blob);
    ASSERT_EQ(got.size(), 2u);
    EXPECT_TRUE(BitwiseEqual(got[0], blocking[0]));
    EXPECT_TRUE(BitwiseEqual(got[1], blocking[1]));
  }
  EXPECT_EQ(wait.waits, 3);
  EXPECT_EQ(wait.dones, 3);
  EXPECT_NE(wait.done_thread, std::this_thread::get_id());
}

}  // namespace
}  // namespace pcr::gpu
