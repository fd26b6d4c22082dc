#include "support/onnx_writer.h"

#include <cstring>

namespace pcr::test {

void AppendVarint(Bytes* out, uint64_t v) {
  while (v >= 0x80) {
    out->push_back(static_cast<uint8_t>(v | 0x80));
    v >>= 7;
  }
  out->push_back(static_cast<uint8_t>(v));
}

Bytes VarintField(int number, uint64_t v) {
  Bytes out;
  AppendVarint(&out, static_cast<uint64_t>(number) << 3);
  AppendVarint(&out, v);
  return out;
}

Bytes BytesField(int number, const Bytes& payload) {
  Bytes out;
  AppendVarint(&out, (static_cast<uint64_t>(number) << 3) | 2);
  AppendVarint(&out, payload.size());
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}

Bytes Fixed32Field(int number, uint32_t bits) {
  Bytes out;
  AppendVarint(&out, (static_cast<uint64_t>(number) << 3) | 5);
  for (int b = 0; b < 4; ++b) out.push_back(static_cast<uint8_t>(bits >> (8 * b)));
  return out;
}

Bytes Str(const std::string& s) { return {s.begin(), s.end()}; }

Bytes Cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

Bytes ValueInfo(const std::string& name, const std::vector<int64_t>& dims) {
  Bytes shape;
  for (int64_t d : dims) {
    const auto dim = d >= 0 ? VarintField(1, static_cast<uint64_t>(d)) : BytesField(2, Str("dyn"));
    shape = Cat({shape, BytesField(1, dim)});
  }
  const auto tensor = Cat({VarintField(1, 1), BytesField(2, shape)});
  return Cat({BytesField(1, Str(name)), BytesField(2, BytesField(1, tensor))});
}

OnnxAttr OnnxAttr::Int(const std::string& name, int64_t v) {
  return {Cat(
      {BytesField(1, Str(name)), VarintField(3, static_cast<uint64_t>(v)), VarintField(20, 2)})};
}

OnnxAttr OnnxAttr::Ints(const std::string& name, const std::vector<int64_t>& v) {
  Bytes packed;
  for (int64_t x : v) AppendVarint(&packed, static_cast<uint64_t>(x));
  return {Cat({BytesField(1, Str(name)), BytesField(8, packed), VarintField(20, 7)})};
}

OnnxAttr OnnxAttr::Float(const std::string& name, float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof(bits));
  return {Cat({BytesField(1, Str(name)), Fixed32Field(2, bits), VarintField(20, 1)})};
}

OnnxAttr OnnxAttr::String(const std::string& name, const std::string& v) {
  return {Cat({BytesField(1, Str(name)), BytesField(4, Str(v)), VarintField(20, 3)})};
}

OnnxWriter& OnnxWriter::Input(const std::string& name, const std::vector<int64_t>& dims) {
  graph_ = Cat({graph_, BytesField(11, ValueInfo(name, dims))});
  return *this;
}

OnnxWriter& OnnxWriter::Output(const std::string& name, const std::vector<int64_t>& dims) {
  graph_ = Cat({graph_, BytesField(12, ValueInfo(name, dims))});
  return *this;
}

OnnxWriter& OnnxWriter::Floats(const std::string& name, const std::vector<int64_t>& dims,
                               const std::vector<float>& values) {
  Bytes t;
  for (int64_t d : dims) t = Cat({t, VarintField(1, static_cast<uint64_t>(d))});
  Bytes raw(values.size() * 4);
  std::memcpy(raw.data(), values.data(), raw.size());  // little-endian hosts, as ONNX requires
  t = Cat({t, VarintField(2, 1), BytesField(8, Str(name)), BytesField(9, raw)});
  graph_ = Cat({graph_, BytesField(5, t)});
  return *this;
}

OnnxWriter& OnnxWriter::Ints(const std::string& name, const std::vector<int64_t>& dims,
                             const std::vector<int64_t>& values) {
  Bytes t;
  for (int64_t d : dims) t = Cat({t, VarintField(1, static_cast<uint64_t>(d))});
  Bytes packed;
  for (int64_t v : values) AppendVarint(&packed, static_cast<uint64_t>(v));
  t = Cat({t, VarintField(2, 7), BytesField(7, packed), BytesField(8, Str(name))});
  graph_ = Cat({graph_, BytesField(5, t)});
  return *this;
}

OnnxWriter& OnnxWriter::RawInitializer(const Bytes& tensor_proto) {
  graph_ = Cat({graph_, BytesField(5, tensor_proto)});
  return *this;
}

OnnxWriter& OnnxWriter::Node(const std::string& op, const std::vector<std::string>& inputs,
                             const std::vector<std::string>& outputs,
                             const std::vector<OnnxAttr>& attributes) {
  Bytes n;
  for (const std::string& i : inputs) n = Cat({n, BytesField(1, Str(i))});
  for (const std::string& o : outputs) n = Cat({n, BytesField(2, Str(o))});
  n = Cat({n, BytesField(3, Str(op + "_" + std::to_string(nodes_++))), BytesField(4, Str(op))});
  for (const OnnxAttr& a : attributes) n = Cat({n, BytesField(5, a.bytes)});
  graph_ = Cat({graph_, BytesField(1, n)});
  return *this;
}

Bytes OnnxWriter::Model(int64_t opset) const {
  const Bytes opset_id =
      Cat({BytesField(1, Str("")), VarintField(2, static_cast<uint64_t>(opset))});
  return Cat({VarintField(1, 8), BytesField(2, Str("pcr-test")), BytesField(7, graph_),
              BytesField(8, opset_id)});
}

}  // namespace pcr::test
