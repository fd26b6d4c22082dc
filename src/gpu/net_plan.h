#pragma once
// An ONNX convolutional network (YOLOv8-seg and the like) lowered to a flat list of steps with
// static shapes, for the executors in src/gpu: the CUDA one and its CPU twin (executor.h). Built
// once per model and input size; immutable afterwards.
//
// Buffers are float32 arrays. Constant buffers (weights, biases, folded constants) carry their
// data in the plan; the others are allocated by the executor (`size` floats each). A Reshape or
// Identity is an alias: its output shares its input's buffer.
#include <cstdint>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "gpu/tensor_math.h"

namespace pcr::gpu {

struct PlanBuffer {
  int64_t size = 0;         // floats
  std::vector<float> data;  // the values of a constant buffer; empty otherwise
  bool constant() const { return !data.empty(); }
};

// out = act(W x im2col(in) + bias): W is c_out x (c_in*kh*kw) row-major (ONNX layout). The
// column matrix lives in the executor's scratch buffer unless the convolution is pointwise.
struct ConvStep {
  int in = -1, out = -1, weight = -1, bias = -1;  // bias -1: none
  ConvGeometry geometry;
  Activation activation = Activation::kNone;
};

// out = scatter(W x in) + bias, W is (c_out*kh*kw) x c_in row-major (repacked from ONNX's
// c_in x c_out x kh x kw); the GEMM result lives in the scratch buffer.
struct ConvTransposeStep {
  int in = -1, out = -1, weight = -1, bias = -1;
  ConvTransposeGeometry geometry;
};

struct UnaryStep {
  int in = -1, out = -1;
  int64_t count = 0;
  Activation activation = Activation::kSigmoid;
};

struct BinaryStep {
  int a = -1, b = -1, out = -1;
  int64_t count = 0;
  BinaryGeometry geometry;
};

struct CopyStep {  // Concat (one per input), Split (one per output), Slice
  int in = -1, out = -1;
  CopyGeometry geometry;
};

struct MaxPoolStep {
  int in = -1, out = -1;
  PoolGeometry geometry;
};

struct ResizeStep {
  int in = -1, out = -1;
  ResizeGeometry geometry;
};

struct TransposeStep {
  int in = -1, out = -1;
  int64_t count = 0;
  TransposeGeometry geometry;
};

struct SoftmaxStep {
  int in = -1, out = -1;
  SoftmaxGeometry geometry;
};

using PlanStep = std::variant<ConvStep, ConvTransposeStep, UnaryStep, BinaryStep, CopyStep,
                              MaxPoolStep, ResizeStep, TransposeStep, SoftmaxStep>;

struct PlanTensor {
  std::string name;
  int buffer = -1;
  std::vector<int64_t> shape;
};

struct NetPlan {
  std::vector<PlanBuffer> buffers;
  std::vector<PlanStep> steps;          // in execution order
  std::vector<std::string> step_names;  // the ONNX node each step comes from
  PlanTensor input;                     // 1 x 3 x H x W
  std::vector<PlanTensor> outputs;      // in the graph's output order
  int64_t scratch_size = 0;             // floats of scratch the largest conv needs
  int fused_activations = 0;            // Conv -> Sigmoid -> Mul chains folded into one step
  int tensors = 0;  // computed tensors before storage sharing (each had its own buffer)
};

// Lowers the serialized ONNX model for an input of 1 x 3 x height x width. Throws
// std::invalid_argument naming the node and op when the graph uses anything outside the
// supported set (Conv with group 1, ConvTranspose with kernel == stride, Sigmoid, Add, Sub, Mul,
// Div, Concat, Split, Slice on one axis, MaxPool, Resize nearest, Reshape, Identity, Transpose,
// Softmax, Constant) or when shapes do not agree.
//
// With share_storage, computed tensors whose lifetimes (first to last step that touches them)
// do not overlap share one buffer, so activation memory is a few of the largest tensors rather
// than all of them; the input and the outputs keep buffers of their own. A step's output never
// shares with its own inputs.
NetPlan BuildNetPlan(const std::vector<uint8_t>& model_bytes, int height, int width,
                     bool share_storage = true);

// Calls f(int& buffer) for every buffer a step reads or writes (weights and biases included).
template <typename F>
void ForEachBuffer(PlanStep& step, F&& f);

// Elements of a tensor of this shape (a scalar's shape is empty: 1).
inline int64_t ShapeElements(const std::vector<int64_t>& shape) {
  int64_t n = 1;
  for (int64_t d : shape) n *= d;
  return n;
}

// Total floats of the plan's non-constant buffers and of its constants.
int64_t ActivationFloats(const NetPlan& plan);
int64_t ConstantFloats(const NetPlan& plan);

template <typename F>
void ForEachBuffer(PlanStep& step, F&& f) {
  std::visit(
      [&f](auto& s) {
        using T = std::decay_t<decltype(s)>;
        if constexpr (std::is_same_v<T, ConvStep> || std::is_same_v<T, ConvTransposeStep>) {
          f(s.in);
          f(s.weight);
          if (s.bias >= 0) f(s.bias);
          f(s.out);
        } else if constexpr (std::is_same_v<T, BinaryStep>) {
          f(s.a);
          f(s.b);
          f(s.out);
        } else {
          f(s.in);
          f(s.out);
        }
      },
      step);
}

}  // namespace pcr::gpu
