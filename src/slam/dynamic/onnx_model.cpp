#include "slam/dynamic/onnx_model.h"

#include <cstring>
#include <set>
#include <stdexcept>

namespace pcr {
namespace {

// ---- Minimal protobuf wire-format walker ----

// The n-byte little-endian unsigned integer at p (n <= 8), as protobuf stores fixed-size values.
uint64_t LittleEndian(const uint8_t* p, size_t n) {
  uint64_t value = 0;
  for (size_t k = 0; k < n; ++k) value |= static_cast<uint64_t>(p[k]) << (8 * k);
  return value;
}

struct WireField {
  uint32_t number = 0;
  int wire_type = 0;
  uint64_t varint = 0;            // wire type 0
  const uint8_t* data = nullptr;  // wire type 2
  size_t size = 0;                // wire type 2
  uint64_t fixed = 0;             // wire types 1 (64 bits) and 5 (32 bits), little-endian
};

class WireReader {
 public:
  WireReader(const uint8_t* begin, size_t size) : begin_(begin), p_(begin), end_(begin + size) {}

  // Next field, false at the end; throws std::invalid_argument on malformed input.
  bool Next(WireField* f) {
    if (p_ == end_) return false;
    const uint64_t key = Varint();
    f->number = static_cast<uint32_t>(key >> 3);
    f->wire_type = static_cast<int>(key & 7);
    if (f->number == 0 || (key >> 3) > 0x1FFFFFFF) Fail("bad field number");
    switch (f->wire_type) {
      case 0:
        f->varint = Varint();
        break;
      case 1:
        f->fixed = Fixed(8);
        break;
      case 2: {
        const uint64_t len = Varint();
        if (len > static_cast<uint64_t>(end_ - p_)) Fail("length past the end");
        f->data = p_;
        f->size = static_cast<size_t>(len);
        p_ += len;
        break;
      }
      case 5:
        f->fixed = Fixed(4);
        break;
      default:
        Fail("unsupported wire type " + std::to_string(f->wire_type));
    }
    return true;
  }

 private:
  uint64_t Varint() {
    uint64_t value = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (p_ == end_) Fail("truncated varint");
      const uint8_t byte = *p_++;
      value |= static_cast<uint64_t>(byte & 0x7F) << shift;
      if ((byte & 0x80) == 0) return value;
    }
    Fail("varint too long");
    return 0;
  }
  uint64_t Fixed(size_t n) {
    if (n > static_cast<size_t>(end_ - p_)) Fail("truncated fixed-size field");
    const uint64_t value = LittleEndian(p_, n);
    p_ += n;
    return value;
  }

 public:
  // Varints packed into a length-delimited field (or one plain varint field).
  static std::vector<uint64_t> PackedVarints(const WireField& f) {
    if (f.wire_type == 0) return {f.varint};
    WireReader r(f.data, f.size);
    std::vector<uint64_t> values;
    while (r.p_ != r.end_) values.push_back(r.Varint());
    return values;
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    throw std::invalid_argument("protobuf " + what + " at byte " + std::to_string(p_ - begin_));
  }

  const uint8_t* begin_;
  const uint8_t* p_;
  const uint8_t* end_;
};

// Length-delimited sub-message of `f` as a reader.
WireReader Sub(const WireField& f) { return WireReader(f.data, f.size); }

std::string AsString(const WireField& f) {
  return std::string(reinterpret_cast<const char*>(f.data), f.size);
}

// ValueInfoProto{name = 1, type = 2}; TypeProto{tensor_type = 1}; Tensor{shape = 2};
// TensorShapeProto{dim = 1}; Dimension{dim_value = 1, dim_param = 2}.
std::vector<int64_t> DimsOfValueInfo(const WireField& value_info) {
  std::vector<int64_t> dims;
  WireReader vi = Sub(value_info);
  WireField f;
  while (vi.Next(&f)) {
    if (f.number != 2 || f.wire_type != 2) continue;
    WireReader type = Sub(f);
    WireField t;
    while (type.Next(&t)) {
      if (t.number != 1 || t.wire_type != 2) continue;
      WireReader tensor = Sub(t);
      WireField s;
      while (tensor.Next(&s)) {
        if (s.number != 2 || s.wire_type != 2) continue;
        WireReader shape = Sub(s);
        WireField d;
        while (shape.Next(&d)) {
          if (d.number != 1 || d.wire_type != 2) continue;
          int64_t value = -1;
          WireReader dim = Sub(d);
          WireField v;
          while (dim.Next(&v)) {
            if (v.number == 1 && v.wire_type == 0) value = static_cast<int64_t>(v.varint);
          }
          dims.push_back(value > 0 ? value : -1);
        }
      }
    }
  }
  return dims;
}

std::string NameOf(const WireField& message, uint32_t name_field) {
  WireReader r = Sub(message);
  WireField f;
  std::string name;
  while (r.Next(&f)) {
    if (f.number == name_field && f.wire_type == 2) name = AsString(f);
  }
  return name;
}

float FloatOfFixed32(uint64_t bits) {
  const uint32_t b = static_cast<uint32_t>(bits);
  float value;
  std::memcpy(&value, &b, sizeof(value));
  return value;
}

double DoubleOfFixed64(uint64_t bits) {
  double value;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

void AppendInts(const WireField& f, std::vector<int64_t>* out) {
  for (uint64_t v : WireReader::PackedVarints(f)) out->push_back(static_cast<int64_t>(v));
}

// Repeated float (width 4) or double (width 8, narrowed to float): one fixed-size field (wire
// type 5 or 1) or a packed run (wire type 2).
void AppendReals(const WireField& f, size_t width, std::vector<float>* out) {
  const auto value = [width](uint64_t bits) {
    return width == 4 ? FloatOfFixed32(bits) : static_cast<float>(DoubleOfFixed64(bits));
  };
  if (f.wire_type == (width == 4 ? 5 : 1)) {
    out->push_back(value(f.fixed));
    return;
  }
  if (f.wire_type != 2 || f.size % width != 0) {
    throw std::invalid_argument(width == 4 ? "bad packed float field" : "bad packed double field");
  }
  for (size_t k = 0; k < f.size; k += width) out->push_back(value(LittleEndian(f.data + k, width)));
}

// Bytes per element of raw_data for the fixed-size TensorProto.DataType values; 0 for string and
// unknown types.
size_t RawElementBytes(int data_type) {
  switch (data_type) {
    case 2:   // uint8
    case 3:   // int8
    case 9:   // bool
    case 17:  // float8e4m3fn
    case 18:  // float8e4m3fnuz
    case 19:  // float8e5m2
    case 20:  // float8e5m2fnuz
      return 1;
    case 4:   // uint16
    case 5:   // int16
    case 10:  // float16
    case 16:  // bfloat16
      return 2;
    case OnnxTensor::kFloat:
    case OnnxTensor::kInt32:
    case 12:  // uint32
      return 4;
    case OnnxTensor::kInt64:
    case OnnxTensor::kDouble:
    case 13:  // uint64
    case 14:  // complex64
      return 8;
    case 15:  // complex128
      return 16;
    default:
      return 0;
  }
}

// TensorProto{dims = 1, data_type = 2, float_data = 4, int32_data = 5, int64_data = 7, name = 8,
// raw_data = 9, double_data = 10, data_location = 14}. Without decode_values, raw_data is only
// checked against the dims (the values stay empty): the check costs no copy of the weights.
OnnxTensor ParseTensor(const WireField& message, bool decode_values = true) {
  OnnxTensor t;
  WireReader r = Sub(message);
  WireField f;
  const uint8_t* raw = nullptr;
  size_t raw_size = 0;
  bool external = false;
  while (r.Next(&f)) {
    switch (f.number) {
      case 1:
        AppendInts(f, &t.dims);
        break;
      case 2:
        t.data_type = static_cast<int>(f.varint);
        break;
      case 4:
        AppendReals(f, 4, &t.floats);
        break;
      case 5:
      case 7:
        AppendInts(f, &t.ints);
        break;
      case 8:
        if (f.wire_type == 2) t.name = AsString(f);
        break;
      case 9:
        if (f.wire_type == 2) {
          raw = f.data;
          raw_size = f.size;
        }
        break;
      case 10:
        AppendReals(f, 8, &t.floats);
        break;
      case 14:
        external = f.wire_type == 0 && f.varint == 1;
        break;
      default:
        break;
    }
  }
  if (external) {
    throw std::invalid_argument("tensor '" + t.name +
                                "' keeps its data in an external file (not supported)");
  }
  int64_t elements = 1;
  for (int64_t d : t.dims) {
    if (d < 0) throw std::invalid_argument("tensor '" + t.name + "' has a negative dim");
    // No initializer holds 2^40 values: this only keeps ElementCount() from overflowing.
    if (d != 0 && elements > (int64_t{1} << 40) / d) {
      throw std::invalid_argument("tensor '" + t.name + "' has implausibly large dims");
    }
    elements *= d;
  }
  if (!t.is_float() && !t.is_int()) {
    // Kept without values (e.g. int8, float16), but raw data of the wrong size is refused as for
    // the types read here: another reader (OpenCV DNN) would trust the dims and read past it.
    const size_t width = RawElementBytes(t.data_type);
    if (raw && width > 0 && raw_size != static_cast<size_t>(elements) * width) {
      throw std::invalid_argument("tensor '" + t.name + "' has " + std::to_string(raw_size) +
                                  " bytes of raw data for " + std::to_string(elements) +
                                  " elements of " + std::to_string(width) + " bytes");
    }
    return t;
  }
  size_t undecoded = 0;  // values of raw_data left undecoded
  const size_t width = RawElementBytes(t.data_type);
  if (raw && raw_size % width != 0) {
    throw std::invalid_argument("tensor '" + t.name + "' raw data is not whole elements");
  }
  if (raw && !decode_values) undecoded = raw_size / width;
  if (raw && decode_values) {
    for (size_t k = 0; k < raw_size; k += width) {
      const uint64_t bits = LittleEndian(raw + k, width);
      switch (t.data_type) {
        case OnnxTensor::kFloat:
          t.floats.push_back(FloatOfFixed32(bits));
          break;
        case OnnxTensor::kDouble:
          t.floats.push_back(static_cast<float>(DoubleOfFixed64(bits)));
          break;
        case OnnxTensor::kInt32:
          t.ints.push_back(static_cast<int32_t>(static_cast<uint32_t>(bits)));
          break;
        default:
          t.ints.push_back(static_cast<int64_t>(bits));
          break;
      }
    }
  }
  const size_t have = undecoded + (t.is_float() ? t.floats.size() : t.ints.size());
  if (static_cast<int64_t>(have) != t.ElementCount()) {
    throw std::invalid_argument("tensor '" + t.name + "' has " + std::to_string(have) +
                                " values for " + std::to_string(t.ElementCount()) + " elements");
  }
  return t;
}

// AttributeProto{name = 1, f = 2, i = 3, s = 4, t = 5, floats = 7, ints = 8}.
OnnxAttribute ParseAttribute(const WireField& message) {
  OnnxAttribute a;
  WireReader r = Sub(message);
  WireField f;
  while (r.Next(&f)) {
    switch (f.number) {
      case 1:
        if (f.wire_type == 2) a.name = AsString(f);
        break;
      case 2:
        if (f.wire_type == 5) a.f = FloatOfFixed32(f.fixed);
        break;
      case 3:
        if (f.wire_type == 0) a.i = static_cast<int64_t>(f.varint);
        break;
      case 4:
        if (f.wire_type == 2) a.s = AsString(f);
        break;
      case 5:
        if (f.wire_type == 2) a.t.push_back(ParseTensor(f));
        break;
      case 7:
        AppendReals(f, 4, &a.floats);
        break;
      case 8:
        AppendInts(f, &a.ints);
        break;
      default:
        break;
    }
  }
  return a;
}

// NodeProto{input = 1, output = 2, name = 3, op_type = 4, attribute = 5, domain = 7}.
OnnxNode ParseNode(const WireField& message) {
  OnnxNode n;
  WireReader r = Sub(message);
  WireField f;
  while (r.Next(&f)) {
    if (f.wire_type != 2) continue;
    switch (f.number) {
      case 1:
        n.inputs.push_back(AsString(f));
        break;
      case 2:
        n.outputs.push_back(AsString(f));
        break;
      case 3:
        n.name = AsString(f);
        break;
      case 4:
        n.op_type = AsString(f);
        break;
      case 5:
        n.attributes.push_back(ParseAttribute(f));
        break;
      case 7:
        n.domain = AsString(f);
        break;
      default:
        break;
    }
  }
  return n;
}

OnnxValueInfo ParseValueInfo(const WireField& message) {
  OnnxValueInfo v;
  v.name = NameOf(message, 1);
  v.dims = DimsOfValueInfo(message);
  return v;
}

// The graph field of a ModelProto{opset_import = 8, graph = 7}; throws when there is none.
WireField GraphOf(const std::vector<uint8_t>& model_bytes, int64_t* opset) {
  WireReader model(model_bytes.data(), model_bytes.size());
  WireField f;
  bool have_graph = false;
  WireField graph;
  while (model.Next(&f)) {
    if (f.number == 7 && f.wire_type == 2) {
      graph = f;
      have_graph = true;
    }
    if (opset && f.number == 8 && f.wire_type == 2) {
      // OperatorSetIdProto{domain = 1, version = 2}; the default domain is "" (or "ai.onnx").
      WireReader o = Sub(f);
      WireField of;
      std::string domain;
      int64_t version = 0;
      while (o.Next(&of)) {
        if (of.number == 1 && of.wire_type == 2) domain = AsString(of);
        if (of.number == 2 && of.wire_type == 0) version = static_cast<int64_t>(of.varint);
      }
      if (domain.empty() || domain == "ai.onnx") *opset = version;
    }
  }
  if (!have_graph) throw std::invalid_argument("no ONNX graph in the protobuf");
  return graph;
}

}  // namespace

int64_t OnnxTensor::ElementCount() const {
  int64_t n = 1;
  for (int64_t d : dims) n *= d;
  return n;
}

const OnnxAttribute* OnnxNode::Find(const std::string& attribute) const {
  for (const OnnxAttribute& a : attributes) {
    if (a.name == attribute) return &a;
  }
  return nullptr;
}

int64_t OnnxNode::Int(const std::string& attribute, int64_t fallback) const {
  const OnnxAttribute* a = Find(attribute);
  return a ? a->i : fallback;
}

float OnnxNode::Float(const std::string& attribute, float fallback) const {
  const OnnxAttribute* a = Find(attribute);
  return a ? a->f : fallback;
}

std::string OnnxNode::String(const std::string& attribute, const std::string& fallback) const {
  const OnnxAttribute* a = Find(attribute);
  return a ? a->s : fallback;
}

std::vector<int64_t> OnnxNode::Ints(const std::string& attribute) const {
  const OnnxAttribute* a = Find(attribute);
  return a ? a->ints : std::vector<int64_t>{};
}

std::string OnnxDimsText(const std::vector<int64_t>& dims) {
  std::string text;
  for (size_t i = 0; i < dims.size(); ++i) {
    if (i) text += 'x';
    text += dims[i] < 0 ? std::string("?") : std::to_string(dims[i]);
  }
  return text;
}

OnnxModel ParseOnnxModel(const std::vector<uint8_t>& model_bytes) {
  OnnxModel model;
  const WireField graph = GraphOf(model_bytes, &model.opset);
  // GraphProto{node = 1, initializer = 5, input = 11, output = 12}.
  std::vector<WireField> inputs;
  WireReader g = Sub(graph);
  WireField f;
  while (g.Next(&f)) {
    if (f.wire_type != 2) continue;
    if (f.number == 1) model.nodes.push_back(ParseNode(f));
    if (f.number == 5) model.initializers.push_back(ParseTensor(f));
    if (f.number == 11) inputs.push_back(f);
    if (f.number == 12) model.outputs.push_back(ParseValueInfo(f));
  }
  std::set<std::string> initializer_names;
  for (const OnnxTensor& t : model.initializers) initializer_names.insert(t.name);
  for (const WireField& input : inputs) {
    OnnxValueInfo v = ParseValueInfo(input);
    if (initializer_names.count(v.name) == 0) model.inputs.push_back(std::move(v));
  }
  return model;
}

std::vector<int64_t> OnnxGraphInputShape(const std::vector<uint8_t>& model_bytes) {
  // ModelProto{graph = 7}; GraphProto{initializer = 5, input = 11}.
  const WireField graph = GraphOf(model_bytes, nullptr);
  WireField f;
  std::set<std::string> initializers;
  std::vector<WireField> inputs;
  WireReader g = Sub(graph);
  while (g.Next(&f)) {
    if (f.wire_type != 2) continue;
    if (f.number == 5) initializers.insert(ParseTensor(f, /*decode_values=*/false).name);
    if (f.number == 11) inputs.push_back(f);
  }
  for (const WireField& input : inputs) {
    if (initializers.count(NameOf(input, 1)) == 0) return DimsOfValueInfo(input);
  }
  throw std::invalid_argument("the ONNX graph has no input");
}

}  // namespace pcr
