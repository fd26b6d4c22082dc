// The CUDA LK flow engine (lk_flow.h): one warp per point runs LkTrackPoint (lk_math.h), the
// function the CPU twin runs with a group of one lane, on the engine's own stream.
//
// Pyramids are uploaded whole (every level's padded buffer, borders included, so that border
// reads see what the host buffers hold) into a small cache keyed by identity: an entry holds
// copies of the pyramid's cv::Mat headers, which keeps the host buffers alive, so that a buffer
// address seen again while cached is the same pyramid (FlowEngine's contract: not modified while
// an engine may hold it). A filter's frame pyramid, `to` of one pass and `from` of the next
// frame's, is uploaded once.
#include <cuda_runtime.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "gpu/cuda_pass_end.cuh"
#include "gpu/executor.h"
#include "gpu/lk_flow.h"
#include "gpu/lk_math.h"

namespace pcr::gpu {
namespace {

constexpr int kWarp = 32;
constexpr int kWarpsPerBlock = 4;
constexpr size_t kSharedBytesLimit = 48 * 1024;  // dynamic shared memory without an opt-in
constexpr size_t kPitchAlign = 256;
constexpr int kCacheEntries = 3;

// The lanes of one warp tracking one point together (see LkSerialLanes).
struct WarpLanes {
  int16_t* image_window = nullptr;
  int16_t* deriv_window = nullptr;
  int first = 0;  // the lane
  int stride = kWarp;
  PCR_HD int64_t Sum(int64_t v) const {
#if defined(__CUDA_ARCH__)
    for (int offset = kWarp / 2; offset > 0; offset >>= 1) {
      v += __shfl_xor_sync(0xffffffffu, v, offset);
    }
#endif
    return v;
  }
};

// Warp w of a block tracks points blockIdx.x * warps + w, then every gridDim.x * warps-th. Each
// warp's window buffers: 3 * window_stride int16 of the dynamic shared memory.
__global__ void __launch_bounds__(kWarp* kWarpsPerBlock)
    LkTrackKernel(LkPyramidViews views, LkSettings settings, const float2* from,
                  const float2* guess, LkPointResult* out, int n, int window_stride) {
  extern __shared__ int16_t window_buffers[];
  const int warp = static_cast<int>(threadIdx.x) / kWarp;
  const int warps = static_cast<int>(blockDim.x) / kWarp;
  WarpLanes lanes;
  lanes.image_window = window_buffers + warp * 3 * window_stride;
  lanes.deriv_window = lanes.image_window + window_stride;
  lanes.first = static_cast<int>(threadIdx.x) % kWarp;
  for (int i = static_cast<int>(blockIdx.x) * warps + warp; i < n;
       i += static_cast<int>(gridDim.x) * warps) {
    const float2 p = from[i];
    const float2 g = settings.use_initial_flow ? guess[i] : p;
    const LkPointResult r = LkTrackPoint(lanes, views, settings, p.x, p.y, g.x, g.y);
    if (lanes.first == 0) out[i] = r;
  }
}

std::string CudaErrorText(cudaError_t e) {
  return std::string(cudaGetErrorName(e)) + " (" + cudaGetErrorString(e) + ")";
}

class CudaLkFlowEngine final : public FlowEngine {
 public:
  explicit CudaLkFlowEngine(int device) : device_(device) {
    try {
      Init();
    } catch (...) {
      Release();
      throw;
    }
  }
  ~CudaLkFlowEngine() override { Release(); }
  CudaLkFlowEngine(const CudaLkFlowEngine&) = delete;
  CudaLkFlowEngine& operator=(const CudaLkFlowEngine&) = delete;

  void Track(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
             const std::vector<cv::Point2f>& from_pts, std::vector<cv::Point2f>& to_pts,
             std::vector<uint8_t>& status, std::vector<float>& error, const LkPass& pass) override {
    const LkSettings settings =
        lk_detail::CheckTrackInputs(from, to, from_pts.size(), to_pts.size(), pass);
    const int area = settings.window * settings.window;
    const int window_stride = (area + 1) / 2 * 2;
    const size_t warp_bytes = 3 * static_cast<size_t>(window_stride) * sizeof(int16_t);
    if (warp_bytes > kSharedBytesLimit) {
      throw std::invalid_argument("FlowEngine::Track (lk) on " + name_ + ": a " +
                                  std::to_string(settings.window) +
                                  " px window does not fit the CUDA engine's shared memory");
    }
    const int warps_per_block =
        static_cast<int>(std::min<size_t>(kWarpsPerBlock, kSharedBytesLimit / warp_bytes));
    const int n = static_cast<int>(from_pts.size());
    Check(cudaSetDevice(device_), "cudaSetDevice");
    if (n > 0) {
      Reserve(n);
      for (int i = 0; i < n; ++i) {
        const cv::Point2f guess = settings.use_initial_flow ? to_pts[i] : from_pts[i];
        host_points_[i] = make_float2(from_pts[i].x, from_pts[i].y);
        host_points_[n + i] = make_float2(guess.x, guess.y);
      }
    }
    to_pts.resize(from_pts.size());
    status.resize(from_pts.size());
    error.resize(from_pts.size());
    if (n == 0) return;

    // Queues the uploads, the kernel and the download; throws before anything waits on it.
    auto enqueue = [&]() {
      // Both looked up before either is uploaded, so that one upload cannot evict the other.
      const Cached* from_gpu = Find(from);
      const Cached* to_gpu = Find(to);
      if (!from_gpu) from_gpu = &Upload(from, to_gpu);
      if (!to_gpu) to_gpu = Find(to);  // `to` may be `from`
      if (!to_gpu) to_gpu = &Upload(to, from_gpu);
      const LkPyramidViews views = DeviceViews(*from_gpu, *to_gpu, pass.max_level);
      Check(
          cudaMemcpyAsync(device_points_, host_points_, 2 * static_cast<size_t>(n) * sizeof(float2),
                          cudaMemcpyHostToDevice, stream_),
          "cudaMemcpyAsync (points)");
      const int blocks = std::min((n + warps_per_block - 1) / warps_per_block, max_blocks_);
      LkTrackKernel<<<blocks, warps_per_block * kWarp, warps_per_block * warp_bytes, stream_>>>(
          views, settings, device_points_, device_points_ + n, device_results_, n, window_stride);
      Check(cudaGetLastError(), "launch of LkTrackKernel");
      Check(cudaMemcpyAsync(host_results_, device_results_,
                            static_cast<size_t>(n) * sizeof(LkPointResult), cudaMemcpyDeviceToHost,
                            stream_),
            "cudaMemcpyAsync (results)");
    };
    pass_end_.Reset();
    if (wait_) {
      // A launch that throws has not arranged for done(): the wait passes the exception on.
      wait_([&](const DeviceDone& done) {
        enqueue();
        Check(pass_end_.Arm(stream_, done), "cudaStreamAddCallback");
        // Nothing after this point: the callback may already have woken the waiter.
      });
      // The wait may have resumed on another thread: the current device is per thread.
      Check(cudaSetDevice(device_), "cudaSetDevice (after the wait)");
    } else {
      enqueue();
    }
    // Kernel faults surface here; they cannot be attributed further.
    Check(cudaStreamSynchronize(stream_), "cudaStreamSynchronize (end of a pass)");
    Check(pass_end_.status(), "the LK pass (as its completion callback saw it)");
    for (int i = 0; i < n; ++i) {
      const LkPointResult& r = host_results_[i];
      to_pts[i] = cv::Point2f(r.x, r.y);
      status[i] = r.status;
      error[i] = r.error;
    }
  }

  std::string Name() const override { return name_; }

  void SetDeviceWait(DeviceWait wait) override { wait_ = std::move(wait); }

 private:
  // One Mat of a cached pyramid on the device: its readable region, borders included, at
  // `offset` bytes into the entry's allocation, rows `pitch` bytes apart.
  struct Plane {
    size_t offset = 0;
    size_t pitch = 0;
    int border = 0;
    int cols = 0, rows = 0;
    size_t pixel_bytes = 0;
  };
  struct Cached {
    std::vector<cv::Mat> mats;  // the pyramid's headers (empty: a free entry)
    std::vector<Plane> planes;  // one per Mat
    uint8_t* device = nullptr;
    size_t capacity = 0;
    uint64_t last_use = 0;
  };

  static bool SamePyramid(const std::vector<cv::Mat>& cached, const std::vector<cv::Mat>& p) {
    if (cached.empty() || cached.size() != p.size()) return false;
    for (size_t i = 0; i < p.size(); ++i) {
      const cv::Mat& a = cached[i];
      const cv::Mat& b = p[i];
      if (a.data != b.data || a.type() != b.type() || a.size() != b.size() ||
          a.step[0] != b.step[0]) {
        return false;
      }
    }
    return true;
  }

  // The cache entry holding `pyramid`, if any (marked as used).
  const Cached* Find(const std::vector<cv::Mat>& pyramid) {
    for (Cached& c : cache_) {
      if (SamePyramid(c.mats, pyramid)) {
        c.last_use = ++use_clock_;
        return &c;
      }
    }
    return nullptr;
  }

  // Uploads `pyramid` into a free cache entry, else into the least recently used one other than
  // `keep`, and returns the entry.
  const Cached& Upload(const std::vector<cv::Mat>& pyramid, const Cached* keep) {
    // Free entries first, then the least recently used.
    auto rank = [](const Cached& c) { return c.mats.empty() ? 0 : c.last_use + 1; };
    Cached* victim = nullptr;
    for (Cached& c : cache_) {
      if (&c != keep && (!victim || rank(c) < rank(*victim))) victim = &c;
    }
    victim->mats.clear();
    victim->planes.clear();
    std::vector<Plane> planes;
    std::vector<lk_detail::StoredLevel> stored;
    size_t total = 0;
    for (const cv::Mat& m : pyramid) {
      const lk_detail::StoredLevel s = lk_detail::LocateStoredLevel(m);
      Plane plane;
      plane.offset = total;
      plane.pitch = (s.row_bytes + kPitchAlign - 1) / kPitchAlign * kPitchAlign;
      plane.border = s.border;
      plane.cols = m.cols;
      plane.rows = m.rows;
      plane.pixel_bytes = m.elemSize();
      total += plane.pitch * static_cast<size_t>(s.rows);
      planes.push_back(plane);
      stored.push_back(s);
    }
    if (victim->capacity < total) {
      if (victim->device) {
        Check(cudaStreamSynchronize(stream_),
              "cudaStreamSynchronize (before a cache reallocation)");
        Check(cudaFree(victim->device), "cudaFree (pyramid cache)");
      }
      victim->device = nullptr;
      victim->capacity = 0;
      void* p = nullptr;
      Check(cudaMalloc(&p, total),
            "cudaMalloc (pyramid cache, " + std::to_string(total) + " bytes)");
      victim->device = static_cast<uint8_t*>(p);
      victim->capacity = total;
    }
    for (size_t i = 0; i < pyramid.size(); ++i) {
      const Plane& plane = planes[i];
      Check(cudaMemcpy2DAsync(victim->device + plane.offset, plane.pitch, stored[i].first,
                              pyramid[i].step[0], stored[i].row_bytes,
                              static_cast<size_t>(stored[i].rows), cudaMemcpyHostToDevice, stream_),
            "cudaMemcpy2DAsync (pyramid level " + std::to_string(i / 2) + ")");
    }
    // Only a complete upload becomes an entry.
    victim->mats = pyramid;
    victim->planes = std::move(planes);
    victim->last_use = ++use_clock_;
    return *victim;
  }

  static LkImageView ImageView(const Cached& c, size_t index) {
    const Plane& p = c.planes[index];
    LkImageView v;
    v.origin = c.device + p.offset + static_cast<size_t>(p.border) * p.pitch +
               static_cast<size_t>(p.border) * p.pixel_bytes;
    v.step = static_cast<int>(p.pitch);
    v.cols = p.cols;
    v.rows = p.rows;
    v.border = p.border;
    return v;
  }

  static LkPyramidViews DeviceViews(const Cached& from, const Cached& to, int max_level) {
    LkPyramidViews views;
    views.max_level = max_level;
    for (int l = 0; l <= max_level; ++l) {
      LkLevelViews& level = views.level[l];
      level.from_image = ImageView(from, 2 * static_cast<size_t>(l));
      level.to_image = ImageView(to, 2 * static_cast<size_t>(l));
      const LkImageView deriv = ImageView(from, 2 * static_cast<size_t>(l) + 1);
      level.from_deriv.origin = reinterpret_cast<const int16_t*>(deriv.origin);
      level.from_deriv.step = deriv.step / static_cast<int>(sizeof(int16_t));
      level.from_deriv.cols = deriv.cols;
      level.from_deriv.rows = deriv.rows;
      level.from_deriv.border = deriv.border;
    }
    return views;
  }

  // Room for n points: pinned staging and device buffers (starts and guesses in, results out).
  void Reserve(int n) {
    if (n <= capacity_) return;
    Check(cudaStreamSynchronize(stream_), "cudaStreamSynchronize (before a reallocation)");
    FreePoints();
    const int capacity = std::max(n, 2 * capacity_);
    const size_t in_bytes = 2 * static_cast<size_t>(capacity) * sizeof(float2);
    const size_t out_bytes = static_cast<size_t>(capacity) * sizeof(LkPointResult);
    void* p = nullptr;
    Check(cudaMallocHost(&p, in_bytes), "cudaMallocHost (points)");
    host_points_ = static_cast<float2*>(p);
    Check(cudaMallocHost(&p, out_bytes), "cudaMallocHost (results)");
    host_results_ = static_cast<LkPointResult*>(p);
    Check(cudaMalloc(&p, in_bytes), "cudaMalloc (points)");
    device_points_ = static_cast<float2*>(p);
    Check(cudaMalloc(&p, out_bytes), "cudaMalloc (results)");
    device_results_ = static_cast<LkPointResult*>(p);
    capacity_ = capacity;
  }

  void FreePoints() noexcept {
    if (host_points_) cudaFreeHost(host_points_);
    if (host_results_) cudaFreeHost(host_results_);
    if (device_points_) cudaFree(device_points_);
    if (device_results_) cudaFree(device_results_);
    host_points_ = nullptr;
    host_results_ = nullptr;
    device_points_ = nullptr;
    device_results_ = nullptr;
    capacity_ = 0;
  }

  void Init() {
    Check(cudaSetDevice(device_), "cudaSetDevice");
    // A host thread waiting for the GPU sleeps instead of spinning (as the CUDA executor asks;
    // the flag is the device's, for the whole process; a refusal leaves the default).
    if (cudaSetDeviceFlags(cudaDeviceScheduleBlockingSync) != cudaSuccess) cudaGetLastError();
    cudaDeviceProp prop{};
    Check(cudaGetDeviceProperties(&prop, device_), "cudaGetDeviceProperties");
    name_ = "cuda:" + std::to_string(device_) + " (" + prop.name + ")";
    max_blocks_ = std::max(1, prop.multiProcessorCount) * 16;
    Check(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "cudaStreamCreateWithFlags");
    cache_.resize(kCacheEntries);
  }

  // Frees everything; never throws (errors are ignored: nothing sensible to do with them here).
  void Release() noexcept {
    cudaSetDevice(device_);
    if (stream_) cudaStreamSynchronize(stream_);
    for (Cached& c : cache_) {
      if (c.device) cudaFree(c.device);
      c.device = nullptr;
      c.capacity = 0;
      c.mats.clear();
    }
    FreePoints();
    if (stream_) cudaStreamDestroy(stream_);
    stream_ = nullptr;
    cudaGetLastError();  // do not leave a (non-sticky) error behind for the next caller
  }

  void Check(cudaError_t e, const std::string& call) const {
    if (e == cudaSuccess) return;
    cudaGetLastError();  // clear a non-sticky error so that the engine stays usable
    throw std::runtime_error("CUDA LK flow engine on " +
                             (name_.empty() ? "cuda:" + std::to_string(device_) : name_) + ": " +
                             call + " failed: " + CudaErrorText(e));
  }

  int device_ = 0;
  std::string name_;
  int max_blocks_ = 1;
  cudaStream_t stream_ = nullptr;
  std::vector<Cached> cache_;
  uint64_t use_clock_ = 0;
  int capacity_ = 0;  // points
  float2* host_points_ = nullptr;
  LkPointResult* host_results_ = nullptr;
  float2* device_points_ = nullptr;
  LkPointResult* device_results_ = nullptr;
  DeviceWait wait_;       // empty: Track() blocks on the stream
  CudaPassEnd pass_end_;  // of the pass in flight
};

}  // namespace

namespace lk_detail {

std::unique_ptr<FlowEngine> MakeCudaLkFlowEngine(int device) {
  std::string why;
  const int count = CudaDeviceCount(&why);
  const std::string where = "LK flow engine on cuda:" + std::to_string(device) + ": ";
  if (count <= 0) throw std::runtime_error(where + "no CUDA device (" + why + ")");
  if (device < 0 || device >= count) {
    throw std::runtime_error(where + "no such device (the CUDA runtime sees " +
                             std::to_string(count) + ")");
  }
  return std::make_unique<CudaLkFlowEngine>(device);
}

}  // namespace lk_detail
}  // namespace pcr::gpu
