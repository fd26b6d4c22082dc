#include "support/onnx_damage.h"

#include <cstdint>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <vector>

#include "support/data_paths.h"

namespace pcr::test {
namespace {

uint64_t ReadPbVarint(const Bytes& b, size_t* p) {
  uint64_t v = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (*p >= b.size()) throw std::runtime_error("truncated varint");
    const uint8_t byte = b[(*p)++];
    v |= static_cast<uint64_t>(byte & 0x7F) << shift;
    if ((byte & 0x80) == 0) return v;
  }
  throw std::runtime_error("varint too long");
}

struct PbField {
  int number = 0;
  int wire_type = 0;
  size_t begin = 0, end = 0;            // the whole field, key included
  size_t payload = 0, payload_end = 0;  // of a length-delimited field
};

std::vector<PbField> PbFields(const Bytes& b) {
  std::vector<PbField> fields;
  size_t p = 0;
  while (p < b.size()) {
    PbField f;
    f.begin = p;
    const uint64_t key = ReadPbVarint(b, &p);
    f.number = static_cast<int>(key >> 3);
    f.wire_type = static_cast<int>(key & 7);
    if (f.wire_type == 0) {
      ReadPbVarint(b, &p);
    } else if (f.wire_type == 1 || f.wire_type == 5) {
      p += f.wire_type == 1 ? 8 : 4;
    } else if (f.wire_type == 2) {
      const uint64_t len = ReadPbVarint(b, &p);
      if (len > b.size() - p) throw std::runtime_error("field past the end");
      f.payload = p;
      p += len;
      f.payload_end = p;
    } else {
      throw std::runtime_error("unexpected wire type");
    }
    if (p > b.size()) throw std::runtime_error("field past the end");
    f.end = p;
    fields.push_back(f);
  }
  return fields;
}

Bytes ByteSlice(const Bytes& b, size_t begin, size_t end) {
  return Bytes(b.begin() + static_cast<std::ptrdiff_t>(begin),
               b.begin() + static_cast<std::ptrdiff_t>(end));
}

// `message` with each length-delimited field `number` replaced by edit(its payload).
template <typename Edit>
Bytes EditPbFields(const Bytes& message, int number, Edit edit) {
  Bytes out;
  for (const PbField& f : PbFields(message)) {
    const Bytes part = f.number == number && f.wire_type == 2
                           ? BytesField(number, edit(ByteSlice(message, f.payload, f.payload_end)))
                           : ByteSlice(message, f.begin, f.end);
    out.insert(out.end(), part.begin(), part.end());
  }
  return out;
}

}  // namespace

Bytes HalveRawData(const Bytes& model, const std::string& tensor) {
  // ModelProto.graph = 7, GraphProto.initializer = 5, TensorProto{name = 8, raw_data = 9}.
  bool found = false;
  const Bytes out = EditPbFields(model, 7, [&](const Bytes& graph) {
    return EditPbFields(graph, 5, [&](const Bytes& t) {
      bool named = false;
      for (const PbField& f : PbFields(t)) {
        named |= f.number == 8 && ByteSlice(t, f.payload, f.payload_end) == Str(tensor);
      }
      if (!named) return t;
      found = true;
      return EditPbFields(t, 9, [](const Bytes& raw) { return ByteSlice(raw, 0, raw.size() / 2); });
    });
  });
  if (!found) throw std::runtime_error("the ONNX graph has no initializer '" + tensor + "'");
  return out;
}

std::string WriteDamagedYoloModel() {
  const std::string intact_path = SharedPath("models/yolov8n-seg_coco_224x640.onnx");
  std::ifstream in(intact_path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + intact_path);
  const Bytes intact((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const Bytes damaged = HalveRawData(intact, kDamagedTensor);
  const std::string path = MakeTempDir("onnx_damage") + "/short_weight.onnx";
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(damaged.data()),
             static_cast<std::streamsize>(damaged.size()));
  return path;
}

}  // namespace pcr::test
