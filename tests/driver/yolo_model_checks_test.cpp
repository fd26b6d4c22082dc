// The checks of a YOLO model agree across the inference engines and `pcr_orb info --model`: a
// damaged model is refused by every engine with one error, and info says an engine runs a model
// only when the segmenter accepts that engine's outputs.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "driver/inference.h"
#include "gpu/executor.h"
#include "pcr_orb_command.h"
#include "slam/common/error.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "support/data_paths.h"
#include "support/onnx_damage.h"
#include "support/onnx_writer.h"

namespace pcr {
namespace {

TEST(YoloModelChecks, EveryEngineRefusesADamagedModelWithTheSameError) {
  YoloOptions yolo;
  yolo.model_path = test::WriteDamagedYoloModel();
  yolo.allow_cuda = false;
  std::vector<std::string> engines = {"opencv", "twin"};
  if (gpu::OneDnnBuilt()) engines.push_back("onednn");
  std::vector<std::string> errors;
  for (const std::string& engine : engines) {
    SCOPED_TRACE(engine);
    driver::ApplyInference(engine, &yolo);
    try {
      const YoloSegmenter segmenter(yolo);
      ADD_FAILURE() << "runs on " << segmenter.backend();
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), yolo.model_path);
      errors.push_back(e.what());
    }
  }
  ASSERT_EQ(errors.size(), engines.size());
  EXPECT_NE(errors[0].find(std::string("tensor '") + test::kDamagedTensor +
                           "' has 8192 values for 16384 elements"),
            std::string::npos)
      << errors[0];
  for (const std::string& e : errors) EXPECT_EQ(e, errors[0]);

  // info refuses it with the same words.
  const test::CommandOutput r =
      test::RunPcrOrb("--log-level error info --model " + yolo.model_path);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(errors[0]), std::string::npos) << r.err;
}

// Outputs 1x84x5120 and 1x32x84x160 (two Reshapes of the input): every op lowers, but 84 channels
// are 4 + 48 classes + 32 mask coefficients, not the 80 COCO classes the segmenter has.
TEST(YoloModelChecks, InfoSaysNoEngineRunsAModelOfTheWrongYoloLayout) {
  const test::Bytes model = test::OnnxWriter()
                                .Input("images", {1, 3, 224, 640})
                                .Ints("shape0", {3}, {1, 84, 5120})
                                .Ints("shape1", {4}, {1, 32, 84, 160})
                                .Node("Reshape", {"images", "shape0"}, {"output0"})
                                .Node("Reshape", {"images", "shape1"}, {"output1"})
                                .Output("output0", {1, 84, 5120})
                                .Output("output1", {1, 32, 84, 160})
                                .Model();
  const std::string path = test::MakeTempDir("yolo_layout") + "/seg48.onnx";
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(model.data()),
             static_cast<std::streamsize>(model.size()));

  const test::CommandOutput r = test::RunPcrOrb("--log-level off info --model " + path);
  EXPECT_EQ(r.status, 0) << r.err;
  const std::string layout_error =
      "84 detection channels = 4 + 48 classes + 32 mask coefficients, but there are 80 class names";
  for (const char* engine : {"opencv:", "pcr executor:"}) {
    const std::string line = test::LineStartingWith(r.out, engine);
    EXPECT_NE(line.find("cannot run it: " + path), std::string::npos) << r.out;
    EXPECT_NE(line.find(layout_error), std::string::npos) << r.out;
  }
  const std::string onednn = test::LineStartingWith(r.out, "onednn:");
  if (gpu::OneDnnBuilt()) {
    EXPECT_NE(onednn.find(layout_error), std::string::npos) << r.out;
  } else {
    EXPECT_NE(onednn.find("unavailable"), std::string::npos) << r.out;
  }
  EXPECT_EQ(test::LineStartingWith(r.out, "cuda:").find("--inference cuda"), std::string::npos)
      << r.out;
  // There is none, and the line says why.
  const std::string layout = test::LineStartingWith(r.out, "YOLO layout:");
  EXPECT_NE(layout.find("none the segmenter takes"), std::string::npos) << r.out;
  EXPECT_NE(layout.find(layout_error), std::string::npos) << r.out;

  // The segmenter does refuse it on the executor (the twin), as info says.
  YoloOptions yolo;
  yolo.model_path = path;
  driver::ApplyInference("twin", &yolo);
  try {
    const YoloSegmenter segmenter(yolo);
    ADD_FAILURE() << "the twin runs it";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(layout_error), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pcr
