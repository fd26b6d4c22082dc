#pragma once
// The end of a pass queued on a CUDA stream, shared by the CUDA engines (cuda_executor.cu,
// lk_flow_cuda.cu) for their launch / wait split: a host callback queued after the pass's work
// calls the waiter's done() and records the status the stream ended with. CUDA-only (included by
// .cu files only: a .cuh, which tests/layering_check.sh keeps out of host-compiled files).
#include <cuda_runtime.h>

#include <atomic>
#include <functional>
#include <utility>

namespace pcr::gpu {

class CudaPassEnd {
 public:
  // Before a pass is queued: forgets the last pass's status.
  void Reset() { status_.store(cudaSuccess); }

  // After the pass's work is queued on `stream`: `done` is called exactly once, from a CUDA
  // runtime thread, when the stream gets there (it must not block or call CUDA). Uses
  // cudaStreamAddCallback, not cudaLaunchHostFunc: its callback runs exactly once also after a
  // device error (with the error), so a waiter is always woken. Returns the error of
  // cudaStreamAddCallback, and then `done` will not be called. Nothing of the pass may be touched
  // after a success: the callback may already have woken the waiter.
  cudaError_t Arm(cudaStream_t stream, std::function<void()> done) {
    done_ = std::move(done);
    const cudaError_t e = cudaStreamAddCallback(stream, &CudaPassEnd::OnEnd, this, 0);
    if (e != cudaSuccess) done_ = nullptr;
    return e;
  }

  // The error the stream reported to the callback (cudaSuccess before it ran, or without one).
  cudaError_t status() const { return status_.load(); }

 private:
  // On a CUDA runtime thread: no CUDA calls, no blocking.
  static void CUDART_CB OnEnd(cudaStream_t /*stream*/, cudaError_t status, void* self_ptr) {
    auto* self = static_cast<CudaPassEnd*>(self_ptr);
    self->status_.store(status);
    // Moved out first: the woken caller may start the next pass (which arms again) while this
    // call is still returning.
    std::function<void()> done = std::move(self->done_);
    self->done_ = nullptr;
    done();
  }

  std::function<void()> done_;  // of the armed pass
  std::atomic<cudaError_t> status_{cudaSuccess};
};

}  // namespace pcr::gpu
