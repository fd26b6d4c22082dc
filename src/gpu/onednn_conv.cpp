// The oneDNN convolutions of the CPU executor "onednn" (executor.h: MakeOneDnnConvKernels). The
// rest of the plan's steps run as the twin's. Built when CMake finds libdnnl (PCR_HAVE_ONEDNN);
// otherwise the functions say the build has none.
#include <algorithm>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <variant>
#include <vector>

#include "gpu/executor.h"

#if defined(PCR_HAVE_ONEDNN)
#include <omp.h>

#include <cstdlib>
#include <mutex>
#include <oneapi/dnnl/dnnl.hpp>
#include <opencv2/core/utility.hpp>

#include "slam/common/log.h"
#endif

namespace pcr::gpu {

#if defined(PCR_HAVE_ONEDNN)
namespace {

using dnnl::memory;
using Tag = memory::format_tag;
using Type = memory::data_type;

// One convolution: the primitive, its weights and bias in the primitive's layout, and the
// reorders between the plan's NCHW buffers and the layout the primitive chose for its source and
// destination (none where it chose NCHW).
struct ConvPrimitive {
  dnnl::convolution_forward conv;
  memory user_src, user_dst;  // the plan's buffers (handles set per call)
  memory src, dst;            // the primitive's (the same objects as user_* without reorders)
  memory weights, bias;
  // Whether a call reorders the plan's source into src and dst into the plan's destination.
  // Neither runs where the convolutions are linked (LinkConvolutions): src is then the producing
  // convolution's dst.
  bool reorder_src = false, reorder_dst = false;
  dnnl::reorder to_src, from_dst;
  std::unordered_map<int, memory> args;  // the primitive's arguments, set once linked
};

// The OpenMP threads of a call: the calling thread's OpenCV thread count (the run's --threads).
int CallThreads() { return std::max(1, cv::getNumThreads()); }

// libgomp's threads spin at the end of each parallel region (about 170 a YOLO forward pass)
// unless OMP_WAIT_POLICY or GOMP_SPINCOUNT says otherwise, and libgomp reads them once, before
// main (Ceres' CHOLMOD links it too), so a program cannot choose for itself. Where other work
// shares the cores, a region then waits for a thread that is not running while another spins:
// measured on 2 cores with other processes on them, a 224x640 forward pass on 2 threads took
// 1112 ms against 90 ms with OMP_WAIT_POLICY=passive. Said once, when calls use more than one
// thread and the machine has other work (a load average of one or more).
void WarnOfSpinningThreads(int threads) {
  if (threads < 2 || std::getenv("OMP_WAIT_POLICY") || std::getenv("GOMP_SPINCOUNT")) return;
  double load = 0;
  if (getloadavg(&load, 1) != 1 || load < 1.0) return;
  static std::once_flag once;
  std::call_once(once, [threads, load] {
    Logger().warn(
        "inference onednn: {} OpenMP threads a convolution, which spin while they wait "
        "(OMP_WAIT_POLICY is not set), and the machine has other work (load average {:.1f}): a "
        "forward pass can take 10x longer. Set OMP_WAIT_POLICY=passive in the environment, or "
        "--threads 1",
        threads, load);
  });
}

class OneDnnConvKernels final : public ConvKernels {
 public:
  explicit OneDnnConvKernels(std::shared_ptr<const NetPlan> plan)
      : plan_(std::move(plan)), engine_(dnnl::engine::kind::cpu, 0), stream_(engine_) {
    Build(CallThreads());
  }

  void Conv(size_t step, const float* in, float* out) override {
    if (step >= convs_.size() || !convs_[step]) {
      throw std::invalid_argument("OneDnnConvKernels: step " + std::to_string(step) +
                                  " is not a convolution of the plan");
    }
    // A pass's first convolution takes the calling thread's count; the rest of the pass keeps
    // it (a linked convolution's input is in the memory of the primitive that wrote it).
    const int threads = CallThreads();
    if (step == first_conv_ && threads != threads_) Build(threads);
    omp_set_num_threads(threads_);
    ConvPrimitive& c = *convs_[step];
    c.user_src.set_data_handle(const_cast<float*>(in));
    c.user_dst.set_data_handle(out);
    if (c.reorder_src) c.to_src.execute(stream_, c.user_src, c.src);
    c.conv.execute(stream_, c.args);
    if (c.reorder_dst) c.from_dst.execute(stream_, c.dst, c.user_dst);
    stream_.wait();
  }

  std::string Name() const override { return "cpu-onednn"; }

 private:
  // Every convolution's primitive for `threads` OpenMP threads. oneDNN fixes a primitive's
  // thread count when it is made (omp_get_max_threads() then) and runs every call on that many,
  // whatever the calling thread's count is by then: made for 2 threads, a run with --threads 1
  // ran each convolution on 2. A pass whose thread count differs makes them again.
  void Build(int threads) {
    WarnOfSpinningThreads(threads);
    omp_set_num_threads(threads);
    const NetPlan& plan = *plan_;
    convs_.clear();
    convs_.resize(plan.steps.size());
    for (size_t s = 0; s < plan.steps.size(); ++s) {
      const auto* step = std::get_if<ConvStep>(&plan.steps[s]);
      if (!step) continue;
      try {
        convs_[s] = std::make_unique<ConvPrimitive>(BuildOne(plan, *step));
      } catch (const dnnl::error& e) {
        throw std::invalid_argument("oneDNN cannot run convolution '" +
                                    (s < plan.step_names.size() ? plan.step_names[s] : "?") +
                                    "' (step " + std::to_string(s) + "): " + e.what());
      }
    }
    first_conv_ = static_cast<size_t>(
        std::find_if(convs_.begin(), convs_.end(), [](const auto& c) { return c != nullptr; }) -
        convs_.begin());
    LinkConvolutions(plan);
    for (const std::unique_ptr<ConvPrimitive>& c : convs_) {
      if (!c) continue;
      c->args = {{DNNL_ARG_SRC, c->src}, {DNNL_ARG_WEIGHTS, c->weights}, {DNNL_ARG_DST, c->dst}};
      if (c->bias) c->args.emplace(DNNL_ARG_BIAS, c->bias);
    }
    threads_ = threads;
  }

  // A convolution whose output only convolutions read, in the layout it writes, hands them its
  // own memory: neither the reorder to NCHW after it nor those before them run, and the plan's
  // buffer stays unwritten (nothing else reads it). A reader is a step that reads the buffer
  // before the next step that writes it (buffers are shared between tensors whose lifetimes do
  // not overlap; a Reshape or Identity reads through the same buffer). The plan's input and
  // outputs stay NCHW.
  void LinkConvolutions(const NetPlan& plan) {
    std::vector<bool> external(plan.buffers.size(), false);
    external[plan.input.buffer] = true;
    for (const PlanTensor& t : plan.outputs) external[t.buffer] = true;
    for (size_t s = 0; s < plan.steps.size(); ++s) {
      if (!convs_[s] || !convs_[s]->reorder_dst) continue;
      const int buffer = std::get<ConvStep>(plan.steps[s]).out;
      if (external[buffer]) continue;
      std::vector<size_t> readers;
      bool only_convolutions = true;
      for (size_t t = s + 1; t < plan.steps.size() && only_convolutions; ++t) {
        const PlanStep& step = plan.steps[t];
        bool reads = false, writes = false;
        std::visit(
            [&](const auto& st) {
              using T = std::decay_t<decltype(st)>;
              if constexpr (std::is_same_v<T, BinaryStep>) {
                reads = st.a == buffer || st.b == buffer;
              } else {
                reads = st.in == buffer;
              }
              writes = st.out == buffer;
            },
            step);
        if (reads) {
          const bool same_layout = convs_[t] && convs_[t]->reorder_src &&
                                   convs_[t]->src.get_desc() == convs_[s]->dst.get_desc();
          if (!same_layout) only_convolutions = false;
          readers.push_back(t);
        }
        if (writes) break;
      }
      if (!only_convolutions || readers.empty()) continue;
      convs_[s]->reorder_dst = false;
      for (size_t t : readers) {
        convs_[t]->src = convs_[s]->dst;
        convs_[t]->reorder_src = false;
      }
    }
  }

  ConvPrimitive BuildOne(const NetPlan& plan, const ConvStep& s) {
    const ConvGeometry& g = s.geometry;
    const memory::dims src_dims{1, g.c_in, g.h_in, g.w_in};
    const memory::dims dst_dims{1, g.c_out, g.h_out, g.w_out};
    const memory::dims w_dims{g.c_out, g.c_in, g.kh, g.kw};
    // The right and bottom padding that give the plan's output size (floor division: a negative
    // remainder means the last rows are not read).
    const int pad_bottom = std::max(
        0, (g.h_out - 1) * g.stride_h + (g.kh - 1) * g.dilation_h + 1 - g.h_in - g.pad_top);
    const int pad_right = std::max(
        0, (g.w_out - 1) * g.stride_w + (g.kw - 1) * g.dilation_w + 1 - g.w_in - g.pad_left);
    const memory::desc src_any(src_dims, Type::f32, Tag::any);
    const memory::desc dst_any(dst_dims, Type::f32, Tag::any);
    const memory::desc w_any(w_dims, Type::f32, Tag::any);
    const memory::desc b_md({g.c_out}, Type::f32, Tag::a);
    const memory::dims strides{g.stride_h, g.stride_w};
    const memory::dims dilates{g.dilation_h - 1, g.dilation_w - 1};
    const memory::dims pad_l{g.pad_top, g.pad_left}, pad_r{pad_bottom, pad_right};
    const bool has_bias = s.bias >= 0;
    const auto desc =
        has_bias ? dnnl::convolution_forward::desc(
                       dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct,
                       src_any, w_any, b_md, dst_any, strides, dilates, pad_l, pad_r)
                 : dnnl::convolution_forward::desc(dnnl::prop_kind::forward_inference,
                                                   dnnl::algorithm::convolution_direct, src_any,
                                                   w_any, dst_any, strides, dilates, pad_l, pad_r);
    dnnl::primitive_attr attr;
    if (s.activation != Activation::kNone) {
      dnnl::post_ops ops;
      ops.append_eltwise(1.0f,
                         s.activation == Activation::kSilu ? dnnl::algorithm::eltwise_swish
                                                           : dnnl::algorithm::eltwise_logistic,
                         1.0f, 0.0f);
      attr.set_post_ops(ops);
    }
    const dnnl::convolution_forward::primitive_desc pd(desc, attr, engine_);

    ConvPrimitive c;
    c.conv = dnnl::convolution_forward(pd);
    const memory::desc user_src_md(src_dims, Type::f32, Tag::nchw);
    const memory::desc user_dst_md(dst_dims, Type::f32, Tag::nchw);
    c.user_src = memory(user_src_md, engine_, DNNL_MEMORY_NONE);
    c.user_dst = memory(user_dst_md, engine_, DNNL_MEMORY_NONE);
    c.reorder_src = pd.src_desc() != user_src_md;
    c.reorder_dst = pd.dst_desc() != user_dst_md;
    c.src = c.reorder_src ? memory(pd.src_desc(), engine_) : c.user_src;
    c.dst = c.reorder_dst ? memory(pd.dst_desc(), engine_) : c.user_dst;
    if (c.reorder_src) c.to_src = dnnl::reorder(c.user_src, c.src);
    if (c.reorder_dst) c.from_dst = dnnl::reorder(c.dst, c.user_dst);
    // Weights: the plan's c_out x c_in x kh x kw, reordered once into the primitive's layout.
    memory user_w({w_dims, Type::f32, Tag::oihw}, engine_,
                  const_cast<float*>(plan.buffers[s.weight].data.data()));
    c.weights = memory(pd.weights_desc(), engine_);
    dnnl::reorder(user_w, c.weights).execute(stream_, user_w, c.weights);
    if (has_bias) {
      c.bias = memory(b_md, engine_);
      const std::vector<float>& b = plan.buffers[s.bias].data;
      std::copy(b.begin(), b.end(), static_cast<float*>(c.bias.get_data_handle()));
    }
    stream_.wait();
    return c;
  }

  std::shared_ptr<const NetPlan> plan_;
  dnnl::engine engine_;
  dnnl::stream stream_;
  std::vector<std::unique_ptr<ConvPrimitive>> convs_;  // per plan step; null: not a convolution
  int threads_ = 0;                                    // the OpenMP threads convs_ were made for
  size_t first_conv_ = 0;                              // the plan's first convolution step
};

}  // namespace

bool OneDnnBuilt() { return true; }

std::unique_ptr<ConvKernels> MakeOneDnnConvKernels(std::shared_ptr<const NetPlan> plan) {
  return std::make_unique<OneDnnConvKernels>(std::move(plan));
}

#else

bool OneDnnBuilt() { return false; }

std::unique_ptr<ConvKernels> MakeOneDnnConvKernels(std::shared_ptr<const NetPlan>) {
  throw std::runtime_error("this build has no oneDNN (install libdnnl-dev and reconfigure)");
}

#endif

}  // namespace pcr::gpu
