#include "slam/dynamic/onnx_model.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <map>

#include "support/data_paths.h"
#include "support/onnx_writer.h"

namespace pcr {
namespace {

using test::BytesField;
using test::Cat;
using test::OnnxAttr;
using test::OnnxWriter;
using test::Str;
using test::VarintField;

TEST(OnnxModel, ReadsNodesAttributesInitializersAndOpset) {
  const auto bytes =
      OnnxWriter()
          .Input("x", {1, 3, -1, 8})
          .Floats("w", {2, 3}, {1, 2, 3, 4, 5, 6.5f})
          .Ints("shape", {2}, {-1, 6})
          .Node("Conv", {"x", "w", ""}, {"y"},
                {OnnxAttr::Ints("pads", {1, 2, 1, 2}), OnnxAttr::Int("group", 1),
                 OnnxAttr::Float("alpha", 0.25f), OnnxAttr::String("auto_pad", "NOTSET")})
          .Output("y", {1, 2, 4, 8})
          .Model(13);
  const OnnxModel m = ParseOnnxModel(bytes);
  EXPECT_EQ(m.opset, 13);
  ASSERT_EQ(m.inputs.size(), 1u);  // initializers are not inputs
  EXPECT_EQ(m.inputs[0].name, "x");
  EXPECT_EQ(m.inputs[0].dims, (std::vector<int64_t>{1, 3, -1, 8}));
  ASSERT_EQ(m.outputs.size(), 1u);
  EXPECT_EQ(m.outputs[0].dims, (std::vector<int64_t>{1, 2, 4, 8}));
  ASSERT_EQ(m.initializers.size(), 2u);
  EXPECT_TRUE(m.initializers[0].is_float());
  EXPECT_EQ(m.initializers[0].floats, (std::vector<float>{1, 2, 3, 4, 5, 6.5f}));
  EXPECT_TRUE(m.initializers[1].is_int());
  EXPECT_EQ(m.initializers[1].ints, (std::vector<int64_t>{-1, 6}));
  ASSERT_EQ(m.nodes.size(), 1u);
  const OnnxNode& n = m.nodes[0];
  EXPECT_EQ(n.op_type, "Conv");
  EXPECT_EQ(n.inputs, (std::vector<std::string>{"x", "w", ""}));
  EXPECT_EQ(n.Ints("pads"), (std::vector<int64_t>{1, 2, 1, 2}));
  EXPECT_EQ(n.Int("group", 7), 1);
  EXPECT_EQ(n.Int("missing", 7), 7);
  EXPECT_FLOAT_EQ(n.Float("alpha", 0.0f), 0.25f);
  EXPECT_EQ(n.String("auto_pad", ""), "NOTSET");
}

TEST(OnnxModel, RejectsExternalDataWrongSizesAndGarbage) {
  // TensorProto{dims = 2, data_type = float, name = "w", float_data = 1 value, ...}.
  const auto short_tensor = Cat({VarintField(1, 2), VarintField(2, 1), BytesField(8, Str("w")),
                                 BytesField(9, {0, 0, 128, 63})});
  const auto model = [](const test::Bytes& tensor) {
    return Cat({VarintField(1, 8), BytesField(7, BytesField(5, tensor))});
  };
  EXPECT_THROW(ParseOnnxModel(model(short_tensor)), std::invalid_argument);
  const auto external =
      Cat({VarintField(1, 1), VarintField(2, 1), BytesField(8, Str("w")), VarintField(14, 1)});
  try {
    ParseOnnxModel(model(external));
    FAIL() << "external data accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("external"), std::string::npos) << e.what();
  }
  // Other data types (float16 here) are read without values; the lowering refuses them when used.
  const auto half =
      Cat({VarintField(1, 1), VarintField(2, 10), BytesField(8, Str("h")), BytesField(9, {0, 60})});
  const OnnxModel m = ParseOnnxModel(model(half));
  ASSERT_EQ(m.initializers.size(), 1u);
  EXPECT_EQ(m.initializers[0].data_type, 10);
  EXPECT_FALSE(m.initializers[0].is_float() || m.initializers[0].is_int());
  EXPECT_TRUE(m.initializers[0].floats.empty());
  EXPECT_THROW(ParseOnnxModel(Str("# not a model")), std::invalid_argument);
  EXPECT_THROW(ParseOnnxModel(VarintField(1, 8)), std::invalid_argument);  // no graph
}

TEST(OnnxModel, ReadsTheRealYolov8SegExport) {
  const std::string path = test::SharedPath("models/yolov8n-seg_coco_224x640.onnx");
  std::ifstream in(path, std::ios::binary);
  ASSERT_TRUE(in) << path;
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  const OnnxModel m = ParseOnnxModel(bytes);
  EXPECT_EQ(m.opset, 17);
  std::map<std::string, int> ops;
  for (const OnnxNode& n : m.nodes) ++ops[n.op_type];
  EXPECT_EQ(ops["Conv"], 76);
  EXPECT_EQ(ops["Sigmoid"], 67);
  EXPECT_EQ(ops["ConvTranspose"], 1);
  EXPECT_EQ(m.initializers.size(), 171u);
  int64_t weights = 0;
  for (const OnnxTensor& t : m.initializers) weights += t.is_float() ? t.ElementCount() : 0;
  EXPECT_GT(weights, 3'000'000);  // YOLOv8n-seg has 3.4 M parameters
  ASSERT_EQ(m.inputs.size(), 1u);
  EXPECT_EQ(m.inputs[0].dims, (std::vector<int64_t>{1, 3, 224, 640}));
  ASSERT_EQ(m.outputs.size(), 2u);
  EXPECT_EQ(m.outputs[1].dims, (std::vector<int64_t>{1, 32, 56, 160}));
}

}  // namespace
}  // namespace pcr
