#include "graph/pipeline.h"

#include <oneapi/tbb/flow_graph.h>
#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/task.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <opencv2/core/utility.hpp>
#include <optional>
#include <string_view>
#include <thread>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "graph/heap.h"
#include "graph/loop_lane.h"
#include "graph/mask_board.h"
#include "nodes/feature_nodes.h"
#include "nodes/filter_node.h"
#include "nodes/slam_nodes.h"
#include "nodes/source_node.h"
#include "slam/common/error.h"
#include "slam/common/log.h"
#include "slam/system/map_archive.h"

namespace pcr::graph {
namespace {

namespace tf = oneapi::tbb::flow;
using nodes::FeaturesPtr;
using nodes::FilteredPtr;
using nodes::FrameResultPtr;
using nodes::FrameTicket;
using nodes::ImagesPtr;
using nodes::QualityLevel;
using nodes::SegmentationOutcome;
using nodes::SegmentationPtr;
using nodes::StereoPtr;
using nodes::TrackedPtr;

using Token = int;
using StereoAndMask = std::tuple<StereoPtr, SegmentationPtr>;
using TrackingInput = std::tuple<FilteredPtr, Token>;
// A loop job for the loop node, with the ticket of the frame whose keyframe made it.
struct LoopWork {
  FrameTicket ticket;
  nodes::LoopJobPtr job;
};
template <typename In, typename... Out>
using StageNode = tf::multifunction_node<In, std::tuple<Out...>>;

// The error's stage when an exception escaped a node body (the bodies catch their own).
constexpr const char* kGraphStage = "graph";
// How often the clock looks whether the graph was cancelled, at the longest.
constexpr std::chrono::milliseconds kCancelPoll(50);

// cv::setNumThreads for the scope of a run.
class CvThreadsScope {
 public:
  explicit CvThreadsScope(int threads) : previous_(cv::getNumThreads()) {
    cv::setNumThreads(threads);
  }
  ~CvThreadsScope() { cv::setNumThreads(previous_); }
  CvThreadsScope(const CvThreadsScope&) = delete;
  CvThreadsScope& operator=(const CvThreadsScope&) = delete;

 private:
  int previous_;
};

template <typename Msg>
const FrameTicket& TicketOf(const std::shared_ptr<const Msg>& m) {
  return m->ticket;
}
template <typename A, typename B>
const FrameTicket& TicketOf(const std::tuple<A, B>& t) {
  return TicketOf(std::get<0>(t));
}

double NsToMs(int64_t ns) { return static_cast<double>(ns) * 1e-6; }

// ThreadSanitizer builds (scripts/tsan.sh). oneTBB's scheduler is not instrumented, so TSAN does
// not see the happens-before edges that TBB's task hand-off provides; these helpers declare them
// (no-ops in other builds):
//  - set-up: what the calling thread wrote before the clock thread starts happens before every
//    node body (TsanSetupDone, TsanAfterSetup);
//  - inputs: a body copies its input out of TBB's slot (written by the producer's thread) with
//    the reads ignored (TsanReceive); a message is a shared_ptr, and the copy's reference-count
//    increment then orders the producer's writes to the message before the body's reads;
//  - serial nodes: their calls come one after the other, on any thread (TsanBody);
//  - tear-down: every body has returned when wait_for_all does (TsanBody, TsanAfterBodies);
//  - the token: mapping of frame k releases the map before it returns the token, and tracking
//    of frame k+1 acquires it.
// Concurrent bodies stay unordered, so races between them are still reported.
#if defined(__SANITIZE_THREAD__)
#define PCR_UNDER_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define PCR_UNDER_TSAN 1
#endif
#endif
#ifdef PCR_UNDER_TSAN
extern "C" {
void __tsan_acquire(void* addr);
void __tsan_release(void* addr);
void AnnotateIgnoreReadsBegin(const char* file, int line);
void AnnotateIgnoreReadsEnd(const char* file, int line);
}
char tsan_setup_sync, tsan_bodies_done;
inline void TsanAcquire(const void* addr) { __tsan_acquire(const_cast<void*>(addr)); }
inline void TsanRelease(const void* addr) { __tsan_release(const_cast<void*>(addr)); }
template <typename T>
T TsanReceive(const T& input) {
  AnnotateIgnoreReadsBegin(__FILE__, __LINE__);
  T copy = input;
  AnnotateIgnoreReadsEnd(__FILE__, __LINE__);
  return copy;
}
inline void TsanSetupDone() { TsanRelease(&tsan_setup_sync); }
inline void TsanAfterSetup() { TsanAcquire(&tsan_setup_sync); }
inline void TsanAfterBodies() { TsanAcquire(&tsan_bodies_done); }
#else
char tsan_bodies_done;
inline void TsanAcquire(const void*) {}
inline void TsanRelease(const void*) {}
template <typename T>
const T& TsanReceive(const T& input) {
  return input;
}
inline void TsanSetupDone() {}
inline void TsanAfterSetup() {}
inline void TsanAfterBodies() {}
#endif

// One call of a node body, its first statement: acquires the set-up (and, for a serial node,
// the node's previous call) at the start; releases the node and "bodies done" at the end, which
// the caller of wait_for_all acquires before it destroys the graph. A body whose argument to it
// reads a member calls TsanAfterSetup() first.
class TsanBody {
 public:
  explicit TsanBody(const void* serial_node = nullptr) : serial_node_(serial_node) {
    TsanAfterSetup();
    if (serial_node_) TsanAcquire(serial_node_);
  }
  ~TsanBody() {
    if (serial_node_) TsanRelease(serial_node_);
    TsanRelease(&tsan_bodies_done);
  }
  TsanBody(const TsanBody&) = delete;
  TsanBody& operator=(const TsanBody&) = delete;

 private:
  const void* serial_node_;
};

// The flow graph's DeviceWait (slam/dynamic/segmenter.h): the calling stage's task is
// suspended while the device works and its thread runs other stages meanwhile, so a GPU pass
// does not hold one of the `--threads` slots; done() resumes the task, on whichever thread picks
// it up. Must be called from a task of the run's arena. A launch that throws (before it has
// arranged for done(), as DeviceWait requires) resumes the task at once and the exception
// surfaces from here.
void SuspendWhileDeviceWorks(const std::function<void(const DeviceDone&)>& launch) {
  std::exception_ptr error;
#ifdef PCR_UNDER_TSAN
  // TSAN cannot follow the stack switches of TBB's suspension (Debian's libtbb is built without
  // sanitizer support; oneTBB itself uses threads instead when it is, and so do we): TSAN
  // builds wait blocked, which keeps the device -> caller hand-off under TSAN's eye.
  std::mutex mutex;
  std::condition_variable ended;
  bool finished = false;
  auto done = [&] {
    std::lock_guard<std::mutex> lock(mutex);
    finished = true;
    ended.notify_one();  // under the lock: the waiter may return (destroying `ended`) after it
  };
  try {
    launch(done);
  } catch (...) {
    error = std::current_exception();
    done();
  }
  std::unique_lock<std::mutex> lock(mutex);
  ended.wait(lock, [&] { return finished; });
#else
  char sync = 0;  // the device's and the launcher's writes -> the resumed half (TSAN)
  oneapi::tbb::task::suspend([&launch, &sync, &error](oneapi::tbb::task::suspend_point tag) {
    try {
      launch([tag, &sync] {
        TsanRelease(&sync);
        oneapi::tbb::task::resume(tag);
      });
    } catch (...) {
      error = std::current_exception();
      TsanRelease(&sync);
      oneapi::tbb::task::resume(tag);
    }
  });
  TsanAcquire(&sync);
#endif
  if (error) std::rethrow_exception(error);
}

// A stage call in progress (GraphRun::Guarded) on the thread that runs it, so that a device wait
// inside it can split its profile at the wait: the thread that resumes the call may be another
// one, and the launching thread runs other stages meanwhile.
// A call waiting for a device gives its thread back to the call current there before it, and
// takes up whichever thread resumes it, keeping what that thread had current for its end.
struct GuardedCall {
  explicit GuardedCall(int64_t start_ns, GuardedCall* enclosing)
      : pieces(start_ns), outer(enclosing) {}
  CallPieces pieces;
  // What the thread now running this call had current before it: the call it runs inside
  // (sequential loop work), or after a device wait what the resuming thread was running.
  GuardedCall* outer;
};
thread_local GuardedCall* current_call = nullptr;

// Ends a Guarded call: the thread it ends on gets back the call that was current there before.
struct EndGuardedCall {
  GuardedCall& call;
  ~EndGuardedCall() { current_call = call.outer; }
};

// Installs device waits for one run (the segmenters' and the scorer's), and removes them after.
class DeviceWaitScope {
 public:
  DeviceWaitScope(const nodes::SegmenterSet& segmenters, const DeviceWait& inference_wait,
                  nodes::FrameScorer* scorer, const DeviceWait& flow_wait)
      : scorer_(scorer) {
    for (Segmenter* s : {segmenters.accurate, segmenters.fast, segmenters.light}) {
      if (!s || std::find(installed_.begin(), installed_.end(), s) != installed_.end()) continue;
      s->SetDeviceWait(inference_wait);
      installed_.push_back(s);
    }
    if (scorer_) scorer_->SetDeviceWait(flow_wait);
  }
  ~DeviceWaitScope() {
    for (Segmenter* s : installed_) s->SetDeviceWait({});
    if (scorer_) scorer_->SetDeviceWait({});
  }
  DeviceWaitScope(const DeviceWaitScope&) = delete;
  DeviceWaitScope& operator=(const DeviceWaitScope&) = delete;

 private:
  std::vector<Segmenter*> installed_;
  nodes::FrameScorer* scorer_;
};

// One run of the graph: shared state of the node bodies and the clock.
class GraphRun {
 public:
  GraphRun(const nodes::FrameSource& source, SlamSystem* slam, const PipelineOptions& options,
           int max_in_flight, const nodes::SegmenterSet& segmenters, nodes::FrameScorer* scorer,
           std::vector<const OrbExtractor*> extra_extractors)
      : source_(source),
        slam_(slam),
        options_(options),
        max_in_flight_(max_in_flight),
        realtime_(options.policy == Policy::kRealtime),
        mono_(slam->mode() == SlamMode::kMonocular),
        source_node_(source, SourceOptionsFor(options)),
        controller_(options.controller),
        preprocess_(source, slam->mode() == SlamMode::kMonocular),
        orb_left_(*slam, nodes::Side::kLeft, extra_extractors),
        orb_right_(*slam, nodes::Side::kRight, extra_extractors),
        stereo_(*slam),
        segment_(segmenters),
        filter_(scorer, options.carry),
        tracking_(slam),
        mapping_(slam),
        clocks_(std::make_unique<FrameClock[]>(source.size())),
        fixed_settings_(FixedSettings(options, slam->options())) {
    level_ = options.adaptive ? options.controller.initial : QualityLevel::kHigh;
    period_ms_ = source.NominalPeriodMs() * (realtime_ ? options.rate : 1.0);
  }

  // Builds and runs the graph; call inside the task arena that should run it.
  PipelineResult Run();

  // A device wait of this run: SuspendWhileDeviceWorks, each pass profiled as a `stage` event
  // on `lane` of the frame whose call is in progress (*ticket, written by that stage's serial
  // body before its call), from the launch to the device's done() (the resumption may come
  // later, when a thread is free). The segmenters' passes: kStageDevice on kDeviceLane; the
  // filter's LK passes: kStageDeviceFlow on kFlowDeviceLane.
  DeviceWait MakeDeviceWait(const char* stage, int lane, const FrameTicket* ticket) {
    return [this, stage, lane, ticket](const std::function<void(const DeviceDone&)>& launch) {
      const FrameTicket frame = *ticket;       // before the task may move to another thread
      GuardedCall* const call = current_call;  // the stage call that waits (null: none)
      const int64_t start = NowNs();
      if (call) {
        call->pieces.Pause(start);
        current_call = call->outer;  // the thread runs other calls while this one waits
      }
      int64_t end = 0;  // written before done(), read after the resumption
      {
        // Whether the launch threw or not, on the thread that took the call up again.
        struct Resumed {
          GuardedCall* call;
          const GraphRun* run;
          ~Resumed() {
            if (!call) return;
            call->pieces.Resume(run->NowNs());
            call->outer = current_call;
            current_call = call;
          }
        } resumed{call, this};
        SuspendWhileDeviceWorks([this, &launch, &end](const DeviceDone& done) {
          launch([this, &end, done] {
            end = NowNs();
            done();
          });
        });  // (a launch that threw never called done(): its exception skips the record)
      }
      profiler_.RecordDevice(stage, frame.seq, frame.frame_index, start, end, lane);
    };
  }
  DeviceWait MakeInferenceWait() {
    return MakeDeviceWait(kStageDevice, Profiler::kDeviceLane, &inference_ticket_);
  }
  DeviceWait MakeFlowWait() {
    return MakeDeviceWait(kStageDeviceFlow, Profiler::kFlowDeviceLane, &filter_ticket_);
  }

 private:
  struct FrameClock {
    std::atomic<int64_t> stereo_end_ns{-1};
    std::atomic<int64_t> mask_ready_ns{-1};
    std::atomic<int64_t> slam_ns{0};        // summed stage calls of the SLAM path
    std::atomic<int64_t> inference_ns{0};   // the frame's segmentation call
    std::atomic<int64_t> preprocess_ns{0};  // its preprocess call (also in slam_ns)
    std::atomic<int64_t> pose_ns{-1};       // tracking done: the frame's pose exists
  };
  struct Admission {
    int64_t release_ns = 0, admit_ns = 0;
  };
  struct FrameError {
    int64_t seq = -1;
    int64_t frame_index = -1;
    std::string stage, what;
  };

  static nodes::SourceOptions SourceOptionsFor(const PipelineOptions& o) {
    nodes::SourceOptions s;
    s.paced = o.policy == Policy::kRealtime;
    s.rate = o.rate;
    s.waiting_capacity =
        o.policy == Policy::kRealtime ? static_cast<size_t>(o.waiting_capacity) : 0;
    return s;
  }
  static nodes::QualitySettings FixedSettings(const PipelineOptions& o, const SlamOptions& slam) {
    nodes::QualitySettings s = o.levels.medium;
    s.orb_features = slam.orb.num_features;
    s.segmenter = nodes::SegmenterSlot::kFast;
    s.inference_every = o.inference_every;
    s.optical_flow = true;
    s.min_keyframe_interval_s = 0;
    s.ba_max_iterations = slam.mapping.bundle_adjustment.max_iterations;
    return s;
  }

  int64_t NowNs() const {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() -
                                                                start_)
        .count();
  }

  // Runs f (returning the stage's output) with the hook, profiling (unless !profile) and error
  // capture; returns nullopt when it threw.
  template <typename F>
  auto Guarded(const char* stage, const FrameTicket& ticket, F&& f, bool profile = true)
      -> std::optional<decltype(f())> {
    const int64_t start = NowNs();
    GuardedCall call(start, current_call);
    current_call = &call;
    const EndGuardedCall end_call{call};
    try {
      if (options_.stage_hook) options_.stage_hook(stage, ticket.frame_index);
      auto out = f();
      const int64_t end = NowNs();
      if (profile)
        profiler_.Record(stage, ticket.seq, ticket.frame_index, start, end, &call.pieces);
      const std::string_view name(stage);
      if (name != kStageLoop && name != kStageGlobalBa) {  // off the frame's path
        FrameClock& clock = clocks_[ticket.seq];
        (name == kStageSegment ? clock.inference_ns : clock.slam_ns).fetch_add(end - start);
        if (name == kStagePreprocess) clock.preprocess_ns.fetch_add(end - start);
      }
      return out;
    } catch (const std::exception& e) {
      RecordError(stage, ticket, e.what());
    } catch (...) {
      RecordError(stage, ticket, "unknown exception");
    }
    return std::nullopt;
  }

  void RecordError(const char* stage, const FrameTicket& ticket, const std::string& what) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!error_ || ticket.seq < error_->seq)
        error_ = FrameError{ticket.seq, ticket.frame_index, stage, what};
    }
    // Debug only: the run's error (PipelineResult::error) says it, once, to whoever reports it.
    Logger().debug("pipeline: frame {} stage {}: {}", ticket.frame_index, stage, what);
    Wake();
  }

  void Wake() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++wake_epoch_;
    }
    wake_.notify_all();
  }

  // Segments one frame and hands the result to the board (nothing on error: it is recorded).
  // One call at a time (the segment node is serial; realtime runs one inference at a time).
  void RunInference(const ImagesPtr& images) {
    inference_ticket_ = images->ticket;
    if (auto fresh = Guarded(kStageSegment, images->ticket, [&] { return segment_(images); })) {
      last_inference_ms_.store((*fresh)->segment_ms);
      board_->OnSegmentation(*fresh);
    }
  }
  // Outcomes of the loop lane, handed to the map's owner (the mapping node) at its next call.
  void PostLoopOutcome(nodes::LoopOutcomePtr outcome) {
    std::lock_guard<std::mutex> lock(loop_mutex_);
    loop_arrived_.push_back(std::move(outcome));
  }
  std::vector<nodes::LoopOutcomePtr> TakeLoopOutcomes() {
    std::lock_guard<std::mutex> lock(loop_mutex_);
    return std::exchange(loop_arrived_, {});
  }
  // The loop lane's work on a job (verification and correction, then the global BA), each step
  // profiled; `post` receives the outcomes. Inline (sequential) or on the loop node.
  // Whatever `post` throws (the sequential policy applies the outcome to the map there) is
  // recorded as the loop stage's error, as the stages' own exceptions are.
  void RunLoopJob(const LoopWork& work, const std::function<void(nodes::LoopOutcomePtr)>& post) {
    nodes::LoopJobPtr resolved;
    const auto corrected =
        Guarded(kStageLoop, work.ticket, [&] { return loop_node_.Close(work.job, &resolved); });
    if (!corrected) return;
    const auto posted = [&](const nodes::LoopOutcomePtr& o) {
      return Guarded(
          kStageLoop, work.ticket,
          [&] {
            post(o);
            return true;
          },
          /*profile=*/false);
    };
    if (!posted(*corrected)) return;
    if (!nodes::LoopNode::FollowsWithGlobalBundleAdjustment(*resolved, **corrected)) return;
    if (auto ba = Guarded(kStageGlobalBa, work.ticket, [&] {
          return nodes::LoopNode::GlobalBundleAdjustment(*resolved, **corrected, &loop_abort_);
        }))
      posted(*ba);
  }
  void ClockLoop();
  void Complete(const FrameResultPtr& result);
  void EmitMask(const SegmentationPtr& msg);
  PipelineResult Collect();

  const nodes::FrameSource& source_;
  SlamSystem* slam_;
  const PipelineOptions& options_;
  const int max_in_flight_;
  const bool realtime_;
  const bool mono_;
  std::chrono::steady_clock::time_point start_;

  // Clock state (mutex_).
  std::mutex mutex_;
  std::condition_variable wake_;
  uint64_t wake_epoch_ = 0;
  nodes::SourceNode source_node_;
  std::vector<Admission> admissions_;  // by seq
  std::vector<int64_t> dropped_indices_, dropped_release_ns_;
  int64_t admitted_ = 0, completed_ = 0;
  size_t max_observed_in_flight_ = 0;
  std::optional<FrameError> error_;
  QualityLevel level_;
  nodes::QualityController controller_;
  std::vector<QualityChange> changes_;
  std::vector<FrameRecord> frames_;
  double period_ms_ = 0;

  // Stages (each called as its node's concurrency allows).
  nodes::PreprocessNode preprocess_;
  nodes::OrbNode orb_left_, orb_right_;
  nodes::StereoNode stereo_;
  nodes::SegmentNode segment_;
  // Realtime: the frame waiting for the network (newest wins) and whether a call is running.
  std::mutex inference_mutex_;
  ImagesPtr pending_inference_;
  bool inference_running_ = false;
  std::atomic<double> last_inference_ms_{0};
  FrameTicket inference_ticket_;  // of the RunInference call in progress (for the device wait)
  FrameTicket filter_ticket_;     // of the filter call in progress (for the flow's device wait)
  nodes::FilterNode filter_;
  nodes::TrackingNode tracking_;
  // The frame index of every frame built in this run (tracking's; read by Collect), by frame id:
  // a keyframe whose frame is not here came with a loaded map.
  std::unordered_map<int64_t, int64_t> frame_index_of_frame_;
  nodes::MappingNode mapping_;
  // Loop lane: outcomes not yet applied (loop_mutex_), and the flag that aborts a running global
  // BA when a newer job is sent.
  std::mutex loop_mutex_;
  std::vector<nodes::LoopOutcomePtr> loop_arrived_;
  std::atomic<bool> loop_abort_{false};
  std::unique_ptr<LoopLane> loop_lane_;  // pipelined and realtime runs
  nodes::LoopNode loop_node_;  // the lane's copy of the map: the lane (or inline mapping) only
  std::unique_ptr<FrameClock[]> clocks_;  // by seq (< source size)
  const nodes::QualitySettings fixed_settings_;
  Profiler profiler_;

  // Graph (built in Run()).
  std::unique_ptr<oneapi::tbb::task_group_context> context_;
  std::unique_ptr<tf::graph> graph_;
  std::unique_ptr<tf::limiter_node<FrameTicket>> limiter_;
  std::unique_ptr<tf::join_node<StereoAndMask, tf::key_matching<int64_t>>> mask_join_;
  std::unique_ptr<MaskBoard> board_;
};

void GraphRun::EmitMask(const SegmentationPtr& msg) {
  clocks_[msg->ticket.seq].mask_ready_ns.store(NowNs());
  tf::input_port<1>(*mask_join_).try_put(msg);
}

PipelineResult GraphRun::Run() {
  context_ = std::make_unique<oneapi::tbb::task_group_context>();
  graph_ = std::make_unique<tf::graph>(*context_);
  tf::graph& g = *graph_;
  const double deadline_ms = realtime_ ? options_.mask_deadline_ms : -1.0;
  board_ = std::make_unique<MaskBoard>(
      deadline_ms, [this](const SegmentationPtr& m) { EmitMask(m); }, [this] { Wake(); },
      options_.wait_for_first_mask);

  auto key_of = [](const auto& msg) { return msg->ticket.seq; };
  limiter_ = std::make_unique<tf::limiter_node<FrameTicket>>(g, max_in_flight_);

  StageNode<FrameTicket, ImagesPtr> preprocess(
      g, tf::unlimited, [this](const FrameTicket& input, auto& ports) {
        const TsanBody tsan_body;
        const auto& t = TsanReceive(input);
        if (auto out = Guarded(kStagePreprocess, t, [&] { return preprocess_(t); }))
          std::get<0>(ports).try_put(*out);
      });
  // Monocular runs: the right branch and the stereo stage only pass empty messages on, and are
  // not profiled (no 0 ms calls in the stage tables and the trace).
  auto orb_body = [this](const nodes::OrbNode& node, const char* stage, bool profile) {
    return [this, &node, stage, profile](const ImagesPtr& input, auto& ports) {
      const TsanBody tsan_body;
      const auto& images = TsanReceive(input);
      if (auto out = Guarded(
              stage, images->ticket, [&] { return node(images); }, profile))
        std::get<0>(ports).try_put(*out);
    };
  };
  StageNode<ImagesPtr, FeaturesPtr> orb_left(g, tf::unlimited,
                                             orb_body(orb_left_, kStageOrbLeft, true));
  StageNode<ImagesPtr, FeaturesPtr> orb_right(g, tf::unlimited,
                                              orb_body(orb_right_, kStageOrbRight, !mono_));
  tf::join_node<std::tuple<FeaturesPtr, FeaturesPtr>, tf::key_matching<int64_t>> feature_join(
      g, key_of, key_of);
  StageNode<std::tuple<FeaturesPtr, FeaturesPtr>, StereoPtr> stereo(
      g, tf::unlimited, [this](const std::tuple<FeaturesPtr, FeaturesPtr>& input, auto& ports) {
        const TsanBody tsan_body;
        const auto& in = TsanReceive(input);
        const FrameTicket& t = TicketOf(in);
        auto out = Guarded(
            kStageStereo, t, [&] { return stereo_(std::get<0>(in), std::get<1>(in)); }, !mono_);
        if (!out) return;
        const int64_t now = NowNs();
        clocks_[t.seq].stereo_end_ns.store(now);
        std::get<0>(ports).try_put(*out);
        board_->OnFeaturesReady(t, now);
      });

  // The segmentation branch answers for every frame: its result or a "not run" value. Serial
  // (every frame is segmented, in frame order) except in realtime, where the network takes the
  // newest waiting frame when it becomes free and frames it skipped answer "busy" at once.
  tf::function_node<ImagesPtr, tf::continue_msg> segment(
      g, realtime_ ? tf::unlimited : tf::serial, [this](const ImagesPtr& input) {
        TsanAfterSetup();  // before the next line reads a member
        const TsanBody tsan_body(realtime_ ? nullptr : &segment_);
        const auto& images = TsanReceive(input);
        if (!segment_.WillRun(images->ticket)) {
          board_->OnSegmentation(segment_(images));  // "not run", immediately
        } else if (!realtime_) {
          RunInference(images);
        } else {
          ImagesPtr skipped;
          bool runner = false;
          {
            std::lock_guard<std::mutex> lock(inference_mutex_);
            skipped = std::exchange(pending_inference_, images);
            runner = !inference_running_;
            inference_running_ = true;
          }
          if (skipped) {
            board_->OnSegmentation(
                nodes::SegmentNode::NotRun(skipped->ticket, SegmentationOutcome::kBusy));
          }
          while (runner) {
            ImagesPtr next;
            {
              std::lock_guard<std::mutex> lock(inference_mutex_);
              next = std::exchange(pending_inference_, nullptr);
              inference_running_ = next != nullptr;
            }
            if (!next) break;
            RunInference(next);
          }
        }
        return tf::continue_msg();
      });

  mask_join_ =
      std::make_unique<tf::join_node<StereoAndMask, tf::key_matching<int64_t>>>(g, key_of, key_of);
  auto seq_of = [](const auto& msg) { return static_cast<size_t>(TicketOf(msg).seq); };
  tf::sequencer_node<StereoAndMask> filter_order(g, seq_of);
  StageNode<StereoAndMask, FilteredPtr> filter(
      g, tf::serial, [this](const StereoAndMask& input, auto& ports) {
        TsanAfterSetup();  // before the next line reads a member
        const TsanBody tsan_body(&filter_);
        const auto& in = TsanReceive(input);
        filter_ticket_ = TicketOf(in);
        if (auto out = Guarded(kStageFilter, TicketOf(in),
                               [&] { return filter_(std::get<0>(in), std::get<1>(in)); }))
          std::get<0>(ports).try_put(*out);
      });
  tf::sequencer_node<FilteredPtr> tracking_order(g, seq_of);
  tf::queue_node<Token> tokens(g);
  tf::join_node<TrackingInput, tf::reserving> token_join(g);
  StageNode<TrackingInput, TrackedPtr> tracking(
      g, tf::serial, [this](const TrackingInput& input, auto& ports) {
        TsanAfterSetup();  // before the next line reads a member
        const TsanBody tsan_body(&tracking_);
        const auto& in = TsanReceive(input);
        TsanAcquire(slam_);  // the token: frame k-1's map edits
        const FilteredPtr& filtered = std::get<0>(in);
        if (auto out = Guarded(kStageTracking, filtered->ticket, [&] {
              if (options_.tracking_delay_ms > 0)
                std::this_thread::sleep_for(
                    std::chrono::microseconds(std::llround(options_.tracking_delay_ms * 1e3)));
              return tracking_(filtered);
            })) {
          clocks_[filtered->ticket.seq].pose_ns.store(NowNs());
          frame_index_of_frame_.emplace((*out)->frame->id(), filtered->ticket.frame_index);
          std::get<0>(ports).try_put(*out);
        }
      });
  // Mapping (keyframes only; other frames pass through unprofiled) hands the token back once the
  // map holds frame k's edits. As the map's owner it also applies what the loop lane sent since
  // its last call and looks for loops on the new keyframe: a job goes to the loop node (its own
  // serial lane, off the frames' path) or, in the sequential policy, runs inline before the token
  // goes back (so that sequential runs stay the deterministic reference).
  const bool inline_loop = options_.policy == Policy::kSequential;
  if (!inline_loop) loop_lane_ = std::make_unique<LoopLane>(options_.loop_lane_nice);
  StageNode<TrackedPtr, FrameResultPtr, Token, LoopWork> mapping(
      g, tf::serial, [this, inline_loop](const TrackedPtr& input, auto& ports) {
        TsanAfterSetup();  // before the next line reads a member
        const TsanBody tsan_body(&mapping_);
        const auto& tracked = TsanReceive(input);
        const std::vector<nodes::LoopOutcomePtr> arrived = TakeLoopOutcomes();
        const bool keyframe = nodes::MappingNode::NeedsMapping(*tracked);
        if (auto out = Guarded(
                kStageMapping, tracked->ticket, [&] { return mapping_.Run(tracked, arrived); },
                keyframe || !arrived.empty())) {
          if (out->loop_job) {
            const LoopWork work{tracked->ticket, out->loop_job};
            if (inline_loop) {
              RunLoopJob(work, [&](nodes::LoopOutcomePtr o) {
                mapping_.ApplyLoopOutcome(*o, tracked->ticket.frame_index);
              });
            } else {
              loop_abort_.store(true);  // a running global BA gives way to the newer loop
              std::get<2>(ports).try_put(work);
            }
          }
          if (keyframe && options_.trim_heap_after_keyframe) TrimHeap();
          TsanRelease(slam_);  // the map edits of this frame, before the token goes back
          std::get<1>(ports).try_put(Token{0});
          std::get<0>(ports).try_put(out->result);
        }
      });
  // The loop node hands each job to the loop lane (a low-priority thread outside the arena) and
  // keeps the graph open until the lane is done with it.
  using LoopNode = tf::async_node<LoopWork, tf::continue_msg>;
  LoopNode loop(g, tf::unlimited, [this](const LoopWork& input, LoopNode::gateway_type& gateway) {
    TsanAfterSetup();  // before the next line reads a member
    const auto& work = TsanReceive(input);
    gateway.reserve_wait();
    loop_lane_->Push(
        [this, work] {
          loop_abort_.store(false);
          RunLoopJob(work, [this](nodes::LoopOutcomePtr o) { PostLoopOutcome(std::move(o)); });
        },
        [&gateway] { gateway.release_wait(); });
  });
  tf::function_node<FrameResultPtr, tf::continue_msg> sink(
      g, tf::serial, [this](const FrameResultPtr& input) {
        TsanAfterSetup();  // before the next line reads a member
        const TsanBody tsan_body(&frames_);
        const auto& result = TsanReceive(input);
        try {
          Complete(result);
        } catch (const std::exception& e) {
          RecordError("sink", result->ticket, e.what());
        } catch (...) {
          RecordError("sink", result->ticket, "unknown exception");
        }
        return tf::continue_msg();
      });

  tf::make_edge(*limiter_, preprocess);
  tf::make_edge(tf::output_port<0>(preprocess), orb_left);
  tf::make_edge(tf::output_port<0>(preprocess), orb_right);
  // Sequential and pipelined segment frames in frame order (a segmenter may keep state from one
  // call to the next, e.g. the truth segmenter's seeded detector misses), whatever order the
  // preprocess calls finish in; realtime takes the newest frame instead.
  tf::sequencer_node<ImagesPtr> segment_order(g, seq_of);
  if (realtime_) {
    tf::make_edge(tf::output_port<0>(preprocess), segment);
  } else {
    tf::make_edge(tf::output_port<0>(preprocess), segment_order);
    tf::make_edge(segment_order, segment);
  }
  tf::make_edge(tf::output_port<0>(orb_left), tf::input_port<0>(feature_join));
  tf::make_edge(tf::output_port<0>(orb_right), tf::input_port<1>(feature_join));
  tf::make_edge(feature_join, stereo);
  tf::make_edge(tf::output_port<0>(stereo), tf::input_port<0>(*mask_join_));
  tf::make_edge(*mask_join_, filter_order);
  tf::make_edge(filter_order, filter);
  tf::make_edge(tf::output_port<0>(filter), tracking_order);
  tf::make_edge(tracking_order, tf::input_port<0>(token_join));
  tf::make_edge(tokens, tf::input_port<1>(token_join));
  tf::make_edge(token_join, tracking);
  tf::make_edge(tf::output_port<0>(tracking), mapping);
  tf::make_edge(tf::output_port<0>(mapping), sink);
  tf::make_edge(tf::output_port<1>(mapping), tokens);
  tf::make_edge(tf::output_port<2>(mapping), loop);
  tokens.try_put(Token{0});

  g.reserve_wait();  // released by the clock when it is done
  // Time 0 of the run (release times, profiles), set when the graph is built and the loop lane
  // started, so that the first frames are not overdue when the clock first looks.
  start_ = std::chrono::steady_clock::now();
  TsanSetupDone();
  std::thread clock([this] { ClockLoop(); });
  // Stage bodies catch everything; an exception that still escapes one cancels the graph, which
  // the clock notices (it stops and releases the graph), and wait_for_all rethrows it: it is
  // reported like any stage error.
  std::string escaped;
  try {
    g.wait_for_all();
  } catch (const std::exception& e) {
    escaped = e.what();
  } catch (...) {
    escaped = "unknown exception";
  }
  if (!escaped.empty()) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!error_ || error_->stage == kGraphStage)
        error_ =
            FrameError{-1, -1, kGraphStage,
                       "exception in the flow graph" + (escaped.empty() ? "" : ": " + escaped)};
      ++wake_epoch_;
    }
    wake_.notify_all();
  }
  clock.join();
  TsanAfterBodies();
  return Collect();
}

void GraphRun::ClockLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    const int64_t now = NowNs();
    if (context_->is_group_execution_cancelled()) {
      // An exception escaped a node body (they catch their own): no frame will complete.
      if (!error_) error_ = FrameError{-1, -1, kGraphStage, "exception in the flow graph"};
      break;
    }
    // A stop request: the first frame not admitted is where the run ends (after the frames
    // before it), as at a failed frame; nothing when every frame was admitted or dropped.
    if (!error_ && options_.stop != nullptr && options_.stop->load()) {
      const size_t next = static_cast<size_t>(admitted_) + dropped_indices_.size();
      if (next < source_.size()) {
        error_ = FrameError{admitted_, source_.frame_indices[next], kStopStage,
                            "stopped on request before this frame"};
        Logger().warn("pipeline: stop requested; frames from {} on are not run",
                      source_.frame_indices[next]);
      }
    }
    if (error_ && completed_ >= error_->seq) {
      // Every frame before the failing one is done: stop the rest.
      graph_->cancel();
      break;
    }
    // Frames due are released one at a time, each admitted while a slot is free, so the waiting
    // room drops a frame only when the slots are taken. After an error nothing is released.
    do {
      if (error_) break;
      for (const nodes::WaitingFrame& d : source_node_.ReleaseDue(now, 1)) {
        dropped_indices_.push_back(source_.frame_indices[d.entry]);
        dropped_release_ns_.push_back(d.release_ns);
      }
      while (!error_ && source_node_.HasWaiting()) {
        const nodes::QualitySettings& settings =
            options_.adaptive ? options_.levels.At(level_) : fixed_settings_;
        const FrameTicket ticket = source_node_.PeekTicket(level_, settings);
        if (!limiter_->try_put(ticket)) break;  // no free token
        const nodes::WaitingFrame w = source_node_.Admit(ticket);
        admissions_.push_back({w.release_ns, NowNs()});
        ++admitted_;
        max_observed_in_flight_ =
            std::max(max_observed_in_flight_, static_cast<size_t>(admitted_ - completed_));
      }
    } while (source_node_.NextReleaseNs() && *source_node_.NextReleaseNs() <= now);
    board_->ExpireDue(NowNs());
    if (!error_ && source_node_.AllReleased() && !source_node_.HasWaiting() &&
        completed_ == admitted_)
      break;

    int64_t wake_at_ns = -1;  // next release or mask deadline; -1: only a notification
    if (const auto release = source_node_.NextReleaseNs(); release && !error_)
      wake_at_ns = *release;
    if (const auto deadline = board_->NextDeadlineNs();
        deadline && (wake_at_ns < 0 || *deadline < wake_at_ns))
      wake_at_ns = *deadline;
    const uint64_t epoch = wake_epoch_;
    auto woken = [&] { return wake_epoch_ != epoch; };
    // Nothing wakes the clock when the graph is cancelled: it looks again at least this often.
    const auto latest = std::chrono::steady_clock::now() + kCancelPoll;
    const auto until =
        wake_at_ns >= 0 ? std::min(latest, start_ + std::chrono::nanoseconds(wake_at_ns)) : latest;
    wake_.wait_until(lock, until, woken);
  }
  lock.unlock();
  graph_->release_wait();
}

void GraphRun::Complete(const FrameResultPtr& result) {
  const int64_t done = NowNs();
  const FrameTicket& t = result->ticket;
  FrameRecord r;
  r.seq = t.seq;
  r.frame_index = t.frame_index;
  r.t_ns = t.t_ns;
  r.quality = t.quality;
  r.inference_scheduled = t.run_inference;
  r.mask = result->mask;
  r.mask_source_seq = result->mask_source_seq;
  r.propagate_ms = result->propagate_ms;
  r.num_excluded = result->num_excluded;
  r.output = result->output;
  r.filter_report = result->filter_report;
  r.done_ns = done;
  r.preprocess_ms = NsToMs(clocks_[t.seq].preprocess_ns.load());
  r.segment_ms = NsToMs(clocks_[t.seq].inference_ns.load());

  // Eq. 8 for this frame: T_slam (its SLAM-path stage calls, wall time, mapping included),
  // T_inference (its own network call, or the latest one when it had none or it is still
  // running, amortised over the level's cadence), T_sync (features waiting for the mask).
  const FrameClock& clock = clocks_[t.seq];
  const double slam_ms = NsToMs(clock.slam_ns.load());
  double inference_ms = 0;
  if (const int64_t own = clock.inference_ns.load(); own > 0) {
    inference_ms = NsToMs(own);
  } else if (segment_.has_segmenter()) {
    inference_ms = last_inference_ms_.load() / std::max(1, t.settings.inference_every);
  }
  const int64_t stereo_end = clock.stereo_end_ns.load();
  const int64_t mask_ready = clock.mask_ready_ns.load();
  const double sync_ms =
      stereo_end >= 0 && mask_ready > stereo_end ? NsToMs(mask_ready - stereo_end) : 0.0;
  r.busy_ms = std::max(slam_ms, inference_ms) + sync_ms;

  size_t completed = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const Admission& a = admissions_[static_cast<size_t>(t.seq)];
    r.release_ns = a.release_ns;
    r.admit_ns = a.admit_ns;
    const int64_t start = realtime_ ? a.release_ns : a.admit_ns;
    const int64_t pose = clock.pose_ns.load();
    r.pose_ns = pose >= 0 ? pose : done;
    r.latency_ms = NsToMs(r.pose_ns - start);
    r.retire_ms = NsToMs(done - start);
    r.segmentation = result->segmentation;
    if (options_.adaptive) {
      const QualityLevel before = controller_.level();
      const QualityLevel after = controller_.Update(period_ms_, r.busy_ms);
      if (after != before) {
        changes_.push_back(
            {t.seq, before, after, controller_.available_ms(), controller_.threshold_ms()});
        Logger().info(
            "pipeline: quality {} -> {} after frame {} (available {:.1f} ms, threshold "
            "{:.1f} ms)",
            nodes::ToString(before), nodes::ToString(after), t.frame_index,
            controller_.available_ms(), controller_.threshold_ms());
      }
      level_ = after;
    }
    ++completed_;
    completed = static_cast<size_t>(completed_);
  }
  // Progress before the token goes back, so an observer never sees more frames in flight than
  // the bound.
  if (options_.on_frame) options_.on_frame(completed, source_.size(), r);
  if (!options_.keep_filter_reports) r.filter_report.reset();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    frames_.push_back(std::move(r));
  }
  if (options_.trim_heap_every > 0 &&
      completed % static_cast<size_t>(options_.trim_heap_every) == 0)
    TrimHeap();
  limiter_->decrementer().try_put(tf::continue_msg());
  Wake();
}

PipelineResult GraphRun::Collect() {
  PipelineResult out;
  out.frames = std::move(frames_);
  out.dropped_frame_indices = std::move(dropped_indices_);
  out.dropped_release_ns = std::move(dropped_release_ns_);
  // Loop outcomes that came after the last frame's mapping (the graph has finished: this thread
  // is the map's owner now), so that no correction is lost at the end of a run.
  FrameTicket after_last;
  after_last.seq = std::max<int64_t>(admitted_ - 1, 0);
  for (const nodes::LoopOutcomePtr& o : TakeLoopOutcomes()) {
    const auto applied = Guarded(
        kStageLoop, after_last,
        [&] {
          mapping_.ApplyLoopOutcome(*o, -1);
          return true;
        },
        /*profile=*/false);
    if (!applied) break;
  }
  // Then the final global BA (loop.final_global_ba), profiled as a global BA after the last
  // frame; not after an error (the run stops there).
  if (!error_ && mapping_.NeedsFinishLoopClosing())
    Guarded(kStageGlobalBa, after_last, [&] { return mapping_.FinishLoopClosing(); });
  out.loop_events = slam_->loop_events();
  out.loop_stats = slam_->loop_closer().stats();
  out.loop_database_keyframes = slam_->loop_closer().database().size();
  out.relocalisation_stats = slam_->relocalisation_stats();
  const std::map<KeyframeId, int> parts = slam_->map().Parts();  // the map's parts at the end
  std::vector<int> tracked_parts;
  out.tracked = slam_->RefinedTrajectory(&parts, &tracked_parts);
  for (size_t i = 0; i < out.tracked.size(); ++i)
    out.map.frame_parts[out.tracked[i].frame_index] = tracked_parts[i];
  if (error_) {
    // The poses of the completed frames only: frames after the failing one may have been tracked
    // already when the graph was cancelled, and their records are not in the result.
    std::unordered_set<int64_t> completed;
    for (const FrameRecord& f : out.frames) completed.insert(f.frame_index);
    std::erase_if(out.tracked,
                  [&](const StampedPose& p) { return !completed.count(p.frame_index); });
    std::erase_if(out.map.frame_parts, [&](const auto& f) { return !completed.count(f.first); });
  }
  out.keyframes = slam_->map().num_keyframes();
  out.map_points = slam_->map().num_points();
  if (options_.keep_final_map)
    out.final_map = std::make_shared<const MapArchive>(slam_->ArchiveMap());
  const Map& map = slam_->map();
  for (const auto& [id, mp] : map.points()) {
    MapCloudPoint c;
    c.p_in_world = mp.p_in_world;
    c.observations = static_cast<int>(mp.observations.size());
    if (const Keyframe* kf = map.keyframe(mp.reference_keyframe)) {
      const auto it = mp.observations.find(mp.reference_keyframe);
      if (it != mp.observations.end()) c.grey = kf->frame->grey(it->second);
    }
    out.map.points.push_back(c);
  }
  std::vector<const Keyframe*> keyframes;
  for (const auto& [id, kf] : map.keyframes()) keyframes.push_back(&kf);
  std::sort(keyframes.begin(), keyframes.end(),
            [](const Keyframe* a, const Keyframe* b) { return a->index < b->index; });
  std::map<KeyframeId, size_t> position_of;
  for (const Keyframe* kf : keyframes) {
    out.map.keyframe_parts.push_back(parts.at(kf->id));
    position_of.emplace(kf->id, out.map.keyframes.size());
    const auto made_here = frame_index_of_frame_.find(kf->frame->id());
    out.map.keyframes.push_back({kf->frame->t_ns(),
                                 made_here == frame_index_of_frame_.end() ? -1 : made_here->second,
                                 kf->cam_from_world.inverse()});
  }
  for (const LoopEvent& e : out.loop_events) {
    if (e.outcome.kind != LoopOutcomeKind::kCorrected || !e.outcome.match) continue;
    const auto a = position_of.find(map.ResolveKeyframe(e.outcome.match->query));
    const auto b = position_of.find(map.ResolveKeyframe(e.outcome.match->matched));
    if (a != position_of.end() && b != position_of.end())
      out.map.loops.emplace_back(a->second, b->second);
  }
  out.events = profiler_.Events();
  if (error_) {
    out.error_frame_index = error_->frame_index;
    out.error_stage = error_->stage;
    out.error = (error_->frame_index >= 0 ? "frame " + std::to_string(error_->frame_index) + ", "
                                          : std::string()) +
                "stage " + error_->stage + ": " + error_->what;
  }

  PipelineStats& s = out.stats;
  s.policy = ToString(options_.policy);
  s.threads = options_.threads;
  s.max_in_flight = max_in_flight_;
  s.rate = options_.rate;
  s.adaptive = options_.adaptive;
  s.period_ms = period_ms_;
  s.frames_total = source_.size();
  s.frames_admitted = static_cast<size_t>(admitted_);
  s.frames_completed = out.frames.size();
  s.frames_dropped = out.dropped_frame_indices.size();
  s.late_results = board_->late_results();
  s.max_in_flight_observed = max_observed_in_flight_;
  s.profile_threads = profiler_.num_threads();
  TimingSeries latency, retire, busy, propagate;
  int64_t last_done = 0;
  for (const FrameRecord& f : out.frames) {
    latency.Add(f.latency_ms);
    retire.Add(f.retire_ms);
    busy.Add(f.busy_ms);
    last_done = std::max(last_done, f.done_ns);
    switch (f.mask) {
      case nodes::MaskStatus::kFresh:
        ++s.masks_fresh;
        break;
      case nodes::MaskStatus::kPropagated:
        ++s.masks_propagated;
        propagate.Add(f.propagate_ms);
        break;
      case nodes::MaskStatus::kStale:
        ++s.masks_stale;
        break;
      case nodes::MaskStatus::kSkipped:
        ++s.masks_skipped;
        break;
    }
    // Late and busy by the frame's own outcome (not by the board's emissions or the network's
    // skipped requests: a request replaced after its frame went on late is that frame's one
    // outcome, late; frames that never completed are in no count).
    s.masks_late += f.segmentation == SegmentationOutcome::kLate;
    s.inferences_busy += f.segmentation == SegmentationOutcome::kBusy;
    if (options_.adaptive) ++s.quality_frames[static_cast<size_t>(f.quality)];
  }
  s.latency = latency.Summarize();
  s.propagate = propagate.Summarize();
  s.retire = retire.Summarize();
  s.busy = busy.Summarize();
  // The run ends with the last thing it waited for; a profiler's user times the run, so calls
  // that outlast the last frame count (they are in the trace), and fps is over the same time.
  int64_t run_end = last_done;
  for (const StageEvent& e : out.events) run_end = std::max(run_end, e.end_ns);
  for (const int64_t release : out.dropped_release_ns) run_end = std::max(run_end, release);
  s.last_retire_s = static_cast<double>(last_done) * 1e-9;
  s.wall_s = static_cast<double>(run_end) * 1e-9;
  s.fps = s.wall_s > 0 ? static_cast<double>(out.frames.size()) / s.wall_s : 0.0;
  s.quality_changes = changes_;
  s.resident_bytes = ResidentBytes();
  s.peak_resident_bytes = PeakResidentBytes();
  s.allocator = AllocatorName();

  // Stage timings and queue waits from the profile. Input ready = end of the upstream stages of
  // the same frame (admission for preprocess; the mask emission for the filter).
  std::map<std::pair<std::string, int64_t>, int64_t> end_of;
  for (const StageEvent& e : out.events) end_of[{e.stage, e.seq}] = e.end_ns;
  auto ready = [&](const StageEvent& e) -> std::optional<int64_t> {
    const std::string stage = e.stage;
    auto end = [&](const char* up) -> std::optional<int64_t> {
      const auto it = end_of.find({up, e.seq});
      if (it == end_of.end()) return std::nullopt;
      return it->second;
    };
    auto latest = [](std::optional<int64_t> a, std::optional<int64_t> b) -> std::optional<int64_t> {
      if (!a || !b) return std::nullopt;
      return std::max(*a, *b);
    };
    if (stage == kStagePreprocess) {
      if (e.seq < 0 || static_cast<size_t>(e.seq) >= admissions_.size()) return std::nullopt;
      return admissions_[static_cast<size_t>(e.seq)].admit_ns;
    }
    if (stage == kStageOrbLeft || stage == kStageOrbRight || stage == kStageSegment)
      return end(kStagePreprocess);
    if (stage == kStageStereo) return latest(end(kStageOrbLeft), end(kStageOrbRight));
    if (stage == kStageFilter) {
      const int64_t mask = clocks_[e.seq].mask_ready_ns.load();
      // Monocular: the (unprofiled) stereo stage passes the left features straight on.
      return latest(mono_ ? end(kStageOrbLeft) : end(kStageStereo),
                    mask >= 0 ? std::optional<int64_t>(mask) : std::nullopt);
    }
    if (stage == kStageTracking) return end(kStageFilter);
    if (stage == kStageMapping) return end(kStageTracking);
    return std::nullopt;
  };
  std::map<std::string, TimingSeries> times, waits;
  std::map<std::string, std::vector<StageWait>> intervals;
  for (StageEvent& e : out.events) {
    times[e.stage].Add(NsToMs(e.end_ns - e.start_ns));
    if (const auto r = ready(e)) {
      const int64_t ready_ns = std::min(*r, e.start_ns);
      e.ready_ns = ready_ns;
      waits[e.stage].Add(NsToMs(e.start_ns - ready_ns));
      intervals[e.stage].push_back({ready_ns, e.start_ns});
    }
  }
  for (const auto& [stage, series] : times) {
    StageStats& st = s.stages[stage];
    st.time = series.Summarize();
    st.wait = waits[stage].Summarize();
    st.max_queue_depth = MaxQueueDepth(intervals[stage]);
  }
  return out;
}

}  // namespace

PipelineResult RunPipeline(const nodes::FrameSource& source, const SlamOptions& slam_options,
                           const PipelineOptions& options, const nodes::SegmenterSet& segmenters,
                           nodes::FrameScorer* scorer) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("PipelineOptions: " + why);
  const bool stereo = options.mode == SlamMode::kStereo;
  if (!source.IsValid(&why, stereo)) throw ConfigError("FrameSource " + source.name + ": " + why);

  SlamOptions capped = slam_options;
  capped.mapping.bundle_adjustment.num_threads =
      std::min(capped.mapping.bundle_adjustment.num_threads, options.threads);
  SlamSystem slam(source.rig, capped, options.mode, options.vocabulary);
  if (options.initial_map) slam.RestoreMap(*options.initial_map);
  const size_t database_loaded = slam.loop_closer().database().size();
  if (capped.localize_only && slam.map().empty())
    throw ConfigError("localisation only needs a map to localise in (a loaded one)");

  // Extractors for the adaptive levels' keypoint counts (same pyramid as the SLAM system's).
  std::vector<std::unique_ptr<OrbExtractor>> extractors;
  std::vector<const OrbExtractor*> extra;
  if (options.adaptive) {
    for (QualityLevel l : {QualityLevel::kLow, QualityLevel::kMedium, QualityLevel::kHigh}) {
      const int n = options.levels.At(l).orb_features;
      const bool known = n == capped.orb.num_features ||
                         std::any_of(extra.begin(), extra.end(), [n](const OrbExtractor* e) {
                           return e->options().num_features == n;
                         });
      if (known) continue;
      OrbOptions o = capped.orb;
      o.num_features = n;
      extractors.push_back(std::make_unique<OrbExtractor>(o));
      extra.push_back(extractors.back().get());
    }
  }
  std::unique_ptr<nodes::MaskScorer> default_scorer;
  if (!scorer && !segmenters.empty()) {
    default_scorer = std::make_unique<nodes::MaskScorer>(options.scorer);
    scorer = default_scorer.get();
  }

  const int max_in_flight = options.policy == Policy::kSequential ? 1 : options.max_in_flight;
  const int arena_threads = options.policy == Policy::kSequential ? 1 : options.threads;
  oneapi::tbb::global_control parallelism(oneapi::tbb::global_control::max_allowed_parallelism,
                                          static_cast<size_t>(options.threads));
  // OpenCV's parallel loops (DNN forward, LK flow, resize) run on TBB in an arena of their own.
  // In the sequential policy they are the only parallelism; in the others the graph already
  // keeps `threads` cores busy with different stages, and a second arena competing for the same
  // TBB workers left one worker idle for seconds at a time (pipelined fps 8.5 instead of 14.7 on
  // 2 cores, bench_pipeline): stages there run OpenCV on their own thread.
  CvThreadsScope cv_threads(options.policy == Policy::kSequential ? options.threads : 1);
  oneapi::tbb::task_arena arena(arena_threads);
  Logger().debug("pipeline: {} on {} ({} frames), {} threads, {} in flight",
                 ToString(options.policy), source.name, source.size(), options.threads,
                 max_in_flight);
  // With a light network the low level can afford inference on every frame.
  PipelineOptions run_options = options;
  if (segmenters.light) run_options.levels.low.inference_every = 1;
  GraphRun run(source, &slam, run_options, max_in_flight, segmenters, scorer, extra);
  // Pipelined and realtime: work on a device (inference, the filter's LK flow) overlaps the CPU
  // stages on every thread. The sequential reference keeps its stages one after another
  // (T = T_slam + T_inference).
  std::optional<DeviceWaitScope> device_wait;
  if (options.policy != Policy::kSequential && options.device_overlap)
    device_wait.emplace(segmenters, run.MakeInferenceWait(), scorer, run.MakeFlowWait());
  PipelineResult result;
  arena.execute([&] { result = run.Run(); });
  result.loop_database_keyframes_loaded = database_loaded;
  return result;
}

}  // namespace pcr::graph
