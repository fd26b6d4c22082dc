#include "driver/inference.h"

#include <gtest/gtest.h>

#include "gpu/executor.h"
#include "graph/pipeline.h"
#include "io/dataset.h"
#include "nodes/filter_node.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

TEST(Inference, OpenCvTwinAndOneDnnEachGiveTheirEngine) {
  YoloOptions yolo;
  yolo.model_path = test::SharedPath("models/yolov8n-seg_coco_224x640.onnx");
  yolo.allow_cuda = false;
  ApplyInference("opencv", &yolo);
  EXPECT_FALSE(yolo.engine_factory);
  EXPECT_EQ(YoloSegmenter(yolo).backend(), "opencv-dnn-cpu");
  ApplyInference("twin", &yolo);
  ASSERT_TRUE(yolo.engine_factory);
  EXPECT_EQ(YoloSegmenter(yolo).backend(), "pcr-cpu-twin");
  if (gpu::OneDnnBuilt()) {
    ApplyInference("onednn", &yolo);
    ASSERT_TRUE(yolo.engine_factory);
    EXPECT_EQ(YoloSegmenter(yolo).backend(), "pcr-cpu-onednn");
  } else {
    try {
      ApplyInference("onednn", &yolo);
      FAIL() << "onednn accepted without oneDNN";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("libdnnl"), std::string::npos) << e.what();
    }
  }
}

TEST(Inference, UnknownValuesAndMissingDevicesAreConfigErrors) {
  YoloOptions yolo;
  try {
    ApplyInference("tensorrt", &yolo);
    FAIL() << "tensorrt accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("tensorrt"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ApplyInference("cuda:", &yolo), ConfigError);
  std::string why;
  if (gpu::CudaDeviceCount(&why) == 0) {
    try {
      ApplyInference("cuda", &yolo);
      FAIL() << "cuda accepted without a device";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
    ApplyInference("auto", &yolo);  // falls back to oneDNN where built, else OpenCV DNN
    EXPECT_EQ(static_cast<bool>(yolo.engine_factory), gpu::OneDnnBuilt());
    yolo.model_path = test::SharedPath("models/yolov8n-seg_coco_224x640.onnx");
    yolo.allow_cuda = false;
    EXPECT_EQ(YoloSegmenter(yolo).backend(),
              gpu::OneDnnBuilt() ? "pcr-cpu-onednn" : "opencv-dnn-cpu");
  } else {
    ApplyInference("auto", &yolo);
    EXPECT_TRUE(yolo.engine_factory);
  }
}

TEST(Inference, FlowPicksWhereTheFiltersLucasKanadeRuns) {
  DynamicFilterOptions filter;
  ApplyFlow("opencv", &filter);
  EXPECT_FALSE(filter.flow_factory);
  EXPECT_EQ(DynamicFilter(filter).flow_engine().Name(), "opencv");
  ApplyFlow("twin", &filter);
  ASSERT_TRUE(filter.flow_factory);
  EXPECT_EQ(DynamicFilter(filter).flow_engine().Name(), "cpu-twin");
  try {
    ApplyFlow("farneback", &filter);
    FAIL() << "farneback accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--flow"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("farneback"), std::string::npos) << e.what();
  }
  std::string why;
  if (gpu::CudaDeviceCount(&why) == 0) {
    try {
      ApplyFlow("cuda:0", &filter);
      FAIL() << "cuda:0 accepted without a device";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
    ApplyFlow("auto", &filter);  // falls back to OpenCV
    EXPECT_FALSE(filter.flow_factory);
  } else {
    ApplyFlow("auto", &filter);
    ASSERT_TRUE(filter.flow_factory);
    EXPECT_EQ(DynamicFilter(filter).flow_engine().Name().rfind("cuda:0", 0), 0u);
  }
}

// The LK twin waits for its passes through the graph's device wait in a pipelined run (a real
// engine on the scheduler's device path) and blocks in the sequential one: the same trajectory.
TEST(Inference, TheLkTwinOnTheGraphsDeviceWaitKeepsPoliciesIdentical) {
  const Dataset dataset = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  nodes::FrameSource source;
  source.name = dataset.name;
  source.rig = dataset.rig;
  for (int64_t i = 0; i < 8; ++i) {
    source.frame_indices.push_back(i);
    source.t_ns.push_back(dataset.t_ns[static_cast<size_t>(i)]);
  }
  source.load_left = [&dataset](int64_t i) { return dataset.LoadLeft(static_cast<size_t>(i)); };
  source.load_right = [&dataset](int64_t i) { return dataset.LoadRight(static_cast<size_t>(i)); };
  const SlamOptions slam;
  DynamicFilterOptions filter;
  ApplyFlow("twin", &filter);
  graph::PipelineResult runs[2];
  const graph::Policy policies[2] = {graph::Policy::kSequential, graph::Policy::kPipelined};
  for (int k = 0; k < 2; ++k) {
    nodes::DynamicFilterScorer scorer(source.rig, slam.orb.scale_factor, filter);
    EXPECT_EQ(scorer.FlowEngineName(), "cpu-twin");
    graph::PipelineOptions options;
    options.policy = policies[k];
    options.threads = 2;
    runs[k] = graph::RunPipeline(source, slam, options, {}, &scorer);
    ASSERT_TRUE(runs[k].error.empty()) << runs[k].error;
    ASSERT_EQ(runs[k].tracked.size(), 8u);
  }
  // Frames 1..7 track into their previous frame, two or three passes each, on the device lane
  // only where the graph installed its wait.
  EXPECT_EQ(runs[0].stats.stages.count(graph::kStageDeviceFlow), 0u);
  ASSERT_EQ(runs[1].stats.stages.count(graph::kStageDeviceFlow), 1u);
  EXPECT_GE(runs[1].stats.stages.at(graph::kStageDeviceFlow).time.count, 14u);
  EXPECT_LE(runs[1].stats.stages.at(graph::kStageDeviceFlow).time.count, 21u);
  for (size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(runs[0].tracked[i].world_from_cam.matrix(),
              runs[1].tracked[i].world_from_cam.matrix())
        << "frame " << i;
  }
}

}  // namespace
}  // namespace pcr::driver
