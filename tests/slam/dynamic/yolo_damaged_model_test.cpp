// A damaged YOLOv8 model (an initializer's raw_data shorter than its dims) is refused by
// YoloSegmenter before any engine sees it: OpenCV DNN 4.6 would build the weight over the short
// data with the declared dims, read past it and run with garbage masks.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iterator>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/dynamic/onnx_model.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "support/data_paths.h"
#include "support/onnx_damage.h"
#include "support/onnx_writer.h"

namespace pcr {
namespace {

using test::Bytes;

Bytes ReadModelBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

const char* const kTensor = test::kDamagedTensor;

void ExpectRefusedNamingTheTensor(const YoloOptions& options) {
  try {
    const YoloSegmenter segmenter(options);
    ADD_FAILURE() << "the damaged model was accepted (" << segmenter.backend() << ")";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), options.model_path);
    const std::string what = e.what();
    EXPECT_NE(what.find(options.model_path), std::string::npos) << what;
    EXPECT_NE(what.find(std::string("tensor '") + kTensor + "' has 8192 values for 16384 elements"),
              std::string::npos)
        << what;
  }
}

TEST(YoloDamagedModel, OpenCvEngineRefusesAShortInitializerNamingIt) {
  YoloOptions options;
  options.model_path = test::WriteDamagedYoloModel();
  options.allow_cuda = false;
  ExpectRefusedNamingTheTensor(options);  // the default engine: OpenCV DNN
}

// The check comes before any engine is made, so every engine gives the same error.
TEST(YoloDamagedModel, NoEngineIsMadeForADamagedModel) {
  YoloOptions options;
  options.model_path = test::WriteDamagedYoloModel();
  int engines_made = 0;
  options.engine_factory = [&](const std::vector<uint8_t>& bytes, cv::Size size) {
    ++engines_made;
    return MakeOpenCvDnnEngine(bytes, size, false);
  };
  ExpectRefusedNamingTheTensor(options);
  EXPECT_EQ(engines_made, 0);
}

TEST(YoloDamagedModel, InputShapeReaderChecksEveryInitializerWithoutDecodingIt) {
  const std::string intact_path = test::SharedPath("models/yolov8n-seg_coco_384x1280.onnx");
  const Bytes intact = ReadModelBytes(intact_path);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(OnnxGraphInputShape(intact), (std::vector<int64_t>{1, 3, 384, 1280}));
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("OnnxGraphInputShape with the initializer check on %s: %.2f ms\n",
              intact_path.c_str(), ms);

  const Bytes damaged = ReadModelBytes(test::WriteDamagedYoloModel());
  try {
    OnnxGraphInputShape(damaged);
    ADD_FAILURE() << "the short initializer was not noticed";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(kTensor), std::string::npos) << e.what();
  }
}

// Raw data of the types read without values (int8, float16, ...) is checked against the dims as
// well: OpenCV DNN would read past it just the same.
TEST(YoloDamagedModel, ShortRawDataOfOtherTypesIsRefused) {
  using test::BytesField;
  using test::Cat;
  using test::VarintField;
  const auto model = [](const Bytes& tensor) {
    return test::OnnxWriter().Input("images", {1, 3, 32, 32}).RawInitializer(tensor).Model();
  };
  // TensorProto{dims = 4, data_type = int8 (3), name = "q", raw_data = 4 or 2 bytes}.
  const auto int8 = [](const Bytes& raw) {
    return Cat(
        {VarintField(1, 4), VarintField(2, 3), BytesField(8, test::Str("q")), BytesField(9, raw)});
  };
  EXPECT_EQ(OnnxGraphInputShape(model(int8({1, 2, 3, 4}))), (std::vector<int64_t>{1, 3, 32, 32}));
  EXPECT_EQ(ParseOnnxModel(model(int8({1, 2, 3, 4}))).initializers.size(), 1u);
  for (const auto& read :
       {std::function<void(const Bytes&)>([](const Bytes& b) { OnnxGraphInputShape(b); }),
        std::function<void(const Bytes&)>([](const Bytes& b) { ParseOnnxModel(b); })}) {
    try {
      read(model(int8({1, 2})));
      ADD_FAILURE() << "2 bytes of raw data accepted for 4 int8 elements";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("tensor 'q' has 2 bytes of raw data for 4 elements"),
                std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace pcr
