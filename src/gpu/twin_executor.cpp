// The CPU twin of cuda_executor.cu: the same steps, the same per-element functions
// (tensor_math.h), Eigen for the GEMMs. Also Executor::Run, which both executors share.
#include <Eigen/Core>
#include <algorithm>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "gpu/executor.h"

namespace pcr::gpu {
namespace {

using RowMajor = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// out (m x n) = a (m x k) * b (k x n), all row-major.
void Gemm(const float* a, const float* b, float* out, int64_t m, int64_t k, int64_t n) {
  Eigen::Map<const RowMajor> A(a, m, k);
  Eigen::Map<const RowMajor> B(b, k, n);
  Eigen::Map<RowMajor> C(out, m, n);
  C.noalias() = A * B;
}

class TwinExecutor final : public Executor {
 public:
  TwinExecutor(std::shared_ptr<const NetPlan> plan, std::unique_ptr<ConvKernels> conv,
               bool row_steps)
      : plan_(std::move(plan)), conv_(std::move(conv)), row_steps_(row_steps) {
    if (!plan_) throw std::invalid_argument("TwinExecutor: no plan");
    storage_.resize(plan_->buffers.size());
    for (size_t i = 0; i < plan_->buffers.size(); ++i) {
      if (!plan_->buffers[i].constant())
        storage_[i].resize(static_cast<size_t>(plan_->buffers[i].size));
    }
    scratch_.resize(static_cast<size_t>(plan_->scratch_size));
  }

  void Launch(const float* input, const Done& done) override {
    float* in = Buffer(plan_->input.buffer);
    std::copy(input, input + plan_->buffers[plan_->input.buffer].size, in);
    for (size_t s = 0; s < plan_->steps.size(); ++s) {
      if (conv_) {
        if (const auto* c = std::get_if<ConvStep>(&plan_->steps[s])) {
          conv_->Conv(s, Buffer(c->in), Buffer(c->out));
          continue;
        }
      }
      std::visit([this](const auto& step) { Execute(step); }, plan_->steps[s]);
    }
    if (done) done();  // last: the caller may already be running Finish() on another thread
  }

  void Finish(const std::vector<float*>& outputs) override {
    if (outputs.size() != plan_->outputs.size()) {
      throw std::invalid_argument("TwinExecutor: one destination per plan output");
    }
    for (size_t i = 0; i < outputs.size(); ++i) {
      const PlanTensor& t = plan_->outputs[i];
      const float* data = Buffer(t.buffer);
      std::copy(data, data + ShapeElements(t.shape), outputs[i]);
    }
  }

  const NetPlan& plan() const override { return *plan_; }
  std::string Name() const override { return conv_ ? conv_->Name() : "cpu-twin"; }

 private:
  float* Buffer(int i) {
    const PlanBuffer& b = plan_->buffers[i];
    // Constant buffers are read-only; the steps never write them.
    return b.constant() ? const_cast<float*>(b.data.data()) : storage_[i].data();
  }
  const float* Optional(int i) { return i < 0 ? nullptr : Buffer(i); }

  void Execute(const ConvStep& s) {
    const ConvGeometry& g = s.geometry;
    const float* in = Buffer(s.in);
    const float* col = in;
    if (!IsPointwise(g)) {
      // Im2ColAt's order, tap by tap (the index decomposition costs more than the copy).
      float* dst = scratch_.data();
      for (int c = 0; c < g.c_in; ++c) {
        for (int ky = 0; ky < g.kh; ++ky) {
          for (int kx = 0; kx < g.kw; ++kx) {
            for (int oy = 0; oy < g.h_out; ++oy) {
              for (int ox = 0; ox < g.w_out; ++ox) *dst++ = Im2ColTap(in, g, c, ky, kx, oy, ox);
            }
          }
        }
      }
      col = scratch_.data();
    }
    float* out = Buffer(s.out);
    Gemm(Buffer(s.weight), col, out, g.c_out, ColRows(g), ColCols(g));
    const float* bias = Optional(s.bias);
    const int64_t plane = ColCols(g), n = plane * g.c_out;
    for (int64_t i = 0; i < n; ++i) out[i] = BiasActivateAt(out, bias, plane, s.activation, i);
  }

  void Execute(const ConvTransposeStep& s) {
    const ConvTransposeGeometry& g = s.geometry;
    const int64_t taps = static_cast<int64_t>(g.c_out) * g.kh * g.kw;
    const int64_t pixels = static_cast<int64_t>(g.h_in) * g.w_in;
    Gemm(Buffer(s.weight), Buffer(s.in), scratch_.data(), taps, g.c_in, pixels);
    float* out = Buffer(s.out);
    const float* bias = Optional(s.bias);
    if (!row_steps_) {
      const int64_t n = ConvTransposeOutCount(g);
      for (int64_t i = 0; i < n; ++i) out[i] = ConvTransposeAt(scratch_.data(), bias, g, i);
      return;
    }
    // ConvTransposeAt's scatter, row by row of the output.
    const float* taps_data = scratch_.data();
    const int64_t w_out = static_cast<int64_t>(g.w_in) * g.kw;
    for (int m = 0; m < g.c_out; ++m) {
      const float b = bias ? bias[m] : 0.0f;
      for (int iy = 0; iy < g.h_in; ++iy) {
        for (int ky = 0; ky < g.kh; ++ky) {
          float* row = out + (static_cast<int64_t>(m) * g.h_in * g.kh + iy * g.kh + ky) * w_out;
          for (int kx = 0; kx < g.kw; ++kx) {
            const float* tap = taps_data +
                               (static_cast<int64_t>(m * g.kh + ky) * g.kw + kx) * pixels +
                               static_cast<int64_t>(iy) * g.w_in;
            for (int ix = 0; ix < g.w_in; ++ix) row[ix * g.kw + kx] = tap[ix] + b;
          }
        }
      }
    }
  }

  void Execute(const UnaryStep& s) {
    const float* in = Buffer(s.in);
    float* out = Buffer(s.out);
    for (int64_t i = 0; i < s.count; ++i) out[i] = Activate(in[i], s.activation);
  }

  void Execute(const BinaryStep& s) {
    const float* a = Buffer(s.a);
    const float* b = Buffer(s.b);
    float* out = Buffer(s.out);
    if (!row_steps_) {
      for (int64_t i = 0; i < s.count; ++i) out[i] = BinaryAt(a, b, s.geometry, i);
      return;
    }
    // BinaryAt's broadcasting, row by row of the last axis: the operands' offsets of a row's
    // first element from BinaryAt's decomposition, then their last-axis strides.
    const BinaryGeometry& g = s.geometry;
    const int64_t width = g.rank > 0 ? g.out_shape[g.rank - 1] : 1;
    const int64_t sa = g.rank > 0 ? g.a_strides[g.rank - 1] : 0;
    const int64_t sb = g.rank > 0 ? g.b_strides[g.rank - 1] : 0;
    for (int64_t start = 0; start < s.count; start += width) {
      int64_t rest = start / width, ia = 0, ib = 0;
      for (int d = g.rank - 2; d >= 0; --d) {
        const int64_t q = rest / g.out_shape[d];
        const int64_t i = rest - q * g.out_shape[d];
        rest = q;
        ia += i * g.a_strides[d];
        ib += i * g.b_strides[d];
      }
      float* o = out + start;
      for (int64_t x = 0; x < width; ++x) o[x] = ApplyBinary(a[ia + x * sa], b[ib + x * sb], g.op);
    }
  }

  void Execute(const CopyStep& s) {
    const float* in = Buffer(s.in);
    float* out = Buffer(s.out);
    if (!row_steps_) {
      const int64_t n = CopyCount(s.geometry);
      for (int64_t i = 0; i < n; ++i) {
        int64_t ii = 0, oi = 0;
        CopyIndices(s.geometry, i, &ii, &oi);
        out[oi] = in[ii];
      }
      return;
    }
    // CopyIndices' blocks: `inner` contiguous elements per (outer, axis position).
    const CopyGeometry& g = s.geometry;
    for (int64_t o = 0; o < g.outer; ++o) {
      for (int64_t k = 0; k < g.count; ++k) {
        const float* from = in + (o * g.in_axis + g.in_offset + k * g.in_step) * g.inner;
        std::copy(from, from + g.inner, out + (o * g.out_axis + g.out_offset + k) * g.inner);
      }
    }
  }

  void Execute(const MaxPoolStep& s) {
    const PoolGeometry& g = s.geometry;
    const float* in = Buffer(s.in);
    float* out = Buffer(s.out);
    for (int64_t i = 0; i < PoolOutCount(g); ++i) out[i] = MaxPoolAt(in, g, i);
  }

  void Execute(const ResizeStep& s) {
    const ResizeGeometry& g = s.geometry;
    const float* in = Buffer(s.in);
    float* out = Buffer(s.out);
    if (!row_steps_) {
      for (int64_t i = 0; i < ResizeOutCount(g); ++i) out[i] = ResizeNearestAt(in, g, i);
      return;
    }
    // ResizeNearestAt with the source column of each output column computed once.
    std::vector<int> column(static_cast<size_t>(g.w_out));
    for (int ox = 0; ox < g.w_out; ++ox) column[ox] = ResizeNearestSource(ox, g.scale_w, g.w_in);
    for (int c = 0; c < g.channels; ++c) {
      for (int oy = 0; oy < g.h_out; ++oy) {
        const int y = ResizeNearestSource(oy, g.scale_h, g.h_in);
        const float* src = in + (static_cast<int64_t>(c) * g.h_in + y) * g.w_in;
        float* row = out + (static_cast<int64_t>(c) * g.h_out + oy) * g.w_out;
        for (int ox = 0; ox < g.w_out; ++ox) row[ox] = src[column[ox]];
      }
    }
  }

  void Execute(const TransposeStep& s) {
    const float* in = Buffer(s.in);
    float* out = Buffer(s.out);
    for (int64_t i = 0; i < s.count; ++i) out[i] = TransposeAt(in, s.geometry, i);
  }

  void Execute(const SoftmaxStep& s) {
    const float* in = Buffer(s.in);
    float* out = Buffer(s.out);
    const int64_t rows = s.geometry.outer * s.geometry.inner;
    for (int64_t r = 0; r < rows; ++r) SoftmaxRow(in, out, s.geometry, r);
  }

  std::shared_ptr<const NetPlan> plan_;
  std::unique_ptr<ConvKernels> conv_;  // null: the twin's own convolutions
  // The copy, element-wise, resize and ConvTranspose steps walk rows and blocks (the same numbers
  // without the per-element index arithmetic) instead of calling the kernels' per-element
  // functions, which the twin proper keeps so that it checks the CUDA kernels' code.
  bool row_steps_ = false;
  std::vector<std::vector<float>> storage_;
  std::vector<float> scratch_;
};

}  // namespace

std::vector<std::vector<float>> Executor::Run(const float* input) {
  Launch(input, {});
  std::vector<std::vector<float>> outputs;
  std::vector<float*> destinations;
  for (const PlanTensor& t : plan().outputs) {
    outputs.emplace_back(static_cast<size_t>(ShapeElements(t.shape)));
  }
  for (std::vector<float>& o : outputs) destinations.push_back(o.data());
  Finish(destinations);
  return outputs;
}

std::unique_ptr<Executor> MakeTwinExecutor(std::shared_ptr<const NetPlan> plan,
                                           std::unique_ptr<ConvKernels> conv, bool row_steps) {
  return std::make_unique<TwinExecutor>(std::move(plan), std::move(conv), row_steps);
}

}  // namespace pcr::gpu
