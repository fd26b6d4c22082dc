#pragma once
// Writes ONNX ModelProto bytes (protobuf wire format) for tests: raw fields for malformed-input
// tests, and OnnxWriter for small well-formed graphs.
#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

namespace pcr::test {

using Bytes = std::vector<uint8_t>;

void AppendVarint(Bytes* out, uint64_t v);
Bytes VarintField(int number, uint64_t v);
Bytes BytesField(int number, const Bytes& payload);
Bytes Fixed32Field(int number, uint32_t bits);
Bytes Str(const std::string& s);
Bytes Cat(std::initializer_list<Bytes> parts);
// ValueInfoProto of a float tensor with the given dims (-1 = symbolic "dyn").
Bytes ValueInfo(const std::string& name, const std::vector<int64_t>& dims);

// An attribute of a node.
struct OnnxAttr {
  static OnnxAttr Int(const std::string& name, int64_t v);
  static OnnxAttr Ints(const std::string& name, const std::vector<int64_t>& v);
  static OnnxAttr Float(const std::string& name, float v);
  static OnnxAttr String(const std::string& name, const std::string& v);
  Bytes bytes;
};

class OnnxWriter {
 public:
  OnnxWriter& Input(const std::string& name, const std::vector<int64_t>& dims);
  OnnxWriter& Output(const std::string& name, const std::vector<int64_t>& dims = {});
  // Float initializers are written as raw_data, integer ones as int64_data (both encodings occur
  // in real exports).
  OnnxWriter& Floats(const std::string& name, const std::vector<int64_t>& dims,
                     const std::vector<float>& values);
  OnnxWriter& Ints(const std::string& name, const std::vector<int64_t>& dims,
                   const std::vector<int64_t>& values);
  // Any TensorProto, already serialized (e.g. an int8 or float16 initializer).
  OnnxWriter& RawInitializer(const Bytes& tensor_proto);
  OnnxWriter& Node(const std::string& op, const std::vector<std::string>& inputs,
                   const std::vector<std::string>& outputs,
                   const std::vector<OnnxAttr>& attributes = {});
  Bytes Model(int64_t opset = 17) const;

 private:
  Bytes graph_;
  int nodes_ = 0;
};

}  // namespace pcr::test
