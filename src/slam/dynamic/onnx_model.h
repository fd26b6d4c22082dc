#pragma once
// A reader for serialized ONNX models (the protobuf ModelProto, parsed from its wire format; no
// protobuf library): the graph's nodes, attributes, initializers, inputs and outputs, enough to
// lower a convolutional network for the executors in src/gpu and to read a model's input size.
#include <cstdint>
#include <string>
#include <vector>

namespace pcr {

struct OnnxTensor {
  enum DataType : int { kFloat = 1, kInt32 = 6, kInt64 = 7, kDouble = 11 };
  std::string name;
  int data_type = 0;  // TensorProto.DataType
  std::vector<int64_t> dims;
  std::vector<float> floats;  // kFloat and kDouble tensors
  std::vector<int64_t> ints;  // kInt64 and kInt32 tensors
                              // (other types, e.g. int8 or float16, are read without values)
  int64_t ElementCount() const;
  bool is_float() const { return data_type == kFloat || data_type == kDouble; }
  bool is_int() const { return data_type == kInt64 || data_type == kInt32; }
};

struct OnnxAttribute {
  std::string name;
  float f = 0.0f;
  int64_t i = 0;
  std::string s;
  std::vector<int64_t> ints;
  std::vector<float> floats;
  std::vector<OnnxTensor> t;  // at most one: the `t` field (Constant's value)
};

struct OnnxNode {
  std::string name, op_type, domain;
  std::vector<std::string> inputs, outputs;  // an empty input name is an omitted optional input
  std::vector<OnnxAttribute> attributes;

  const OnnxAttribute* Find(const std::string& attribute) const;  // null when absent
  int64_t Int(const std::string& attribute, int64_t fallback) const;
  float Float(const std::string& attribute, float fallback) const;
  std::string String(const std::string& attribute, const std::string& fallback) const;
  std::vector<int64_t> Ints(const std::string& attribute) const;  // empty when absent
};

struct OnnxValueInfo {
  std::string name;
  int elem_type = 0;
  std::vector<int64_t> dims;  // symbolic or missing dims are -1
};

struct OnnxModel {
  int64_t opset = 0;            // of the default domain
  std::vector<OnnxNode> nodes;  // topologically sorted, as ONNX requires
  std::vector<OnnxTensor> initializers;
  std::vector<OnnxValueInfo> inputs;  // graph inputs that are not initializers
  std::vector<OnnxValueInfo> outputs;
};

// Dims as text, e.g. "1x3x?x640" (symbolic or missing dims, -1, as '?').
std::string OnnxDimsText(const std::vector<int64_t>& dims);

// Throws std::invalid_argument (with the byte offset) when the bytes are not a well-formed
// ModelProto with a graph, or a tensor keeps its data outside the file (external data), or the
// data of a float or integer tensor (or the raw data of another fixed-size type) does not match
// its dims, naming the tensor.
OnnxModel ParseOnnxModel(const std::vector<uint8_t>& model_bytes);

// Dims of the first graph input (not an initializer) of a serialized ONNX ModelProto; symbolic
// or missing dims are -1. Checks every initializer as ParseOnnxModel does (external data, data
// against dims) without decoding the weights (under 1 ms for YOLOv8n-seg, decoding takes ~80), so
// that a damaged file is refused before a reader that trusts the dims (OpenCV DNN reads past short
// raw data) gets it. Throws std::invalid_argument when the bytes are not a ModelProto with a graph
// input (bad protobuf wire format, no graph, no input) or an initializer is bad (naming it).
std::vector<int64_t> OnnxGraphInputShape(const std::vector<uint8_t>& model_bytes);

}  // namespace pcr
