#pragma once
// Per-element math of the network executor's kernels, shared by the CUDA kernels
// (src/gpu/cuda_executor.cu) and their CPU twin (src/gpu/twin_executor.cpp): every function takes
// an output element's flat index (or a row) and the step's geometry by value and computes that
// element, so both executors produce the same numbers from the same code.
//
// Tensors are dense, row-major (NCHW for images), float32. Geometries are plain structs copied
// into kernels by value; they hold no pointers. Index arithmetic is 32-bit (a 64-bit division is
// several times slower on a CPU and emulated on a GPU): every tensor, column matrix and index
// handed to these functions stays below 2^31 elements, which BuildNetPlan checks.
#include <cmath>
#include <cstdint>

#if defined(__CUDACC__)
#define PCR_HD __host__ __device__
#else
#define PCR_HD
#endif

namespace pcr::gpu {

inline constexpr int kMaxRank = 6;

enum class Activation : int { kNone = 0, kSilu = 1, kSigmoid = 2 };
enum class BinaryOp : int { kAdd = 0, kSub = 1, kMul = 2, kDiv = 3 };

PCR_HD inline float Sigmoid(float x) { return 1.0f / (1.0f + expf(-x)); }

PCR_HD inline float Activate(float x, Activation a) {
  switch (a) {
    case Activation::kSilu:
      return x * Sigmoid(x);
    case Activation::kSigmoid:
      return Sigmoid(x);
    default:
      return x;
  }
}

PCR_HD inline float ApplyBinary(float a, float b, BinaryOp op) {
  switch (op) {
    case BinaryOp::kAdd:
      return a + b;
    case BinaryOp::kSub:
      return a - b;
    case BinaryOp::kMul:
      return a * b;
    default:
      return a / b;
  }
}

// ---- Convolution as im2col + GEMM ----

// One image (batch 1), groups 1. Output is c_out x h_out x w_out.
struct ConvGeometry {
  int c_in = 0, h_in = 0, w_in = 0;
  int c_out = 0, h_out = 0, w_out = 0;
  int kh = 1, kw = 1;
  int stride_h = 1, stride_w = 1;
  int pad_top = 0, pad_left = 0;
  int dilation_h = 1, dilation_w = 1;
};

// Rows of the column matrix (c_in * kh * kw) and its columns (h_out * w_out).
PCR_HD inline int64_t ColRows(const ConvGeometry& g) {
  return static_cast<int64_t>(g.c_in) * g.kh * g.kw;
}
PCR_HD inline int64_t ColCols(const ConvGeometry& g) {
  return static_cast<int64_t>(g.h_out) * g.w_out;
}
// A 1x1, stride 1, unpadded convolution reads the input directly as its column matrix.
PCR_HD inline bool IsPointwise(const ConvGeometry& g) {
  return g.kh == 1 && g.kw == 1 && g.stride_h == 1 && g.stride_w == 1 && g.pad_top == 0 &&
         g.pad_left == 0 && g.h_out == g.h_in && g.w_out == g.w_in;
}

// Tap (c, ky, kx) of the kernel at output pixel (oy, ox): the input value it reads, zero in the
// padding. Row (c * kh + ky) * kw + kx, column oy * w_out + ox of the column matrix.
PCR_HD inline float Im2ColTap(const float* in, const ConvGeometry& g, int c, int ky, int kx, int oy,
                              int ox) {
  const int y = oy * g.stride_h - g.pad_top + ky * g.dilation_h;
  const int x = ox * g.stride_w - g.pad_left + kx * g.dilation_w;
  if (y < 0 || y >= g.h_in || x < 0 || x >= g.w_in) return 0.0f;
  return in[(c * g.h_in + y) * g.w_in + x];
}

// Element `index` of the column matrix (row-major, ColRows x ColCols). The CUDA kernel computes
// elements by index; the CPU twin walks the taps in the same order without the divisions.
PCR_HD inline float Im2ColAt(const float* in, const ConvGeometry& g, int64_t index) {
  const int cols = g.h_out * g.w_out;
  const int i = static_cast<int>(index);
  const int row = i / cols;
  const int col = i - row * cols;
  const int kx = row % g.kw;
  const int ky = (row / g.kw) % g.kh;
  const int c = row / (g.kw * g.kh);
  const int oy = col / g.w_out;
  return Im2ColTap(in, g, c, ky, kx, oy, col - oy * g.w_out);
}

// Epilogue of a GEMM whose output has `plane` elements per row (channel): adds the channel's
// bias (bias may be null) and applies the activation. Element `index` of the c x plane output.
PCR_HD inline float BiasActivateAt(const float* acc, const float* bias, int64_t plane,
                                   Activation act, int64_t index) {
  const float b = bias ? bias[static_cast<int>(index) / static_cast<int>(plane)] : 0.0f;
  return Activate(acc[index] + b, act);
}

// ConvTranspose with kernel == stride and no padding (the YOLOv8-seg prototype upsampler): the
// taps of output pixels never overlap, so the layer is a GEMM (c_out*kh*kw x c_in) times the
// input (c_in x h_in*w_in) followed by this scatter. Output is c_out x (h_in*kh) x (w_in*kw).
struct ConvTransposeGeometry {
  int c_in = 0, h_in = 0, w_in = 0;
  int c_out = 0, kh = 1, kw = 1;
};

PCR_HD inline int64_t ConvTransposeOutCount(const ConvTransposeGeometry& g) {
  return static_cast<int64_t>(g.c_out) * g.h_in * g.kh * g.w_in * g.kw;
}

// Element `index` of the output from the GEMM result `taps` ((c_out*kh*kw) x (h_in*w_in)).
PCR_HD inline float ConvTransposeAt(const float* taps, const float* bias,
                                    const ConvTransposeGeometry& g, int64_t index) {
  const int w_out = g.w_in * g.kw;
  const int h_out = g.h_in * g.kh;
  const int i = static_cast<int>(index);
  const int x = i % w_out;
  const int y = (i / w_out) % h_out;
  const int m = i / (w_out * h_out);
  const int ix = x / g.kw, kx = x - ix * g.kw;
  const int iy = y / g.kh, ky = y - iy * g.kh;
  const int tap_row = (m * g.kh + ky) * g.kw + kx;
  const float b = bias ? bias[m] : 0.0f;
  return taps[tap_row * g.h_in * g.w_in + iy * g.w_in + ix] + b;
}

// ---- Element-wise ----

// Numpy broadcasting: both operands' strides are given in the output's index space (0 along
// broadcast axes). rank <= kMaxRank.
struct BinaryGeometry {
  int rank = 0;
  int64_t out_shape[kMaxRank] = {};
  int64_t a_strides[kMaxRank] = {};
  int64_t b_strides[kMaxRank] = {};
  BinaryOp op = BinaryOp::kAdd;
};

PCR_HD inline float BinaryAt(const float* a, const float* b, const BinaryGeometry& g,
                             int64_t index) {
  int rest = static_cast<int>(index), ia = 0, ib = 0;
  for (int d = g.rank - 1; d >= 0; --d) {
    const int dim = static_cast<int>(g.out_shape[d]);
    const int q = rest / dim;
    const int i = rest - q * dim;
    rest = q;
    ia += i * static_cast<int>(g.a_strides[d]);
    ib += i * static_cast<int>(g.b_strides[d]);
  }
  return ApplyBinary(a[ia], b[ib], g.op);
}

// Copy of a block along one axis, the tensor seen as outer x axis x inner: element
// (o, k, i), k < count, of the block goes from input axis position in_offset + k * in_step to
// output axis position out_offset + k. Concat, Split and single-axis Slice are such copies.
struct CopyGeometry {
  int64_t outer = 1, inner = 1;
  int64_t in_axis = 0, out_axis = 0;  // axis lengths of the input and output tensors
  int64_t in_offset = 0, in_step = 1, out_offset = 0;
  int64_t count = 0;  // axis positions copied
};

PCR_HD inline int64_t CopyCount(const CopyGeometry& g) { return g.outer * g.count * g.inner; }

// Flat input and output indices of block element `index` (index < CopyCount(g)).
PCR_HD inline void CopyIndices(const CopyGeometry& g, int64_t index, int64_t* in_index,
                               int64_t* out_index) {
  const int inner = static_cast<int>(g.inner), count = static_cast<int>(g.count);
  const int j = static_cast<int>(index);
  const int q = j / inner;
  const int i = j - q * inner;
  const int o = q / count;
  const int k = q - o * count;
  *in_index = (o * static_cast<int>(g.in_axis) + static_cast<int>(g.in_offset) +
               k * static_cast<int>(g.in_step)) *
                  inner +
              i;
  *out_index = (o * static_cast<int>(g.out_axis) + static_cast<int>(g.out_offset) + k) * inner + i;
}

// Max pooling over channels x h x w; padded taps are ignored.
struct PoolGeometry {
  int channels = 0, h_in = 0, w_in = 0, h_out = 0, w_out = 0;
  int kh = 1, kw = 1, stride_h = 1, stride_w = 1, pad_top = 0, pad_left = 0;
};

PCR_HD inline int64_t PoolOutCount(const PoolGeometry& g) {
  return static_cast<int64_t>(g.channels) * g.h_out * g.w_out;
}

PCR_HD inline float MaxPoolAt(const float* in, const PoolGeometry& g, int64_t index) {
  const int i = static_cast<int>(index);
  const int ox = i % g.w_out;
  const int oy = (i / g.w_out) % g.h_out;
  const int c = i / (g.w_out * g.h_out);
  const float* plane = in + c * g.h_in * g.w_in;
  float best = -3.402823466e38f;
  for (int ky = 0; ky < g.kh; ++ky) {
    const int y = oy * g.stride_h - g.pad_top + ky;
    if (y < 0 || y >= g.h_in) continue;
    for (int kx = 0; kx < g.kw; ++kx) {
      const int x = ox * g.stride_w - g.pad_left + kx;
      if (x < 0 || x >= g.w_in) continue;
      const float v = plane[y * g.w_in + x];
      best = v > best ? v : best;
    }
  }
  return best;
}

// Nearest-neighbour resize (ONNX Resize, mode nearest, coordinate mode asymmetric, nearest
// mode floor): output pixel (y, x) reads input pixel (floor(y / scale_h), floor(x / scale_w)).
struct ResizeGeometry {
  int channels = 0, h_in = 0, w_in = 0, h_out = 0, w_out = 0;
  float scale_h = 1.0f, scale_w = 1.0f;
};

PCR_HD inline int64_t ResizeOutCount(const ResizeGeometry& g) {
  return static_cast<int64_t>(g.channels) * g.h_out * g.w_out;
}

// The input row (or column) that output row (column) `o` reads along an axis of `n_in` input
// positions scaled by `scale`.
PCR_HD inline int ResizeNearestSource(int o, float scale, int n_in) {
  const int i = static_cast<int>(floorf(static_cast<float>(o) / scale));
  return i < n_in - 1 ? i : n_in - 1;
}

PCR_HD inline float ResizeNearestAt(const float* in, const ResizeGeometry& g, int64_t index) {
  const int i = static_cast<int>(index);
  const int ox = i % g.w_out;
  const int oy = (i / g.w_out) % g.h_out;
  const int c = i / (g.w_out * g.h_out);
  const int y = ResizeNearestSource(oy, g.scale_h, g.h_in);
  const int x = ResizeNearestSource(ox, g.scale_w, g.w_in);
  return in[(c * g.h_in + y) * g.w_in + x];
}

// Transpose: out_shape is the permuted shape; in_strides[d] is the input stride of the axis
// that becomes output axis d.
struct TransposeGeometry {
  int rank = 0;
  int64_t out_shape[kMaxRank] = {};
  int64_t in_strides[kMaxRank] = {};
};

PCR_HD inline float TransposeAt(const float* in, const TransposeGeometry& g, int64_t index) {
  int rest = static_cast<int>(index), offset = 0;
  for (int d = g.rank - 1; d >= 0; --d) {
    const int dim = static_cast<int>(g.out_shape[d]);
    const int q = rest / dim;
    offset += (rest - q * dim) * static_cast<int>(g.in_strides[d]);
    rest = q;
  }
  return in[offset];
}

// Softmax along one axis, the tensor seen as outer x axis x inner: row r (< outer * inner) is
// the axis at (r / inner, r % inner).
struct SoftmaxGeometry {
  int64_t outer = 1, axis = 1, inner = 1;
};

PCR_HD inline void SoftmaxRow(const float* in, float* out, const SoftmaxGeometry& g, int64_t row) {
  if (g.axis <= 0) return;
  const int64_t o = row / g.inner, i = row % g.inner;
  const int64_t base = o * g.axis * g.inner + i;
  float m = in[base];
  for (int64_t k = 1; k < g.axis; ++k) m = fmaxf(m, in[base + k * g.inner]);
  float sum = 0.0f;
  for (int64_t k = 0; k < g.axis; ++k) sum += expf(in[base + k * g.inner] - m);
  const float inv = 1.0f / sum;
  for (int64_t k = 0; k < g.axis; ++k)
    out[base + k * g.inner] = expf(in[base + k * g.inner] - m) * inv;
}

}  // namespace pcr::gpu
