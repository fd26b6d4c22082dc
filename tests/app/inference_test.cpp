#include "app/inference.h"

#include <gtest/gtest.h>

#include "gpu/executor.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::app {
namespace {

TEST(Inference, OpenCvIsTheDefaultEngineAndTwinPlugsInTheExecutor) {
  YoloOptions yolo;
  yolo.model_path = test::SharedPath("models/yolov8n-seg_coco_224x640.onnx");
  yolo.allow_cuda = false;
  ApplyInference("opencv", &yolo);
  EXPECT_FALSE(yolo.engine_factory);
  EXPECT_EQ(YoloSegmenter(yolo).backend(), "opencv-dnn-cpu");
  ApplyInference("twin", &yolo);
  ASSERT_TRUE(yolo.engine_factory);
  EXPECT_EQ(YoloSegmenter(yolo).backend(), "pcr-cpu-twin");
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
    ApplyInference("auto", &yolo);  // falls back to OpenCV DNN
    EXPECT_FALSE(yolo.engine_factory);
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

}  // namespace
}  // namespace pcr::app
