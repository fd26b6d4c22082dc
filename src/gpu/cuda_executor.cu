// The CUDA executor (executor.h): runs a NetPlan on one device, one kernel per step on the
// executor's own stream, the convolution GEMMs on cuBLAS.
//
// Every kernel is a grid-stride loop over its output elements that calls the per-element function
// of tensor_math.h, the same function the CPU twin (twin_executor.cpp) calls, so the two
// executors differ only in the GEMMs' summation order. Kernels hold no math of their own.
#include <cublas_v2.h>
#include <cuda_runtime.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "gpu/cublas_library.h"
#include "gpu/cuda_pass_end.cuh"
#include "gpu/executor.h"
#include "gpu/net_plan.h"
#include "gpu/tensor_math.h"

namespace pcr::gpu {

int CublasMajorVersion() { return CUBLAS_VER_MAJOR; }

namespace {

// The process's cuBLAS (cublas_library.h, opened on first use) with its entry points' types.
struct CublasApi {
  decltype(&cublasCreate_v2) create;
  decltype(&cublasDestroy_v2) destroy;
  decltype(&cublasSetStream_v2) set_stream;
  decltype(&cublasSetMathMode) set_math_mode;
  decltype(&cublasGetStatusString) status_string;
  decltype(&cublasSgemm_v2) sgemm;

  explicit CublasApi(const CublasLibrary& lib)
      : create(reinterpret_cast<decltype(create)>(lib.create)),
        destroy(reinterpret_cast<decltype(destroy)>(lib.destroy)),
        set_stream(reinterpret_cast<decltype(set_stream)>(lib.set_stream)),
        set_math_mode(reinterpret_cast<decltype(set_math_mode)>(lib.set_math_mode)),
        status_string(reinterpret_cast<decltype(status_string)>(lib.status_string)),
        sgemm(reinterpret_cast<decltype(sgemm)>(lib.sgemm)) {}

  // Throws (cublas_library.h's error) while the library cannot be opened; a later call tries again.
  static const CublasApi& Get() {
    static const CublasApi api(Cublas());
    return api;
  }
};

// ---- Kernels: thin loops over tensor_math.h ----

constexpr int kThreads = 256;

__device__ inline int64_t FirstIndex() {
  return static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
}
__device__ inline int64_t GridStride() { return static_cast<int64_t>(gridDim.x) * blockDim.x; }

__global__ void Im2ColKernel(const float* in, float* col, ConvGeometry g, int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride()) col[i] = Im2ColAt(in, g, i);
}

// In place: element i reads only acc[i] (and the bias), so out may be acc.
__global__ void BiasActivateKernel(float* out, const float* bias, int64_t plane, Activation act,
                                   int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride()) {
    out[i] = BiasActivateAt(out, bias, plane, act, i);
  }
}

__global__ void ConvTransposeKernel(const float* taps, const float* bias, float* out,
                                    ConvTransposeGeometry g, int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride())
    out[i] = ConvTransposeAt(taps, bias, g, i);
}

__global__ void UnaryKernel(const float* in, float* out, Activation act, int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride()) out[i] = Activate(in[i], act);
}

__global__ void BinaryKernel(const float* a, const float* b, float* out, BinaryGeometry g,
                             int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride()) out[i] = BinaryAt(a, b, g, i);
}

__global__ void CopyKernel(const float* in, float* out, CopyGeometry g, int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride()) {
    int64_t in_index = 0, out_index = 0;
    CopyIndices(g, i, &in_index, &out_index);
    out[out_index] = in[in_index];
  }
}

__global__ void MaxPoolKernel(const float* in, float* out, PoolGeometry g, int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride()) out[i] = MaxPoolAt(in, g, i);
}

__global__ void ResizeKernel(const float* in, float* out, ResizeGeometry g, int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride()) out[i] = ResizeNearestAt(in, g, i);
}

__global__ void TransposeKernel(const float* in, float* out, TransposeGeometry g, int64_t n) {
  for (int64_t i = FirstIndex(); i < n; i += GridStride()) out[i] = TransposeAt(in, g, i);
}

// One thread per row.
__global__ void SoftmaxKernel(const float* in, float* out, SoftmaxGeometry g, int64_t rows) {
  for (int64_t r = FirstIndex(); r < rows; r += GridStride()) SoftmaxRow(in, out, g, r);
}

// ---- Host side ----

std::string CudaErrorText(cudaError_t e) {
  return std::string(cudaGetErrorName(e)) + ": " + cudaGetErrorString(e);
}

int64_t ShapeCount(const std::vector<int64_t>& shape) {
  int64_t n = 1;
  for (int64_t d : shape) {
    if (d < 0) throw std::runtime_error("CUDA executor: negative dimension in a plan tensor shape");
    n *= d;
  }
  return n;
}

int64_t Product(int64_t a, int64_t b, int64_t c = 1) { return a * b * c; }

class CudaExecutor final : public Executor {
 public:
  CudaExecutor(std::shared_ptr<const NetPlan> plan, int device)
      : plan_(std::move(plan)), device_(device) {
    try {
      Init();
    } catch (...) {
      Release();
      throw;
    }
  }

  ~CudaExecutor() override { Release(); }

  CudaExecutor(const CudaExecutor&) = delete;
  CudaExecutor& operator=(const CudaExecutor&) = delete;

  std::string Name() const override { return name_; }

  void Launch(const float* input, const Done& done) override {
    step_ = -1;
    // The current device is per host thread; a pass may come from another thread than the
    // constructor, and its two halves from two threads.
    Check(cudaSetDevice(device_), "cudaSetDevice");
    // A pass that threw (or was never finished) may have left copies from the staging buffers
    // queued, and its callback may still be running; wait for them.
    Check(cudaStreamSynchronize(stream_), "cudaStreamSynchronize (start of a pass)");
    pass_end_.Reset();
    if (input_count_ > 0) {
      if (input == nullptr) throw std::runtime_error("CUDA executor: Launch() given a null input");
      std::memcpy(host_input_, input, static_cast<size_t>(input_count_) * sizeof(float));
      Check(cudaMemcpyAsync(buffers_[plan_->input.buffer], host_input_,
                            static_cast<size_t>(input_count_) * sizeof(float),
                            cudaMemcpyHostToDevice, stream_),
            "cudaMemcpyAsync (input)");
    }
    for (size_t i = 0; i < plan_->steps.size(); ++i) {
      step_ = static_cast<int>(i);
      std::visit([this](const auto& s) { RunStep(s); }, plan_->steps[i]);
    }
    step_ = -1;
    for (size_t i = 0; i < plan_->outputs.size(); ++i) {
      if (output_counts_[i] == 0) continue;
      Check(cudaMemcpyAsync(host_outputs_ + output_offsets_[i], buffers_[plan_->outputs[i].buffer],
                            static_cast<size_t>(output_counts_[i]) * sizeof(float),
                            cudaMemcpyDeviceToHost, stream_),
            "cudaMemcpyAsync (output)");
    }
    if (!done) return;
    Check(pass_end_.Arm(stream_, done), "cudaStreamAddCallback");
    // Nothing after this point: the callback may already have woken the caller's Finish().
  }

  void Finish(const std::vector<float*>& outputs) override {
    if (outputs.size() != plan_->outputs.size()) {
      throw std::invalid_argument("CUDA executor: one destination per plan output");
    }
    step_ = -1;
    Check(cudaSetDevice(device_), "cudaSetDevice");
    // Kernel faults surface here, after the last step; they cannot be attributed to a step.
    Check(cudaStreamSynchronize(stream_), "cudaStreamSynchronize (end of a pass)");
    Check(pass_end_.status(), "the forward pass (as its completion callback saw it)");
    for (size_t i = 0; i < outputs.size(); ++i) {
      const float* begin = host_outputs_ + output_offsets_[i];
      std::copy(begin, begin + output_counts_[i], outputs[i]);
    }
  }

  const NetPlan& plan() const override { return *plan_; }

 private:
  void Init() {
    if (!plan_) throw std::runtime_error("CUDA executor: null plan");
    Check(cudaSetDevice(device_), "cudaSetDevice");
    // A host thread waiting for the GPU sleeps instead of spinning: the pipeline's CPU stages
    // (ORB, filter, tracking) run on the same few cores meanwhile. The flag is the device's
    // primary context's, for the whole process; a runtime that refuses to change it on an active
    // context leaves the default (a warning-free fallback: only the waiting differs).
    if (cudaSetDeviceFlags(cudaDeviceScheduleBlockingSync) != cudaSuccess) cudaGetLastError();
    cudaDeviceProp prop{};
    Check(cudaGetDeviceProperties(&prop, device_), "cudaGetDeviceProperties");
    name_ = "cuda:" + std::to_string(device_) + " (" + prop.name + ")";
    // Enough blocks to fill the device; the grid-stride loops cover the rest.
    max_blocks_ = std::max(1, prop.multiProcessorCount) * 32;

    Check(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "cudaStreamCreateWithFlags");
    try {
      blas_ = &CublasApi::Get();  // opened by the first executor (cublas_library.h)
    } catch (const std::exception& e) {
      Fail(e.what());
    }
    Check(blas_->create(&cublas_), "cublasCreate");
    Check(blas_->set_stream(cublas_, stream_), "cublasSetStream");
    // Plain FP32 GEMMs (no TF32 tensor-op math), so that the results agree with the CPU twin's
    // Eigen GEMMs to float rounding (summation order aside). CUBLAS_DEFAULT_MATH is cuBLAS's
    // default already; set explicitly so that a change of default cannot slip in TF32.
    Check(blas_->set_math_mode(cublas_, CUBLAS_DEFAULT_MATH), "cublasSetMathMode");

    // Sizes first, so that a faulty plan is refused before anything is allocated for it.
    const std::vector<PlanBuffer>& bufs = plan_->buffers;
    sizes_.assign(bufs.size(), 0);
    for (size_t i = 0; i < bufs.size(); ++i) {
      sizes_[i] = std::max<int64_t>(bufs[i].size, static_cast<int64_t>(bufs[i].data.size()));
    }
    Validate();

    buffers_.assign(bufs.size(), nullptr);
    for (size_t i = 0; i < bufs.size(); ++i) {
      const int64_t floats = sizes_[i];
      if (floats <= 0) continue;
      const size_t bytes = static_cast<size_t>(floats) * sizeof(float);
      void* p = nullptr;
      Check(cudaMalloc(&p, bytes), "cudaMalloc (buffer " + std::to_string(i) + ")");
      buffers_[i] = static_cast<float*>(p);
      if (bufs[i].constant()) {
        // Uploaded once; the plan (and so the source) outlives the executor's construction.
        Check(cudaMemcpyAsync(p, bufs[i].data.data(), bufs[i].data.size() * sizeof(float),
                              cudaMemcpyHostToDevice, stream_),
              "cudaMemcpyAsync (constant buffer " + std::to_string(i) + ")");
      } else {
        Check(cudaMemsetAsync(p, 0, bytes, stream_),
              "cudaMemsetAsync (buffer " + std::to_string(i) + ")");
      }
    }
    if (plan_->scratch_size > 0) {
      void* p = nullptr;
      Check(cudaMalloc(&p, static_cast<size_t>(plan_->scratch_size) * sizeof(float)),
            "cudaMalloc (scratch)");
      scratch_ = static_cast<float*>(p);
    }

    // Pinned host staging of the input and the outputs.
    if (input_count_ > 0) {
      void* p = nullptr;
      Check(cudaMallocHost(&p, static_cast<size_t>(input_count_) * sizeof(float)),
            "cudaMallocHost (input staging)");
      host_input_ = static_cast<float*>(p);
    }
    const int64_t total_out =
        output_counts_.empty() ? 0 : output_offsets_.back() + output_counts_.back();
    if (total_out > 0) {
      void* p = nullptr;
      Check(cudaMallocHost(&p, static_cast<size_t>(total_out) * sizeof(float)),
            "cudaMallocHost (output staging)");
      host_outputs_ = static_cast<float*>(p);
    }

    Check(cudaStreamSynchronize(stream_), "cudaStreamSynchronize (uploads)");
  }

  // Frees everything; never throws (errors are ignored: nothing sensible to do with them here).
  void Release() noexcept {
    if (device_ >= 0) cudaSetDevice(device_);
    if (stream_) cudaStreamSynchronize(stream_);
    for (float*& p : buffers_) {
      if (p) cudaFree(p);
      p = nullptr;
    }
    if (scratch_) cudaFree(scratch_);
    scratch_ = nullptr;
    if (host_input_) cudaFreeHost(host_input_);
    host_input_ = nullptr;
    if (host_outputs_) cudaFreeHost(host_outputs_);
    host_outputs_ = nullptr;
    if (cublas_) blas_->destroy(cublas_);
    cublas_ = nullptr;
    if (stream_) cudaStreamDestroy(stream_);
    stream_ = nullptr;
    cudaGetLastError();  // do not leave a (non-sticky) error behind for the next caller
  }

  // ---- Error reporting ----

  std::string Where() const {
    if (step_ < 0) return "";
    std::string node = static_cast<size_t>(step_) < plan_->step_names.size()
                           ? plan_->step_names[static_cast<size_t>(step_)]
                           : std::string("?");
    return " (step " + std::to_string(step_) + ", node '" + node + "')";
  }

  [[noreturn]] void Fail(const std::string& what) const {
    throw std::runtime_error("CUDA executor on " +
                             (name_.empty() ? "device " + std::to_string(device_) : name_) + ": " +
                             what + Where());
  }

  void Check(cudaError_t e, const std::string& call) const {
    if (e == cudaSuccess) return;
    cudaGetLastError();  // clear a non-sticky error so that the executor stays usable
    Fail(call + " failed: " + CudaErrorText(e));
  }

  void Check(cublasStatus_t s, const std::string& call) const {
    if (s == CUBLAS_STATUS_SUCCESS) return;
    Fail(call + " failed: " + blas_->status_string(s));
  }

  void CheckLaunch(const char* kernel) const {
    Check(cudaGetLastError(), std::string("launch of ") + kernel);
  }

  // Buffer `index` exists on the device and holds at least `floats` floats.
  void RequireBuffer(int index, int64_t floats, const std::string& role) const {
    if (index < 0 || static_cast<size_t>(index) >= sizes_.size()) {
      Fail("plan error: " + role + " buffer " + std::to_string(index) + " out of range (" +
           std::to_string(sizes_.size()) + " buffers)");
    }
    if (floats > sizes_[static_cast<size_t>(index)]) {
      Fail("plan error: " + role + " buffer " + std::to_string(index) + " holds " +
           std::to_string(sizes_[static_cast<size_t>(index)]) + " floats, needs " +
           std::to_string(floats));
    }
  }
  void RequireScratch(int64_t floats) const {
    if (floats > plan_->scratch_size) {
      Fail("plan error: scratch holds " + std::to_string(plan_->scratch_size) + " floats, needs " +
           std::to_string(floats));
    }
  }
  void RequireGemmDims(int64_t m, int64_t n, int64_t k) const {
    constexpr int64_t kMax = std::numeric_limits<int>::max();
    if (m > kMax || n > kMax || k > kMax)
      Fail("plan error: GEMM dimension beyond cuBLAS's int range");
  }

  // ---- Validation at construction (sizes as each step's kernels use them) ----

  // The input, the outputs and every step's buffers exist and are large enough for what the
  // copies and kernels touch, so that a faulty plan is refused rather than corrupting device
  // memory. Fills input_count_ and the output counts and offsets.
  void Validate() {
    input_count_ = ShapeCount(plan_->input.shape);
    if (input_count_ > 0) RequireBuffer(plan_->input.buffer, input_count_, "input");
    int64_t total_out = 0;
    for (const PlanTensor& t : plan_->outputs) {
      const int64_t n = ShapeCount(t.shape);
      if (n > 0) RequireBuffer(t.buffer, n, "output '" + t.name + "'");
      output_offsets_.push_back(total_out);
      output_counts_.push_back(n);
      total_out += n;
    }
    for (size_t i = 0; i < plan_->steps.size(); ++i) {
      step_ = static_cast<int>(i);
      std::visit([this](const auto& s) { Validate(s); }, plan_->steps[i]);
    }
    step_ = -1;
  }

  void Validate(const ConvStep& s) const {
    const ConvGeometry& g = s.geometry;
    const int64_t k = ColRows(g), n = ColCols(g), m = g.c_out;
    RequireBuffer(s.in, Product(g.c_in, g.h_in, g.w_in), "conv input");
    RequireBuffer(s.out, m * n, "conv output");
    RequireBuffer(s.weight, m * k, "conv weight");
    if (s.bias >= 0) RequireBuffer(s.bias, m, "conv bias");
    if (IsPointwise(g)) {
      if (k != g.c_in || n != Product(g.h_in, g.w_in)) Fail("plan error: pointwise conv shapes");
    } else {
      RequireScratch(k * n);
    }
    RequireGemmDims(m, n, k);
  }
  void Validate(const ConvTransposeStep& s) const {
    const ConvTransposeGeometry& g = s.geometry;
    const int64_t m = Product(g.c_out, g.kh, g.kw), n = Product(g.h_in, g.w_in), k = g.c_in;
    RequireBuffer(s.in, k * n, "conv-transpose input");
    RequireBuffer(s.out, ConvTransposeOutCount(g), "conv-transpose output");
    RequireBuffer(s.weight, m * k, "conv-transpose weight");
    if (s.bias >= 0) RequireBuffer(s.bias, g.c_out, "conv-transpose bias");
    RequireScratch(m * n);
    RequireGemmDims(m, n, k);
  }
  void Validate(const UnaryStep& s) const {
    RequireBuffer(s.in, s.count, "unary input");
    RequireBuffer(s.out, s.count, "unary output");
  }
  void Validate(const BinaryStep& s) const {
    // The operands' extents follow from the broadcast strides: the largest index each reads.
    const BinaryGeometry& g = s.geometry;
    if (g.rank < 0 || g.rank > kMaxRank) Fail("plan error: binary rank out of range");
    int64_t last_a = 0, last_b = 0;
    for (int d = 0; d < g.rank; ++d) {
      if (g.out_shape[d] <= 0) return;  // empty output: nothing read or written
      last_a += (g.out_shape[d] - 1) * g.a_strides[d];
      last_b += (g.out_shape[d] - 1) * g.b_strides[d];
    }
    if (s.count <= 0) return;
    RequireBuffer(s.a, last_a + 1, "binary operand a");
    RequireBuffer(s.b, last_b + 1, "binary operand b");
    RequireBuffer(s.out, s.count, "binary output");
  }
  void Validate(const CopyStep& s) const {
    const CopyGeometry& g = s.geometry;
    if (CopyCount(g) <= 0) return;
    RequireBuffer(s.in, Product(g.outer, g.in_axis, g.inner), "copy input");
    RequireBuffer(s.out, Product(g.outer, g.out_axis, g.inner), "copy output");
    // in_step may be negative (a reversed Slice): check both ends of the input positions.
    const int64_t in_first = g.in_offset, in_last = g.in_offset + (g.count - 1) * g.in_step;
    if (std::min(in_first, in_last) < 0 || std::max(in_first, in_last) >= g.in_axis ||
        g.out_offset < 0 || g.out_offset + g.count > g.out_axis) {
      Fail("plan error: copy block outside its axis");
    }
  }
  void Validate(const MaxPoolStep& s) const {
    const PoolGeometry& g = s.geometry;
    RequireBuffer(s.in, Product(g.channels, g.h_in, g.w_in), "max-pool input");
    RequireBuffer(s.out, PoolOutCount(g), "max-pool output");
  }
  void Validate(const ResizeStep& s) const {
    const ResizeGeometry& g = s.geometry;
    RequireBuffer(s.in, Product(g.channels, g.h_in, g.w_in), "resize input");
    RequireBuffer(s.out, ResizeOutCount(g), "resize output");
  }
  void Validate(const TransposeStep& s) const {
    RequireBuffer(s.in, s.count, "transpose input");
    RequireBuffer(s.out, s.count, "transpose output");
  }
  void Validate(const SoftmaxStep& s) const {
    const SoftmaxGeometry& g = s.geometry;
    const int64_t n = Product(g.outer, g.axis, g.inner);
    RequireBuffer(s.in, n, "softmax input");
    RequireBuffer(s.out, n, "softmax output");
  }

  // ---- Steps ----

  int Blocks(int64_t n) const {
    return static_cast<int>(std::min<int64_t>((n + kThreads - 1) / kThreads, max_blocks_));
  }
  float* Buf(int index) const {
    return index >= 0 ? buffers_[static_cast<size_t>(index)] : nullptr;
  }

  // Row-major C[m x n] = A[m x k] * B[k x n]. cuBLAS is column-major, and a row-major matrix is
  // its transpose seen column-major, so compute C^T = B^T A^T: cuBLAS's (m, n, k) = (n, m, k)
  // with B first.
  void GemmRowMajor(int64_t m, int64_t n, int64_t k, const float* a, const float* b, float* c) {
    if (m <= 0 || n <= 0) return;
    const float one = 1.0f, zero = 0.0f;
    const int mi = static_cast<int>(m), ni = static_cast<int>(n), ki = static_cast<int>(k);
    Check(blas_->sgemm(cublas_, CUBLAS_OP_N, CUBLAS_OP_N, ni, mi, ki, &one, b, ni, a,
                       std::max(ki, 1), &zero, c, ni),
          "cublasSgemm");
  }

  void RunStep(const ConvStep& s) {
    const ConvGeometry& g = s.geometry;
    const int64_t k = ColRows(g), n = ColCols(g), m = g.c_out;
    const float* col = Buf(s.in);
    if (!IsPointwise(g)) {
      const int64_t count = k * n;
      if (count > 0) {
        Im2ColKernel<<<Blocks(count), kThreads, 0, stream_>>>(Buf(s.in), scratch_, g, count);
        CheckLaunch("Im2ColKernel");
      }
      col = scratch_;
    }
    float* out = Buf(s.out);
    GemmRowMajor(m, n, k, Buf(s.weight), col, out);
    const int64_t count = m * n;
    if (count > 0) {
      BiasActivateKernel<<<Blocks(count), kThreads, 0, stream_>>>(out, Buf(s.bias), n, s.activation,
                                                                  count);
      CheckLaunch("BiasActivateKernel");
    }
  }

  void RunStep(const ConvTransposeStep& s) {
    const ConvTransposeGeometry& g = s.geometry;
    const int64_t m = Product(g.c_out, g.kh, g.kw), n = Product(g.h_in, g.w_in), k = g.c_in;
    GemmRowMajor(m, n, k, Buf(s.weight), Buf(s.in), scratch_);
    const int64_t count = ConvTransposeOutCount(g);
    if (count > 0) {
      ConvTransposeKernel<<<Blocks(count), kThreads, 0, stream_>>>(scratch_, Buf(s.bias),
                                                                   Buf(s.out), g, count);
      CheckLaunch("ConvTransposeKernel");
    }
  }

  void RunStep(const UnaryStep& s) {
    if (s.count <= 0) return;
    UnaryKernel<<<Blocks(s.count), kThreads, 0, stream_>>>(Buf(s.in), Buf(s.out), s.activation,
                                                           s.count);
    CheckLaunch("UnaryKernel");
  }

  void RunStep(const BinaryStep& s) {
    if (s.count <= 0) return;
    BinaryKernel<<<Blocks(s.count), kThreads, 0, stream_>>>(Buf(s.a), Buf(s.b), Buf(s.out),
                                                            s.geometry, s.count);
    CheckLaunch("BinaryKernel");
  }

  void RunStep(const CopyStep& s) {
    const int64_t count = CopyCount(s.geometry);
    if (count <= 0) return;
    CopyKernel<<<Blocks(count), kThreads, 0, stream_>>>(Buf(s.in), Buf(s.out), s.geometry, count);
    CheckLaunch("CopyKernel");
  }

  void RunStep(const MaxPoolStep& s) {
    const PoolGeometry& g = s.geometry;
    const int64_t count = PoolOutCount(g);
    if (count <= 0) return;
    MaxPoolKernel<<<Blocks(count), kThreads, 0, stream_>>>(Buf(s.in), Buf(s.out), g, count);
    CheckLaunch("MaxPoolKernel");
  }

  void RunStep(const ResizeStep& s) {
    const ResizeGeometry& g = s.geometry;
    const int64_t count = ResizeOutCount(g);
    if (count <= 0) return;
    ResizeKernel<<<Blocks(count), kThreads, 0, stream_>>>(Buf(s.in), Buf(s.out), g, count);
    CheckLaunch("ResizeKernel");
  }

  void RunStep(const TransposeStep& s) {
    if (s.count <= 0) return;
    TransposeKernel<<<Blocks(s.count), kThreads, 0, stream_>>>(Buf(s.in), Buf(s.out), s.geometry,
                                                               s.count);
    CheckLaunch("TransposeKernel");
  }

  void RunStep(const SoftmaxStep& s) {
    const SoftmaxGeometry& g = s.geometry;
    const int64_t rows = g.outer * g.inner;
    if (rows <= 0 || g.axis <= 0) return;
    SoftmaxKernel<<<Blocks(rows), kThreads, 0, stream_>>>(Buf(s.in), Buf(s.out), g, rows);
    CheckLaunch("SoftmaxKernel");
  }

  std::shared_ptr<const NetPlan> plan_;
  int device_ = -1;
  std::string name_;
  int max_blocks_ = 1;
  int step_ = -1;  // the step being validated or enqueued, for error messages; -1 outside steps

  cudaStream_t stream_ = nullptr;
  const CublasApi* blas_ = nullptr;  // set before cublas_
  cublasHandle_t cublas_ = nullptr;
  std::vector<float*> buffers_;  // per plan buffer; null where the plan's buffer is empty
  std::vector<int64_t> sizes_;   // floats allocated per plan buffer
  float* scratch_ = nullptr;

  int64_t input_count_ = 0;
  float* host_input_ = nullptr;    // pinned staging of the input
  float* host_outputs_ = nullptr;  // pinned staging of all outputs, back to back
  CudaPassEnd pass_end_;           // of the launched pass
  std::vector<int64_t> output_offsets_, output_counts_;
};

}  // namespace

bool CudaExecutorBuilt() { return true; }

int CudaDeviceCount(std::string* why) {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess) {
    cudaGetLastError();  // the failed query must not look like a later call's error
    if (why) *why = CudaErrorText(e);
    return 0;
  }
  if (count <= 0) {
    if (why) *why = "the CUDA runtime reports no device";
    return 0;
  }
  return count;
}

std::unique_ptr<Executor> MakeCudaExecutor(std::shared_ptr<const NetPlan> plan, int device) {
  if (!plan) throw std::runtime_error("MakeCudaExecutor: null plan");
  std::string why;
  const int count = CudaDeviceCount(&why);
  if (count == 0) throw std::runtime_error("no CUDA device: " + why);
  if (device < 0 || device >= count) {
    throw std::runtime_error("no CUDA device: device " + std::to_string(device) +
                             " requested, the CUDA runtime sees " + std::to_string(count));
  }
  return std::make_unique<CudaExecutor>(std::move(plan), device);
}

std::string CublasStatusText(int status) {
  return CublasApi::Get().status_string(static_cast<cublasStatus_t>(status));
}

}  // namespace pcr::gpu
