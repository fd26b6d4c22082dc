#include "gpu/net_plan.h"

#include <algorithm>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <stdexcept>

#include "slam/dynamic/onnx_model.h"

namespace pcr::gpu {
namespace {

using Shape = std::vector<int64_t>;

// Elements of a shape; throws for a negative dim or a count past 2^40 (the executor indexes in
// 32 bits; this bound only keeps the plan-time arithmetic from overflowing).
int64_t Count(const Shape& s) {
  constexpr int64_t kLimit = int64_t{1} << 40;
  int64_t n = 1;
  for (int64_t d : s) {
    if (d < 0 || d > kLimit)
      throw std::invalid_argument("tensor dim " + std::to_string(d) + " out of range");
    if (d != 0 && n > kLimit / d) throw std::invalid_argument("tensor of more than 2^40 elements");
    n *= d;
  }
  return n;
}

std::string ShapeText(const Shape& s) {
  std::string text;
  for (size_t i = 0; i < s.size(); ++i) {
    if (i) text += 'x';
    text += std::to_string(s[i]);
  }
  return text.empty() ? "scalar" : text;
}

// A tensor known at plan time: a float buffer (computed, or constant with its data in the plan)
// or an integer constant (shapes, slice bounds), which has no buffer.
struct Value {
  Shape shape;
  int buffer = -1;
  bool is_int = false;
  std::vector<int64_t> ints;
  // An initializer of another ONNX data type (int8, float16, undefined...): -1 when supported.
  int unsupported_type = -1;
};

// Bounds on attributes and dims, so that the plan's int geometry cannot overflow.
constexpr int64_t kMaxKernel = 4096;  // kernel sizes, strides, dilations, pads
constexpr int64_t kMaxDim = 1 << 24;  // channels, heights, widths

class Lowering {
 public:
  Lowering(const OnnxModel& model, int height, int width) : model_(model) {
    if (height <= 0 || width <= 0) throw std::invalid_argument("input size must be positive");
    if (model.inputs.empty()) throw std::invalid_argument("the graph has no input");
    const OnnxValueInfo& in = model.inputs[0];
    const Shape want = {1, 3, height, width};
    if (in.dims.size() != 4) {
      throw std::invalid_argument("graph input '" + in.name + "' has rank " +
                                  std::to_string(in.dims.size()) + ", expected 1x3xHxW");
    }
    for (size_t d = 0; d < 4; ++d) {
      if (in.dims[d] > 0 && in.dims[d] != want[d]) {
        throw std::invalid_argument("graph input '" + in.name + "' is " + ShapeText(in.dims) +
                                    ", not " + ShapeText(want));
      }
    }
    plan_.input = {in.name, NewBuffer(Count(want)), want};
    values_[in.name] = Value{want, plan_.input.buffer, false, {}};
    for (const OnnxTensor& t : model.initializers) values_[t.name] = ConstantValue(t);
    for (const OnnxNode& n : model.nodes) {
      for (const std::string& i : n.inputs) ++consumers_[i];
    }
    for (const OnnxValueInfo& o : model.outputs) graph_outputs_.insert(o.name);
  }

  NetPlan Build() {
    for (size_t k = 0; k < model_.nodes.size(); ++k) {
      if (skipped_.count(k)) continue;
      const OnnxNode& n = model_.nodes[k];
      if (!n.domain.empty() && n.domain != "ai.onnx") Fail(n, "custom domain '" + n.domain + "'");
      if (n.outputs.empty() || n.outputs[0].empty()) Fail(n, "no output");
      const std::string& op = n.op_type;
      if (op == "Conv") {
        LowerConv(k);
      } else if (op == "ConvTranspose") {
        LowerConvTranspose(n);
      } else if (op == "Sigmoid") {
        const Value& x = Float(n, 0);
        const int out = Define(n, 0, x.shape);
        Emit(n, UnaryStep{x.buffer, out, Count(x.shape), Activation::kSigmoid});
      } else if (op == "Add" || op == "Sub" || op == "Mul" || op == "Div") {
        LowerBinary(n);
      } else if (op == "Concat") {
        LowerConcat(n);
      } else if (op == "Split") {
        LowerSplit(n);
      } else if (op == "Slice") {
        LowerSlice(n);
      } else if (op == "MaxPool") {
        LowerMaxPool(n);
      } else if (op == "Resize") {
        LowerResize(n);
      } else if (op == "Reshape") {
        LowerReshape(n);
      } else if (op == "Identity") {
        Alias(n, Input(n, 0).shape);
      } else if (op == "Transpose") {
        LowerTranspose(n);
      } else if (op == "Softmax") {
        LowerSoftmax(n);
      } else if (op == "Constant") {
        const OnnxAttribute* value = n.Find("value");
        if (!value || value->t.empty()) Fail(n, "Constant without a tensor 'value'");
        values_[Output(n, 0)] = ConstantValue(value->t[0]);
      } else {
        Fail(n, "unsupported op");
      }
    }
    for (const OnnxValueInfo& o : model_.outputs) {
      const auto it = values_.find(o.name);
      if (it == values_.end())
        throw std::invalid_argument("graph output '" + o.name + "' is never computed");
      if (it->second.is_int || it->second.buffer < 0 ||
          plan_.buffers[it->second.buffer].constant()) {
        throw std::invalid_argument("graph output '" + o.name + "' is a constant");
      }
      plan_.outputs.push_back({o.name, it->second.buffer, it->second.shape});
    }
    if (plan_.outputs.empty()) throw std::invalid_argument("the graph has no output");
    return std::move(plan_);
  }

 private:
  [[noreturn]] void Fail(const OnnxNode& n, const std::string& why) const {
    throw std::invalid_argument("node '" + n.name + "' (" + n.op_type + "): " + why);
  }

  int NewBuffer(int64_t size) {
    plan_.buffers.push_back(PlanBuffer{size, {}});
    return static_cast<int>(plan_.buffers.size()) - 1;
  }

  int ConstBuffer(std::vector<float> data) {
    const int64_t size = static_cast<int64_t>(data.size());
    if (size == 0) data.push_back(0.0f);  // a constant buffer is never empty
    plan_.buffers.push_back(PlanBuffer{std::max<int64_t>(size, 1), std::move(data)});
    return static_cast<int>(plan_.buffers.size()) - 1;
  }

  Value ConstantValue(const OnnxTensor& t) {
    Value v;
    v.shape = t.dims;
    if (!t.is_float() && !t.is_int()) {
      v.unsupported_type = std::max(t.data_type, 0);
    } else if (t.is_int()) {
      v.is_int = true;
      v.ints = t.ints;
    } else {
      v.buffer = ConstBuffer(t.floats);
    }
    return v;
  }

  const std::string& Output(const OnnxNode& n, size_t i) const {
    if (i >= n.outputs.size() || n.outputs[i].empty())
      Fail(n, "missing output " + std::to_string(i));
    return n.outputs[i];
  }

  bool HasInput(const OnnxNode& n, size_t i) const {
    return i < n.inputs.size() && !n.inputs[i].empty();
  }

  const Value& Input(const OnnxNode& n, size_t i) const {
    if (!HasInput(n, i)) Fail(n, "missing input " + std::to_string(i));
    const auto it = values_.find(n.inputs[i]);
    if (it == values_.end()) Fail(n, "input '" + n.inputs[i] + "' is not computed before it");
    if (it->second.unsupported_type >= 0) {
      Fail(n, "input '" + n.inputs[i] + "' has ONNX data type " +
                  std::to_string(it->second.unsupported_type) +
                  " (the executor takes float32/64 and int32/64 constants)");
    }
    return it->second;
  }

  const Value& Float(const OnnxNode& n, size_t i) const {
    const Value& v = Input(n, i);
    if (v.is_int) Fail(n, "input '" + n.inputs[i] + "' is an integer tensor");
    return v;
  }

  const std::vector<float>& ConstFloats(const OnnxNode& n, size_t i) const {
    const Value& v = Float(n, i);
    if (!plan_.buffers[v.buffer].constant())
      Fail(n, "input '" + n.inputs[i] + "' must be a constant");
    return plan_.buffers[v.buffer].data;
  }

  std::vector<int64_t> ConstInts(const OnnxNode& n, size_t i) const {
    const Value& v = Input(n, i);
    if (!v.is_int) Fail(n, "input '" + n.inputs[i] + "' must be a constant integer tensor");
    return v.ints;
  }

  // A new float buffer for output i of n.
  int Define(const OnnxNode& n, size_t i, const Shape& shape) {
    const int buffer = NewBuffer(Count(shape));
    values_[Output(n, i)] = Value{shape, buffer, false, {}};
    return buffer;
  }

  void Alias(const OnnxNode& n, const Shape& shape) {
    Value v = Input(n, 0);
    if (Count(v.shape) != Count(shape)) {
      Fail(n, "cannot view " + ShapeText(v.shape) + " as " + ShapeText(shape));
    }
    v.shape = shape;
    values_[Output(n, 0)] = v;
  }

  template <typename Step>
  void Emit(const OnnxNode& n, Step step) {
    plan_.steps.emplace_back(step);
    plan_.step_names.push_back(n.name.empty() ? n.op_type : n.name);
  }

  static int64_t Axis(const OnnxNode& n, int64_t axis, size_t rank) {
    const int64_t r = static_cast<int64_t>(rank);
    if (axis < -r || axis >= r) {
      throw std::invalid_argument("node '" + n.name + "' (" + n.op_type + "): axis " +
                                  std::to_string(axis) + " out of range for rank " +
                                  std::to_string(rank));
    }
    return axis < 0 ? axis + r : axis;
  }

  static int64_t Prod(const Shape& s, size_t begin, size_t end) {
    int64_t p = 1;
    for (size_t d = begin; d < end; ++d) p *= s[d];
    return p;
  }

  const Shape& Image(const OnnxNode& n, const Value& x) const {
    for (int64_t d : x.shape) {
      if (d < 1 || d > kMaxDim) Fail(n, "image dims out of range: " + ShapeText(x.shape));
    }
    if (x.shape.size() != 4 || x.shape[0] != 1)
      Fail(n, "expected a 1xCxHxW input, got " + ShapeText(x.shape));
    return x.shape;
  }

  void CheckWeightDims(const OnnxNode& n, const Shape& w) const {
    if (w[0] > kMaxDim || w[1] > kMaxDim || w[2] < 1 || w[2] > kMaxKernel || w[3] < 1 ||
        w[3] > kMaxKernel) {
      Fail(n, "weight dims out of range: " + ShapeText(w));
    }
  }

  void Pads2d(const OnnxNode& n, int* top, int* left) const {
    const std::string auto_pad = n.String("auto_pad", "NOTSET");
    if (auto_pad != "NOTSET" && !auto_pad.empty())
      Fail(n, "auto_pad " + auto_pad + " is not supported");
    const std::vector<int64_t> pads = n.Ints("pads");
    *top = *left = 0;
    if (pads.empty()) return;
    if (pads.size() != 4) Fail(n, "expected 4 pads");
    for (int64_t p : pads) {
      if (p < 0 || p > kMaxKernel) Fail(n, "pads out of range");
    }
    *top = static_cast<int>(pads[0]);
    *left = static_cast<int>(pads[1]);
    if (pads[2] != pads[0] || pads[3] != pads[1]) Fail(n, "asymmetric padding is not supported");
  }

  // A 2-D attribute (strides, dilations, kernel_shape): `fallback` twice when absent; each value
  // in [1, kMaxKernel].
  std::vector<int64_t> Pair(const OnnxNode& n, const std::string& attribute,
                            int64_t fallback) const {
    std::vector<int64_t> v = n.Ints(attribute);
    if (v.empty()) v = {fallback, fallback};
    if (v.size() != 2) Fail(n, "expected a 2-D " + attribute);
    for (int64_t x : v) {
      if (x < 1 || x > kMaxKernel) Fail(n, attribute + " out of range");
    }
    return v;
  }

  void LowerConv(size_t k) {
    const OnnxNode& n = model_.nodes[k];
    const Value& x = Float(n, 0);
    const Shape& xs = Image(n, x);
    const Value& w = Float(n, 1);
    if (!plan_.buffers[w.buffer].constant() || w.shape.size() != 4)
      Fail(n, "weights must be a constant 4-D tensor");
    if (n.Int("group", 1) != 1) Fail(n, "grouped convolution is not supported");
    CheckWeightDims(n, w.shape);
    if (w.shape[1] != xs[1])
      Fail(n, "weights " + ShapeText(w.shape) + " do not fit input " + ShapeText(xs));
    ConvGeometry g;
    g.c_in = static_cast<int>(xs[1]);
    g.h_in = static_cast<int>(xs[2]);
    g.w_in = static_cast<int>(xs[3]);
    g.c_out = static_cast<int>(w.shape[0]);
    g.kh = static_cast<int>(w.shape[2]);
    g.kw = static_cast<int>(w.shape[3]);
    const std::vector<int64_t> strides = Pair(n, "strides", 1);
    const std::vector<int64_t> dilations = Pair(n, "dilations", 1);
    g.stride_h = static_cast<int>(strides[0]);
    g.stride_w = static_cast<int>(strides[1]);
    g.dilation_h = static_cast<int>(dilations[0]);
    g.dilation_w = static_cast<int>(dilations[1]);
    Pads2d(n, &g.pad_top, &g.pad_left);
    // A negative span is an empty output (integer division would round it up to one row).
    const int span_h = g.h_in + 2 * g.pad_top - g.dilation_h * (g.kh - 1) - 1;
    const int span_w = g.w_in + 2 * g.pad_left - g.dilation_w * (g.kw - 1) - 1;
    if (span_h < 0 || span_w < 0) Fail(n, "empty output");
    g.h_out = span_h / g.stride_h + 1;
    g.w_out = span_w / g.stride_w + 1;
    const int bias = OptionalBias(n, g.c_out);
    const Shape out_shape = {1, g.c_out, g.h_out, g.w_out};
    ConvStep step{x.buffer, -1, w.buffer, bias, g, Activation::kNone};
    // Conv -> Sigmoid -> Mul(conv, sigmoid) is SiLU: one step instead of three.
    const OnnxNode* mul = nullptr;
    size_t sigmoid_index = 0, mul_index = 0;
    if (FindSilu(k, &sigmoid_index, &mul_index)) {
      mul = &model_.nodes[mul_index];
      skipped_.insert(sigmoid_index);
      skipped_.insert(mul_index);
      step.activation = Activation::kSilu;
      ++plan_.fused_activations;
    }
    step.out = mul ? Define(*mul, 0, out_shape) : Define(n, 0, out_shape);
    if (!IsPointwise(g)) plan_.scratch_size = std::max(plan_.scratch_size, ColRows(g) * ColCols(g));
    Emit(n, step);
  }

  // The constant bias (input 2) of a Conv or ConvTranspose, -1 when absent.
  int OptionalBias(const OnnxNode& n, int c_out) const {
    if (!HasInput(n, 2)) return -1;
    const Value& b = Float(n, 2);
    if (!plan_.buffers[b.buffer].constant() || Count(b.shape) != c_out) {
      Fail(n, "bias must be a constant of c_out values");
    }
    return b.buffer;
  }

  bool FindSilu(size_t conv_index, size_t* sigmoid_index, size_t* mul_index) const {
    const std::string& x = model_.nodes[conv_index].outputs.at(0);
    if (graph_outputs_.count(x) || Consumers(x) != 2) return false;
    for (size_t s = conv_index + 1; s < model_.nodes.size(); ++s) {
      const OnnxNode& sig = model_.nodes[s];
      if (sig.op_type != "Sigmoid" || sig.inputs.size() != 1 || sig.inputs[0] != x) continue;
      if (sig.outputs.size() != 1 || graph_outputs_.count(sig.outputs[0]) ||
          Consumers(sig.outputs[0]) != 1)
        return false;
      for (size_t m = s + 1; m < model_.nodes.size(); ++m) {
        const OnnxNode& mul = model_.nodes[m];
        if (mul.op_type != "Mul" || mul.inputs.size() != 2) continue;
        const bool match = (mul.inputs[0] == x && mul.inputs[1] == sig.outputs[0]) ||
                           (mul.inputs[1] == x && mul.inputs[0] == sig.outputs[0]);
        if (!match) continue;
        *sigmoid_index = s;
        *mul_index = m;
        return true;
      }
      return false;
    }
    return false;
  }

  int Consumers(const std::string& name) const {
    const auto it = consumers_.find(name);
    return it == consumers_.end() ? 0 : it->second;
  }

  void LowerConvTranspose(const OnnxNode& n) {
    const Value& x = Float(n, 0);
    const Shape& xs = Image(n, x);
    const Value& w = Float(n, 1);
    if (!plan_.buffers[w.buffer].constant() || w.shape.size() != 4 || w.shape[0] != xs[1]) {
      Fail(n, "weights must be a constant c_in x c_out x kh x kw tensor");
    }
    if (n.Int("group", 1) != 1) Fail(n, "grouped ConvTranspose is not supported");
    CheckWeightDims(n, w.shape);
    ConvTransposeGeometry g;
    g.c_in = static_cast<int>(xs[1]);
    g.h_in = static_cast<int>(xs[2]);
    g.w_in = static_cast<int>(xs[3]);
    g.c_out = static_cast<int>(w.shape[1]);
    g.kh = static_cast<int>(w.shape[2]);
    g.kw = static_cast<int>(w.shape[3]);
    const std::vector<int64_t> strides = Pair(n, "strides", 1);
    const std::vector<int64_t> dilations = Pair(n, "dilations", 1);
    const std::vector<int64_t> pads = n.Ints("pads");
    const std::vector<int64_t> output_padding = n.Ints("output_padding");
    const bool plain = strides[0] == g.kh && strides[1] == g.kw &&
                       dilations == std::vector<int64_t>{1, 1} &&
                       std::all_of(pads.begin(), pads.end(), [](int64_t p) { return p == 0; }) &&
                       std::all_of(output_padding.begin(), output_padding.end(),
                                   [](int64_t p) { return p == 0; }) &&
                       n.Find("output_shape") == nullptr;
    if (!plain)
      Fail(n, "only ConvTranspose with stride == kernel, no padding, no dilation is supported");
    // Repack c_in x c_out x kh x kw into (c_out*kh*kw) x c_in.
    const std::vector<float>& src = plan_.buffers[w.buffer].data;
    const int64_t taps = static_cast<int64_t>(g.c_out) * g.kh * g.kw;
    std::vector<float> packed(static_cast<size_t>(taps * g.c_in));
    for (int64_t c = 0; c < g.c_in; ++c) {
      for (int64_t t = 0; t < taps; ++t) packed[t * g.c_in + c] = src[c * taps + t];
    }
    const int bias = OptionalBias(n, g.c_out);
    const int weight = ConstBuffer(std::move(packed));
    const int out = Define(n, 0,
                           Shape{1, g.c_out, static_cast<int64_t>(g.h_in) * g.kh,
                                 static_cast<int64_t>(g.w_in) * g.kw});
    plan_.scratch_size = std::max(plan_.scratch_size, taps * g.h_in * g.w_in);
    Emit(n, ConvTransposeStep{x.buffer, out, weight, bias, g});
  }

  static Shape Broadcast(const OnnxNode& n, const Shape& a, const Shape& b) {
    const size_t rank = std::max(a.size(), b.size());
    Shape out(rank);
    for (size_t d = 0; d < rank; ++d) {
      const int64_t da = d + a.size() >= rank ? a[d + a.size() - rank] : 1;
      const int64_t db = d + b.size() >= rank ? b[d + b.size() - rank] : 1;
      if (da != db && da != 1 && db != 1) {
        throw std::invalid_argument("node '" + n.name + "' (" + n.op_type + "): shapes " +
                                    ShapeText(a) + " and " + ShapeText(b) + " do not broadcast");
      }
      out[d] = da == 1 ? db : da;  // a 0 dim broadcasts against 1 to 0
    }
    return out;
  }

  // Strides of `s` in the index space of the broadcast shape `out` (0 along broadcast axes).
  static void BroadcastStrides(const Shape& s, const Shape& out, int64_t* strides) {
    const size_t rank = out.size();
    int64_t stride = 1;
    for (size_t d = rank; d-- > 0;) {
      if (d + s.size() < rank) {
        strides[d] = 0;
        continue;
      }
      const int64_t dim = s[d + s.size() - rank];
      strides[d] = dim == 1 ? 0 : stride;
      stride *= dim;
    }
  }

  void LowerBinary(const OnnxNode& n) {
    const Value& a = Input(n, 0);
    const Value& b = Input(n, 1);
    const Shape out_shape = Broadcast(n, a.shape, b.shape);
    if (a.is_int || b.is_int) {
      if (!a.is_int || !b.is_int) Fail(n, "mixes integer and float tensors");
      FoldIntBinary(n, a, b, out_shape);
      return;
    }
    if (out_shape.size() > static_cast<size_t>(kMaxRank)) Fail(n, "rank above 6");
    BinaryGeometry g;
    g.rank = static_cast<int>(out_shape.size());
    std::copy(out_shape.begin(), out_shape.end(), g.out_shape);
    BroadcastStrides(a.shape, out_shape, g.a_strides);
    BroadcastStrides(b.shape, out_shape, g.b_strides);
    const std::string& op = n.op_type;
    g.op = op == "Add"   ? BinaryOp::kAdd
           : op == "Sub" ? BinaryOp::kSub
           : op == "Mul" ? BinaryOp::kMul
                         : BinaryOp::kDiv;
    const int a_buffer = a.buffer, b_buffer = b.buffer;
    const int out = Define(n, 0, out_shape);
    Emit(n, BinaryStep{a_buffer, b_buffer, out, Count(out_shape), g});
  }

  // Shape arithmetic on integer constants is done here, once.
  void FoldIntBinary(const OnnxNode& n, const Value& a, const Value& b, const Shape& out_shape) {
    int64_t as[kMaxRank] = {}, bs[kMaxRank] = {};
    if (out_shape.size() > static_cast<size_t>(kMaxRank)) Fail(n, "rank above 6");
    BroadcastStrides(a.shape, out_shape, as);
    BroadcastStrides(b.shape, out_shape, bs);
    Value v;
    v.shape = out_shape;
    v.is_int = true;
    for (int64_t i = 0; i < Count(out_shape); ++i) {
      int64_t rest = i, ia = 0, ib = 0;
      for (size_t d = out_shape.size(); d-- > 0;) {
        ia += (rest % out_shape[d]) * as[d];
        ib += (rest % out_shape[d]) * bs[d];
        rest /= out_shape[d];
      }
      const int64_t x = a.ints[ia], y = b.ints[ib];
      const std::string& op = n.op_type;
      if (op == "Div" && (y == 0 || (x == std::numeric_limits<int64_t>::min() && y == -1))) {
        Fail(n, "integer division by zero or overflow");
      }
      int64_t r = 0;
      const bool overflow = op == "Add"   ? __builtin_add_overflow(x, y, &r)
                            : op == "Sub" ? __builtin_sub_overflow(x, y, &r)
                            : op == "Mul" ? __builtin_mul_overflow(x, y, &r)
                                          : (r = x / y, false);
      if (overflow) Fail(n, "integer overflow in shape arithmetic");
      v.ints.push_back(r);
    }
    values_[Output(n, 0)] = v;
  }

  void LowerConcat(const OnnxNode& n) {
    const Value& first = Input(n, 0);
    const int64_t axis = Axis(n, n.Int("axis", 0), first.shape.size());
    Shape out_shape = first.shape;
    out_shape[axis] = 0;
    for (size_t i = 0; i < n.inputs.size(); ++i) {
      const Value& v = Input(n, i);
      if (v.is_int != first.is_int || v.shape.size() != first.shape.size())
        Fail(n, "inputs differ in type or rank");
      for (size_t d = 0; d < v.shape.size(); ++d) {
        if (static_cast<int64_t>(d) != axis && v.shape[d] != first.shape[d]) {
          Fail(n, "shapes " + ShapeText(first.shape) + " and " + ShapeText(v.shape) +
                      " differ off the axis");
        }
      }
      out_shape[axis] += v.shape[axis];
    }
    if (first.is_int) {
      if (first.shape.size() != 1) Fail(n, "integer Concat of rank other than 1");
      Value v{out_shape, -1, true, {}};
      for (size_t i = 0; i < n.inputs.size(); ++i) {
        const std::vector<int64_t>& ints = Input(n, i).ints;
        v.ints.insert(v.ints.end(), ints.begin(), ints.end());
      }
      values_[Output(n, 0)] = v;
      return;
    }
    std::vector<int> ins;
    std::vector<Shape> shapes;
    for (size_t i = 0; i < n.inputs.size(); ++i) {
      ins.push_back(Input(n, i).buffer);
      shapes.push_back(Input(n, i).shape);
    }
    const int out = Define(n, 0, out_shape);
    int64_t offset = 0;
    for (size_t i = 0; i < ins.size(); ++i) {
      CopyGeometry g;
      g.outer = Prod(out_shape, 0, axis);
      g.inner = Prod(out_shape, axis + 1, out_shape.size());
      g.in_axis = shapes[i][axis];
      g.out_axis = out_shape[axis];
      g.out_offset = offset;
      g.count = shapes[i][axis];
      offset += g.count;
      if (g.count > 0) Emit(n, CopyStep{ins[i], out, g});
    }
  }

  void LowerSplit(const OnnxNode& n) {
    const Value& x = Float(n, 0);
    const int64_t axis = Axis(n, n.Int("axis", 0), x.shape.size());
    std::vector<int64_t> sizes = HasInput(n, 1) ? ConstInts(n, 1) : n.Ints("split");
    const int64_t parts = static_cast<int64_t>(n.outputs.size());
    if (sizes.empty()) {
      if (x.shape[axis] % parts != 0) Fail(n, "axis does not divide into equal parts");
      sizes.assign(static_cast<size_t>(parts), x.shape[axis] / parts);
    }
    for (int64_t size : sizes) {
      if (size < 0 || size > x.shape[axis]) Fail(n, "split size out of range");
    }
    if (static_cast<int64_t>(sizes.size()) != parts ||
        std::accumulate(sizes.begin(), sizes.end(), int64_t{0}) != x.shape[axis]) {
      Fail(n, "split sizes do not add up to the axis length " + std::to_string(x.shape[axis]));
    }
    const Value in = x;
    int64_t offset = 0;
    for (size_t i = 0; i < sizes.size(); ++i) {
      Shape s = in.shape;
      s[axis] = sizes[i];
      const int out = Define(n, i, s);
      CopyGeometry g;
      g.outer = Prod(s, 0, axis);
      g.inner = Prod(s, axis + 1, s.size());
      g.in_axis = in.shape[axis];
      g.out_axis = sizes[i];
      g.in_offset = offset;
      g.count = sizes[i];
      offset += sizes[i];
      if (g.count > 0) Emit(n, CopyStep{in.buffer, out, g});
    }
  }

  void LowerSlice(const OnnxNode& n) {
    const Value x = Float(n, 0);
    if (!HasInput(n, 1) || !HasInput(n, 2))
      Fail(n, "Slice needs starts and ends inputs (opset >= 10)");
    const std::vector<int64_t> starts = ConstInts(n, 1), ends = ConstInts(n, 2);
    std::vector<int64_t> axes = HasInput(n, 3) ? ConstInts(n, 3) : std::vector<int64_t>{};
    std::vector<int64_t> steps = HasInput(n, 4) ? ConstInts(n, 4) : std::vector<int64_t>{};
    if (axes.empty()) {
      for (size_t i = 0; i < starts.size(); ++i) axes.push_back(static_cast<int64_t>(i));
    }
    if (steps.empty()) steps.assign(starts.size(), 1);
    if (starts.size() != ends.size() || axes.size() != starts.size() ||
        steps.size() != starts.size()) {
      Fail(n, "starts, ends, axes and steps differ in length");
    }
    Shape out_shape = x.shape;
    CopyGeometry g;
    int sliced_axes = 0;
    for (size_t i = 0; i < starts.size(); ++i) {
      const int64_t axis = Axis(n, axes[i], x.shape.size());
      const int64_t dim = x.shape[axis];
      if (steps[i] <= 0) Fail(n, "only positive steps are supported");
      int64_t start = starts[i] < 0 ? starts[i] + dim : starts[i];
      int64_t end = ends[i] < 0 ? ends[i] + dim : ends[i];
      start = std::clamp<int64_t>(start, 0, dim);
      end = std::clamp<int64_t>(end, 0, dim);
      const int64_t count = end > start ? (end - start + steps[i] - 1) / steps[i] : 0;
      if (count == dim) continue;  // the whole axis
      if (++sliced_axes > 1) Fail(n, "slicing more than one axis is not supported");
      out_shape[axis] = count;
      g.outer = Prod(x.shape, 0, axis);
      g.inner = Prod(x.shape, axis + 1, x.shape.size());
      g.in_axis = dim;
      g.out_axis = count;
      g.in_offset = start;
      g.in_step = steps[i];
      g.count = count;
    }
    const int out = Define(n, 0, out_shape);
    if (sliced_axes == 0) {  // a full copy
      g.outer = 1;
      g.inner = 1;
      g.in_axis = g.out_axis = g.count = Count(x.shape);
    }
    if (g.count > 0) Emit(n, CopyStep{x.buffer, out, g});
  }

  void LowerMaxPool(const OnnxNode& n) {
    const Value& x = Float(n, 0);
    const Shape& xs = Image(n, x);
    const std::vector<int64_t> kernel = Pair(n, "kernel_shape", 0);
    const std::vector<int64_t> strides = Pair(n, "strides", 1);
    const std::vector<int64_t> dilations = Pair(n, "dilations", 1);
    if (dilations != std::vector<int64_t>{1, 1}) Fail(n, "dilated pooling is not supported");
    if (n.Int("ceil_mode", 0) != 0) Fail(n, "ceil_mode is not supported");
    if (n.outputs.size() > 1 && !n.outputs[1].empty())
      Fail(n, "the Indices output is not supported");
    PoolGeometry g;
    g.channels = static_cast<int>(xs[1]);
    g.h_in = static_cast<int>(xs[2]);
    g.w_in = static_cast<int>(xs[3]);
    g.kh = static_cast<int>(kernel[0]);
    g.kw = static_cast<int>(kernel[1]);
    g.stride_h = static_cast<int>(strides[0]);
    g.stride_w = static_cast<int>(strides[1]);
    Pads2d(n, &g.pad_top, &g.pad_left);
    const int span_h = g.h_in + 2 * g.pad_top - g.kh;
    const int span_w = g.w_in + 2 * g.pad_left - g.kw;
    if (span_h < 0 || span_w < 0) Fail(n, "empty output");  // as for Conv
    g.h_out = span_h / g.stride_h + 1;
    g.w_out = span_w / g.stride_w + 1;
    const int in = x.buffer;
    const int out = Define(n, 0, Shape{1, g.channels, g.h_out, g.w_out});
    Emit(n, MaxPoolStep{in, out, g});
  }

  void LowerResize(const OnnxNode& n) {
    const Value& x = Float(n, 0);
    const Shape& xs = Image(n, x);
    if (n.String("mode", "nearest") != "nearest") Fail(n, "only mode 'nearest' is supported");
    if (n.String("coordinate_transformation_mode", "half_pixel") != "asymmetric" ||
        n.String("nearest_mode", "round_prefer_floor") != "floor") {
      Fail(n,
           "only coordinate_transformation_mode 'asymmetric' with nearest_mode 'floor' is "
           "supported");
    }
    ResizeGeometry g;
    g.channels = static_cast<int>(xs[1]);
    g.h_in = static_cast<int>(xs[2]);
    g.w_in = static_cast<int>(xs[3]);
    if (HasInput(n, 3)) {
      const std::vector<int64_t> sizes = ConstInts(n, 3);
      if (sizes.size() != 4 || sizes[0] != 1 || sizes[1] != xs[1])
        Fail(n, "sizes must resize H and W only");
      if (sizes[2] < 1 || sizes[2] > kMaxDim || sizes[3] < 1 || sizes[3] > kMaxDim)
        Fail(n, "sizes out of range");
      g.h_out = static_cast<int>(sizes[2]);
      g.w_out = static_cast<int>(sizes[3]);
      g.scale_h = static_cast<float>(g.h_out) / static_cast<float>(g.h_in);
      g.scale_w = static_cast<float>(g.w_out) / static_cast<float>(g.w_in);
    } else if (HasInput(n, 2)) {
      const std::vector<float>& scales = ConstFloats(n, 2);
      if (scales.size() != 4 || scales[0] != 1.0f || scales[1] != 1.0f)
        Fail(n, "scales must resize H and W only");
      for (int k = 2; k < 4; ++k) {
        if (!(scales[k] > 0.0f && scales[k] <= 1024.0f)) Fail(n, "scales out of range");
      }
      g.scale_h = scales[2];
      g.scale_w = scales[3];
      g.h_out = static_cast<int>(static_cast<float>(g.h_in) * g.scale_h);
      g.w_out = static_cast<int>(static_cast<float>(g.w_in) * g.scale_w);
    } else {
      Fail(n, "needs constant scales or sizes");
    }
    if (g.h_out <= 0 || g.w_out <= 0) Fail(n, "empty output");
    const int in = x.buffer;
    const int out = Define(n, 0, Shape{1, g.channels, g.h_out, g.w_out});
    Emit(n, ResizeStep{in, out, g});
  }

  void LowerReshape(const OnnxNode& n) {
    const Value& x = Input(n, 0);
    const std::vector<int64_t> target = ConstInts(n, 1);
    const bool allow_zero = n.Int("allowzero", 0) != 0;
    Shape s(target.size());
    int infer = -1;
    int64_t known = 1;
    for (size_t d = 0; d < target.size(); ++d) {
      if (target[d] == -1) {
        if (infer >= 0) Fail(n, "more than one -1 in the shape");
        infer = static_cast<int>(d);
        continue;
      }
      if (target[d] == 0 && !allow_zero) {
        if (d >= x.shape.size()) Fail(n, "0 copies a dim the input does not have");
        s[d] = x.shape[d];
      } else if (target[d] < 0) {
        Fail(n, "negative dim in the shape");
      } else {
        s[d] = target[d];
      }
      known = Count(Shape{known, s[d]});
    }
    if (infer >= 0) {
      if (known == 0 || Count(x.shape) % known != 0) Fail(n, "cannot infer the -1 dim");
      s[infer] = Count(x.shape) / known;
    }
    Alias(n, s);
  }

  void LowerTranspose(const OnnxNode& n) {
    const Value& x = Float(n, 0);
    const size_t rank = x.shape.size();
    if (rank > static_cast<size_t>(kMaxRank)) Fail(n, "rank above 6");
    std::vector<int64_t> perm = n.Ints("perm");
    if (perm.empty()) {
      for (size_t d = 0; d < rank; ++d) perm.push_back(static_cast<int64_t>(rank - 1 - d));
    }
    std::vector<int64_t> sorted = perm;
    std::sort(sorted.begin(), sorted.end());
    for (size_t d = 0; d < rank; ++d) {
      if (sorted.size() != rank || sorted[d] != static_cast<int64_t>(d))
        Fail(n, "perm is not a permutation");
    }
    int64_t in_strides[kMaxRank] = {};
    int64_t stride = 1;
    for (size_t d = rank; d-- > 0;) {
      in_strides[d] = stride;
      stride *= x.shape[d];
    }
    TransposeGeometry g;
    g.rank = static_cast<int>(rank);
    Shape out_shape(rank);
    for (size_t d = 0; d < rank; ++d) {
      out_shape[d] = x.shape[perm[d]];
      g.out_shape[d] = out_shape[d];
      g.in_strides[d] = in_strides[perm[d]];
    }
    const int in = x.buffer;
    const int out = Define(n, 0, out_shape);
    Emit(n, TransposeStep{in, out, Count(out_shape), g});
  }

  void LowerSoftmax(const OnnxNode& n) {
    const Value& x = Float(n, 0);
    const size_t rank = x.shape.size();
    const int64_t axis = Axis(n, n.Int("axis", model_.opset >= 13 ? -1 : 1), rank);
    if (model_.opset < 13 && axis != static_cast<int64_t>(rank) - 1) {
      Fail(n, "Softmax before opset 13 is only supported on the last axis");
    }
    SoftmaxGeometry g;
    g.outer = Prod(x.shape, 0, axis);
    g.axis = x.shape[axis];
    g.inner = Prod(x.shape, axis + 1, rank);
    const int in = x.buffer;
    const Shape shape = x.shape;
    const int out = Define(n, 0, shape);
    Emit(n, SoftmaxStep{in, out, g});
  }

  const OnnxModel& model_;
  NetPlan plan_;
  std::map<std::string, Value> values_;
  std::map<std::string, int> consumers_;
  std::set<std::string> graph_outputs_;
  std::set<size_t> skipped_;
};

// Greedy interval allocation: tensors in order of first use; each takes the smallest free buffer
// that is large enough, else a new one. A buffer is free once the last step touching its tensor
// is strictly before the new tensor's first step.
void ShareStorage(NetPlan* plan) {
  const int n = static_cast<int>(plan->buffers.size());
  std::vector<int> first(n, -1), last(n, -1);
  for (int k = 0; k < static_cast<int>(plan->steps.size()); ++k) {
    ForEachBuffer(plan->steps[k], [&](int& b) {
      if (first[b] < 0) first[b] = k;
      last[b] = k;
    });
  }
  std::vector<bool> pinned(n, false);
  pinned[plan->input.buffer] = true;
  for (const PlanTensor& t : plan->outputs) pinned[t.buffer] = true;

  std::vector<int> order;
  for (int b = 0; b < n; ++b) {
    if (!plan->buffers[b].constant() && !pinned[b] && first[b] >= 0) order.push_back(b);
  }
  std::sort(order.begin(), order.end(), [&](int a, int b) { return first[a] < first[b]; });

  std::vector<PlanBuffer> buffers;
  std::vector<int> map(n, -1);
  for (int b = 0; b < n; ++b) {  // constants, the input, outputs and unused buffers stay
    if (plan->buffers[b].constant() || pinned[b] || first[b] < 0) {
      map[b] = static_cast<int>(buffers.size());
      buffers.push_back(std::move(plan->buffers[b]));
    }
  }
  struct Slot {
    int buffer;
    int busy_until;
  };
  std::vector<Slot> slots;
  for (int b : order) {
    const int64_t size = plan->buffers[b].size;
    int best = -1;
    for (int i = 0; i < static_cast<int>(slots.size()); ++i) {
      if (slots[i].busy_until >= first[b]) continue;
      const int64_t have = buffers[slots[i].buffer].size;
      if (have >= size && (best < 0 || have < buffers[slots[best].buffer].size)) best = i;
    }
    if (best < 0) {
      slots.push_back({static_cast<int>(buffers.size()), -1});
      buffers.push_back(PlanBuffer{0, {}});
      best = static_cast<int>(slots.size()) - 1;
    }
    PlanBuffer& target = buffers[slots[best].buffer];
    target.size = std::max(target.size, size);  // a new slot starts at 0
    slots[best].busy_until = last[b];
    map[b] = slots[best].buffer;
  }
  for (PlanStep& step : plan->steps) ForEachBuffer(step, [&](int& b) { b = map[b]; });
  plan->input.buffer = map[plan->input.buffer];
  for (PlanTensor& t : plan->outputs) t.buffer = map[t.buffer];
  plan->buffers = std::move(buffers);
}

}  // namespace

NetPlan BuildNetPlan(const std::vector<uint8_t>& model_bytes, int height, int width,
                     bool share_storage) {
  const OnnxModel model = ParseOnnxModel(model_bytes);
  NetPlan plan = Lowering(model, height, width).Build();
  for (const PlanBuffer& b : plan.buffers) plan.tensors += b.constant() ? 0 : 1;
  // The kernels index in 32 bits (tensor_math.h).
  constexpr int64_t kMaxElements = std::numeric_limits<int32_t>::max();
  for (const PlanBuffer& b : plan.buffers) {
    if (b.size > kMaxElements) {
      throw std::invalid_argument("a tensor of " + std::to_string(b.size) +
                                  " elements is beyond the executor's 32-bit indexing");
    }
  }
  if (plan.scratch_size > kMaxElements) {
    throw std::invalid_argument("a convolution's column matrix of " +
                                std::to_string(plan.scratch_size) +
                                " elements is beyond the executor's 32-bit indexing");
  }
  if (share_storage) ShareStorage(&plan);
  return plan;
}

int64_t ActivationFloats(const NetPlan& plan) {
  int64_t n = plan.scratch_size;
  for (const PlanBuffer& b : plan.buffers) n += b.constant() ? 0 : b.size;
  return n;
}

int64_t ConstantFloats(const NetPlan& plan) {
  int64_t n = 0;
  for (const PlanBuffer& b : plan.buffers) n += b.constant() ? b.size : 0;
  return n;
}

}  // namespace pcr::gpu
