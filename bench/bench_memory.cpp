// Memory-flatness benchmark: a long synthetic replay through the pipelined flow graph, sampling
// the resident set size (VmRSS) every --sample-every frames next to the map size, and the verdict
// "max RSS after warm-up exceeds the RSS at warm-up end by X%" (target: at most 10%). A run that
// failed a frame or completed fewer frames than --frames prints its figures with INVALID verdicts
// and exits 3 (the verdicts themselves do not change the exit status).
//
//   bench_memory [--frames 2000] [--warmup 200] [--sample-every 100] [--world-frames 400]
//                [--scale 1] [--segmenter truth|none] [--filter on|off] [--threads 2]
//                [--max-in-flight 4] [--seed 1] [--movers 6] [--parked 8] [--speed 8]
//                [--max-keyframes N] [--trim] [--heap-policy on|off] [--mmap-threshold BYTES]
//                [--trim-every N]
//
// Frames are rendered on the fly in memory by the synthetic world (src/sim) inside the source's
// loaders; nothing is written to disk. The world is built on the loop route for --world-frames
// frames (a rounded rectangle of streets about world_frames * 0.7 m long at 8 m/s), and replay
// frame i shows world frame i mod P, where P is the number of frames of one lap: the camera drives
// the same streets again and again, so a map that recognised the revisited places would stop
// growing. (At the wrap the camera jumps by less than half a frame's travel along the lane and
// the moving objects jump to their lap-start positions.)
// --segmenter truth: the rendered instance image as a perfect detector's masks (every car,
// cyclist and pedestrian, moving or parked), so the mask branch, the mask carry and the filter's
// mask stage run as with YOLO, at no inference cost.
// Columns: RSS (VmRSS from /proc/self/statm), mean and anon (per-frame means since the previous
// sample of RSS and of its anonymous part: without the file-backed pages of the program and its
// libraries, which code paths page in as they first run), peak, heap (bytes malloc has handed out
// and not got back: glibc's mallinfo2 uordblks + hblkhd, jemalloc's stats.allocated), the map's
// keyframes and points, and the last frame's tracking. To tell the map's growth from the rest, the
// heap is fitted against the keyframe count, and --speed 0 (the ego car stands still, so the map
// needs no new keyframes while the movers keep moving) is the control run of everything but the
// map. --per-frame writes one CSV row per frame as it retires (resident, anonymous and heap MiB,
// whether it was a keyframe, its local BA and mapping ms, keyframes, map points, tracked points):
// where a peak comes from.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "bench_args.h"
#include "bench_cli.h"
#include "graph/heap.h"
#include "graph/pipeline.h"
#include "nodes/filter_node.h"
#include "sim/synthetic_world.h"
#include "slam/dynamic/mask_utils.h"
#include "slam/dynamic/segmenter.h"

namespace {

struct Args {
  int frames = 2000, warmup = 200, sample_every = 100, world_frames = 400;
  double scale = 1.0;
  std::string segmenter = "truth";
  bool filter = true;
  int threads = 2, max_in_flight = 4;
  uint64_t seed = 1;
  int movers = 6, parked = 8;
  double speed_mps = 8.0;   // 0: a parked ego car (control run: no new keyframes are needed)
  int max_keyframes = 0;    // mapping.max_keyframes: 0 unbounded, else a bounded map
  bool trim = false;        // return freed heap to the system after each sample (TrimHeap)
  bool heap_policy = true;  // graph/heap.h: capped arenas, periodic trim, --mmap-threshold
  size_t mmap_threshold = pcr::graph::HeapPolicy{}.mmap_threshold_bytes;  // with the policy
  int trim_every = pcr::graph::PipelineOptions{}.trim_heap_every;         // with the policy
  std::string per_frame;  // CSV of every frame's memory and map work (empty: none)
  bool trim_after_keyframe = pcr::graph::PipelineOptions{}.trim_heap_after_keyframe;
};

// Reads the command line into *a. Returns -1 when the benchmark is to run, else its exit status
// (0 after --help). A bad value throws std::invalid_argument naming the option.
int ParseArgs(int argc, char** argv, Args* a) {
  using pcr::bench::AddInt;
  using pcr::bench::AddNumber;
  using pcr::bench::AddOnOff;
  CLI::App app{
      "Memory flatness: a long synthetic loop replay through the pipelined graph, rendered in "
      "memory, sampling the resident set and the map; verdicts compare the samples after the "
      "warm-up with the warm-up's end (target: at most 10% more). Exits 3 when a frame failed or "
      "fewer than --frames completed (see the top of bench/bench_memory.cpp)"};
  AddInt(app, "--frames", &a->frames, 1, 10000000, "N", "frames replayed");
  AddInt(app, "--warmup", &a->warmup, 0, 10000000, "FRAMES",
         "frames before the reference sample (fewer than --frames)");
  AddInt(app, "--sample-every", &a->sample_every, 1, 10000000, "FRAMES",
         "frames between samples (a sample's window)");
  AddInt(app, "--world-frames", &a->world_frames, 50, 1000000, "FRAMES",
         "frames of the synthetic loop route built (about world-frames x 0.7 m of streets); "
         "the replay drives its lap again and again");
  AddNumber(
      app, "--scale", &a->scale, "in (0, 4]", [](double v) { return v > 0 && v <= 4; }, "X",
      "image scale (1: KITTI's 1241x376)");
  app.add_option("--segmenter", a->segmenter,
                 "truth (the rendered instances as a perfect detector's masks) or none")
      ->check(CLI::IsMember({"truth", "none"}))
      ->capture_default_str();
  AddOnOff(app, "--filter", &a->filter, "the multi-stage dynamic filter");
  AddInt(app, "--threads", &a->threads, 1, 256, "N", "pipeline threads");
  AddInt(app, "--max-in-flight", &a->max_in_flight, 1, 1024, "N",
         "frames admitted and not finished");
  app.add_option_function<std::string>(
         "--seed",
         [a](const std::string& text) { a->seed = pcr::bench::ParseUnsigned(text, "--seed"); },
         "the synthetic world's seed")
      ->type_name("N")
      ->default_str(std::to_string(a->seed));
  AddInt(app, "--movers", &a->movers, 0, 500, "N", "moving objects");
  AddInt(app, "--parked", &a->parked, 0, 2000, "N", "parked cars");
  AddNumber(
      app, "--speed", &a->speed_mps, "in [0, 40]", [](double v) { return v >= 0 && v <= 40; },
      "M/S",
      "ego speed, m/s (0: the ego car stands still, the traffic moves: the control run without "
      "map growth)");
  AddInt(app, "--max-keyframes", &a->max_keyframes, 0, 10000000, "N",
         "mapping.max_keyframes: a bounded map forgets its oldest keyframes (0: unbounded)");
  app.add_flag("--trim", a->trim, "return freed heap to the system after each sample");
  AddOnOff(app, "--heap-policy", &a->heap_policy,
           "as pcr_orb: capped malloc arenas, a periodic trim, --mmap-threshold (graph/heap.h)");
  AddInt(app, "--trim-every", &a->trim_every, 0, 10000000, "FRAMES",
         "with --heap-policy on: hand free heap pages back every N frames (0: never)");
  app.add_option_function<std::string>(
         "--mmap-threshold",
         [a](const std::string& text) {
           a->mmap_threshold = pcr::bench::ParseUnsigned(text, "--mmap-threshold");
         },
         "with --heap-policy on, glibc's malloc only: blocks of this many bytes and more are "
         "mapped on their own (0: malloc's default)")
      ->type_name("BYTES")
      ->default_str(std::to_string(a->mmap_threshold));
  AddOnOff(app, "--trim-after-keyframe", &a->trim_after_keyframe,
           "also trim the heap after each keyframe's local mapping");
  app.add_option("--per-frame", a->per_frame,
                 "write one CSV row per retired frame (resident, anonymous and heap MiB, "
                 "keyframe, local BA and mapping ms, map size)")
      ->type_name("FILE.csv");
  const int status = pcr::bench::Parse(app, argc, argv);
  if (status >= 0) return status;
  // The verdicts compare the samples after the warm-up with the one at its end.
  if (a->warmup >= a->frames)
    throw std::invalid_argument("--warmup " + std::to_string(a->warmup) +
                                " leaves no frame to measure: it must be less than --frames " +
                                std::to_string(a->frames));
  return -1;
}

// "exceeds BASE by 12.3%" or "is 2.0% below BASE": a verdict's growth `pct` over `base`.
std::string Versus(double pct, const std::string& base) {
  return pct > 0 ? fmt::format("exceeds {} by {:.1f}%", base, pct)
                 : fmt::format("is {:.1f}% below {}", -pct, base);
}

using pcr::graph::ResidentBytes;

double MiB(int64_t bytes) { return static_cast<double>(bytes) / (1024.0 * 1024.0); }

// Frames per lap of the loop: the frame in [n/2, n) whose camera is nearest to frame 0's.
int LapFrames(const pcr::sim::SyntheticWorld& world) {
  const Eigen::Vector3d start = world.WorldFromCam(0).translation();
  int best = world.NumFrames() - 1;
  double best_m = 1e18;
  for (int k = world.NumFrames() / 2; k < world.NumFrames(); ++k) {
    const double d = (world.WorldFromCam(k).translation() - start).norm();
    if (d < best_m) {
      best_m = d;
      best = k;
    }
  }
  return best;
}

// Rendered frames by replay index, kept until a few newer ones exist: load_left renders the
// pair, load_right and the segmenter read it back. Thread-safe.
class RenderCache {
 public:
  struct Entry {
    cv::Mat left, right, instance_left;
  };

  RenderCache(const pcr::sim::SyntheticWorld& world, int lap_frames)
      : world_(world), lap_frames_(lap_frames) {}

  std::shared_ptr<const Entry> Get(int64_t replay_index) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (const auto it = entries_.find(replay_index); it != entries_.end()) return it->second;
    }
    pcr::sim::RenderedFrame frame =
        world_.RenderFrame(static_cast<int>(replay_index % lap_frames_));
    auto entry = std::make_shared<Entry>();
    entry->left = frame.left;
    entry->right = frame.right;
    entry->instance_left = frame.instance_left;
    std::lock_guard<std::mutex> lock(mutex_);
    entries_[replay_index] = entry;
    by_data_[entry->left.data] = entry;
    while (entries_.size() > kCapacity) {
      by_data_.erase(entries_.begin()->second->left.data);
      entries_.erase(entries_.begin());
    }
    return entry;
  }

  // The entry whose left image shares `left`'s pixel buffer (the segmenter receives the image
  // that load_left returned); nullptr when it has been evicted.
  std::shared_ptr<const Entry> FindByLeft(const cv::Mat& left) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = by_data_.find(left.data);
    return it == by_data_.end() ? nullptr : it->second;
  }

  size_t size() {
    std::lock_guard<std::mutex> lock(mutex_);
    return entries_.size();
  }

 private:
  static constexpr size_t kCapacity = 16;  // > max in flight
  const pcr::sim::SyntheticWorld& world_;
  const int lap_frames_;
  std::mutex mutex_;
  std::map<int64_t, std::shared_ptr<const Entry>> entries_;
  std::map<const uchar*, std::shared_ptr<const Entry>> by_data_;
};

// A perfect detector: every dynamic-class instance in the rendered instance image (moving or
// parked) as an instance mask, with the confidence map of the YOLO path.
class RenderedTruthSegmenter final : public pcr::Segmenter {
 public:
  RenderedTruthSegmenter(RenderCache* cache, const pcr::sim::InstanceTable& table)
      : cache_(cache), table_(table) {}

  pcr::Segmentation Segment(const cv::Mat& image) override {
    const auto entry = cache_->FindByLeft(image);
    if (!entry) throw std::runtime_error("truth segmenter: the frame left the render cache");
    const cv::Mat& ids = entry->instance_left;
    std::map<uint16_t, cv::Mat> masks;
    for (int v = 0; v < ids.rows; ++v) {
      const uint16_t* row = ids.ptr<uint16_t>(v);
      for (int u = 0; u < ids.cols; ++u) {
        if (!table_.IsObject(row[u])) continue;
        cv::Mat& m = masks[row[u]];
        if (m.empty()) m = cv::Mat::zeros(ids.size(), CV_8UC1);
        m.at<uint8_t>(v, u) = 255;
      }
    }
    pcr::Segmentation out;
    out.backend = "rendered-truth";
    for (auto& [id, mask] : masks) {
      const std::string cls = table_.ClassNameOf(id);
      if (!classes_.Find(cls)) continue;
      const cv::Rect box = cv::boundingRect(mask);
      if (box.area() == 0) continue;
      pcr::Instance inst;
      inst.class_name = cls;
      inst.class_id = static_cast<int>(pcr::sim::ParseClassName(cls));
      inst.confidence = 0.9f;
      inst.box_px = cv::Rect2f(box);
      inst.mask = mask;
      inst.instance_id = static_cast<int>(out.instances.size());
      out.instances.push_back(std::move(inst));
    }
    out.instance_map = pcr::BuildInstanceMap(out.instances, ids.size());
    out.dynamic_confidence = pcr::DynamicConfidenceMap(out.instances, ids.size(), classes_, 5, 2.0);
    return out;
  }
  std::string Name() const override { return "rendered-truth"; }

 private:
  RenderCache* cache_;
  const pcr::sim::InstanceTable& table_;
  pcr::DynamicClassPolicy classes_;
};

struct Sample {
  size_t frame = 0;
  double t_s = 0;
  int64_t rss = 0, heap = 0;
  int64_t rss_peak = 0;   // largest RSS seen at any frame since the previous sample
  int64_t rss_mean = 0;   // mean RSS over the frames since the previous sample
  int64_t anon_mean = 0;  // the same without file-backed pages (anonymous memory)
  size_t keyframes = 0, map_points = 0;
  int tracked = 0;
  std::string status;
};

}  // namespace

int main(int argc, char** argv) {
  try {
    Args args;
    if (const int status = ParseArgs(argc, argv, &args); status >= 0) return status;
    if (args.heap_policy) {  // as pcr_orb does
      pcr::graph::HeapPolicy policy;
      policy.mmap_threshold_bytes = args.mmap_threshold;
      if (!pcr::graph::ConfigureHeap(policy) && args.mmap_threshold > 0) {
        std::fprintf(stderr, "bench_memory: --mmap-threshold has no effect under %s\n",
                     pcr::graph::AllocatorName().c_str());
      }
    }
    spdlog::set_level(spdlog::level::warn);
    const auto start = std::chrono::steady_clock::now();
    auto seconds = [&] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };

    pcr::sim::SynthOptions synth;
    synth.frames = args.world_frames;
    synth.seed = args.seed;
    synth.num_movers = args.movers;
    synth.num_parked = args.parked;
    synth.speed_mps = args.speed_mps;
    synth.route = pcr::sim::RouteKind::kLoop;
    if (args.scale != 1.0) synth = synth.Scaled(args.scale);
    const pcr::sim::SyntheticWorld world(synth);
    const int lap = LapFrames(world);
    const double lap_jump_m =
        (world.WorldFromCam(lap).translation() - world.WorldFromCam(0).translation()).norm();
    RenderCache cache(world, lap);
    RenderedTruthSegmenter truth(&cache, world.Instances());

    pcr::nodes::FrameSource source;
    source.name = "synthetic loop";
    source.rig = world.Rig();
    for (int i = 0; i < args.frames; ++i) {
      source.frame_indices.push_back(i);
      source.t_ns.push_back(static_cast<int64_t>(std::llround(i * 1e9 / synth.rate_hz)));
    }
    source.load_left = [&cache](int64_t i) { return cache.Get(i)->left; };
    source.load_right = [&cache](int64_t i) { return cache.Get(i)->right; };

    pcr::nodes::SegmenterSet segmenters;
    if (args.segmenter == "truth") segmenters.fast = &truth;
    pcr::SlamOptions slam_options;
    slam_options.mapping.max_keyframes = args.max_keyframes;
    std::unique_ptr<pcr::nodes::DynamicFilterScorer> scorer;
    if (args.filter)
      scorer = std::make_unique<pcr::nodes::DynamicFilterScorer>(source.rig,
                                                                 slam_options.orb.scale_factor);

    std::printf(
        "bench_memory: %d frames of a synthetic loop (%dx%d, world of %d frames, lap %d frames "
        "= %.0f m, wrap jump %.2f m), pipelined, %d threads, %d in flight, segmenter %s, filter "
        "%s; warm-up %d frames; %s\n",
        args.frames, synth.width_px, synth.height_px, args.world_frames, lap,
        lap * synth.speed_mps / synth.rate_hz, lap_jump_m, args.threads, args.max_in_flight,
        args.segmenter.c_str(), args.filter ? "on" : "off", args.warmup,
        pcr::graph::AllocatorName().c_str());
    std::printf("%6s %7s %9s %9s %9s %9s %9s %5s %7s %7s %9s\n", "frame", "time s", "RSS MiB",
                "mean MiB", "anon MiB", "peak MiB", "heap MiB", "kf", "points", "tracked",
                "status");
    std::fflush(stdout);

    std::vector<Sample> samples;
    int64_t window_peak = 0;
    double window_sum = 0, window_anon_sum = 0;
    int window_count = 0;
    auto take = [&](size_t frame, const pcr::FrameOutput* out) {
      Sample s;
      s.frame = frame;
      s.t_s = seconds();
      if (args.trim) pcr::graph::TrimHeap();  // freed pages stay resident otherwise
      s.rss = ResidentBytes();
      s.rss_peak = std::max(window_peak, s.rss);
      s.rss_mean = window_count > 0 ? static_cast<int64_t>(window_sum / window_count) : s.rss;
      s.anon_mean = window_count > 0 ? static_cast<int64_t>(window_anon_sum / window_count) : 0;
      window_peak = 0;
      window_sum = 0;
      window_anon_sum = 0;
      window_count = 0;
      s.heap = pcr::graph::HeapInUseBytes();
      if (out) {
        s.keyframes = out->num_keyframes;
        s.map_points = out->num_map_points;
        s.tracked = out->num_tracked;
        s.status = pcr::ToString(out->status);
      }
      std::printf("%6zu %7.1f %9.1f %9.1f %9.1f %9.1f %9.1f %5zu %7zu %7d %9s\n", s.frame, s.t_s,
                  MiB(s.rss), MiB(s.rss_mean), MiB(s.anon_mean), MiB(s.rss_peak), MiB(s.heap),
                  s.keyframes, s.map_points, s.tracked, s.status.c_str());
      std::fflush(stdout);
      samples.push_back(s);
    };
    take(0, nullptr);

    pcr::graph::PipelineOptions options;
    options.policy = pcr::graph::Policy::kPipelined;
    options.threads = args.threads;
    options.max_in_flight = args.max_in_flight;
    options.trim_heap_every = args.heap_policy ? args.trim_every : 0;
    options.trim_heap_after_keyframe = args.heap_policy && args.trim_after_keyframe;
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> per_frame(nullptr, std::fclose);
    if (!args.per_frame.empty()) {
      per_frame.reset(std::fopen(args.per_frame.c_str(), "w"));
      if (!per_frame) throw std::runtime_error("cannot write " + args.per_frame);
      std::fprintf(per_frame.get(),
                   "frame,rss_mib,anon_mib,heap_mib,keyframe,ba_ms,mapping_ms,keyframes,"
                   "map_points,tracked\n");
    }
    options.on_frame = [&](size_t done, size_t, const pcr::graph::FrameRecord& record) {
      const pcr::FrameOutput& out = record.output;
      int64_t file_now = 0;
      const int64_t rss_now = ResidentBytes(&file_now);
      if (per_frame) {
        std::fprintf(per_frame.get(), "%zu,%.2f,%.2f,%.2f,%d,%.1f,%.1f,%zu,%zu,%d\n", done,
                     MiB(rss_now), MiB(rss_now - file_now), MiB(pcr::graph::HeapInUseBytes()),
                     out.keyframe_inserted ? 1 : 0, out.mapping.ba_ms, out.times_ms.local_mapping,
                     out.num_keyframes, out.num_map_points, out.num_tracked);
      }
      window_peak = std::max(window_peak, rss_now);
      window_sum += static_cast<double>(rss_now);
      window_anon_sum += static_cast<double>(rss_now - file_now);
      ++window_count;
      if (done % static_cast<size_t>(args.sample_every) == 0 ||
          done == static_cast<size_t>(args.warmup))
        take(done, &out);
    };
    const pcr::graph::PipelineResult result =
        pcr::graph::RunPipeline(source, slam_options, options, segmenters, scorer.get());
    if (!result.error.empty()) std::fprintf(stderr, "pipeline error: %s\n", result.error.c_str());
    const int64_t rss_end = ResidentBytes();
    // A run that failed a frame or stopped early measured a shorter (or different) run than the
    // one asked for: its figures are printed, but the verdicts say INVALID and it exits 3.
    const bool complete =
        result.error.empty() && result.stats.frames_completed == static_cast<size_t>(args.frames);
    const std::string invalid =
        complete ? std::string()
                 : fmt::format(" (INVALID: {} of {} frames completed{}{})",
                               result.stats.frames_completed, args.frames,
                               result.error.empty() ? "" : ", error: ", result.error);

    // Verdict: samples after the warm-up against the one at its end.
    const Sample* at_warmup = nullptr;
    for (const Sample& s : samples)
      if (s.frame == static_cast<size_t>(args.warmup)) at_warmup = &s;
    if (!at_warmup) {
      std::printf("no sample at the end of the warm-up (frame %d)%s\n", args.warmup,
                  invalid.c_str());
      return complete ? 1 : 3;
    }
    int64_t max_rss = at_warmup->rss;
    size_t max_frame = at_warmup->frame;
    for (const Sample& s : samples) {
      if (s.frame > at_warmup->frame && s.rss > max_rss) {
        max_rss = s.rss;
        max_frame = s.frame;
      }
    }
    const Sample& last = samples.back();
    const double growth_pct =
        100.0 * static_cast<double>(max_rss - at_warmup->rss) / static_cast<double>(at_warmup->rss);
    std::printf(
        "run: %zu frames completed in %.1f s (%.2f fps), %zu keyframes, %zu map points at the "
        "end; RSS after the run (result held) %.1f MiB\n",
        result.stats.frames_completed, result.stats.wall_s, result.stats.fps, result.keyframes,
        result.map_points, MiB(rss_end));
    if (last.frame > at_warmup->frame) {
      const double frames = static_cast<double>(last.frame - at_warmup->frame);
      const double d_kf = static_cast<double>(last.keyframes) - at_warmup->keyframes;
      const double d_rss = static_cast<double>(last.rss - at_warmup->rss);
      const double d_heap = static_cast<double>(last.heap - at_warmup->heap);
      std::printf(
          "after warm-up (frames %zu..%zu): RSS %+.1f MiB (%+.1f KiB/frame), heap %+.1f MiB, "
          "keyframes %+.0f, map points %+.0f%s\n",
          at_warmup->frame, last.frame, MiB(static_cast<int64_t>(d_rss)), d_rss / 1024.0 / frames,
          MiB(static_cast<int64_t>(d_heap)), d_kf,
          static_cast<double>(last.map_points) - at_warmup->map_points,
          d_kf > 0
              ? fmt::format("; {:.0f} KiB of heap per new keyframe", d_heap / 1024.0 / d_kf).c_str()
              : "");
    }
    // What grows: least-squares fit of the heap against the map's keyframe count after the
    // warm-up, and the per-frame records the result keeps by design (lower bounds: strings and
    // vectors inside them not counted).
    {
      double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
      for (const Sample& s : samples) {
        if (s.frame < at_warmup->frame || s.status.empty()) continue;
        const double x = static_cast<double>(s.keyframes), y = static_cast<double>(s.heap);
        n += 1;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
      }
      const double den = n * sxx - sx * sx;
      // Only when the keyframe count moved (spread of at least ~10 keyframes).
      if (n >= 3 && den > 100.0 * n * n) {
        const double slope = (n * sxy - sx * sy) / den, intercept = (sy - slope * sx) / n;
        double max_residual = 0;
        for (const Sample& s : samples) {
          if (s.frame < at_warmup->frame || s.status.empty()) continue;
          max_residual = std::max(max_residual,
                                  std::abs(static_cast<double>(s.heap) -
                                           (intercept + slope * static_cast<double>(s.keyframes))));
        }
        std::printf(
            "heap ~ %.1f MiB + %.0f KiB x keyframes (fit over %.0f samples after warm-up; largest "
            "residual %.1f MiB)\n",
            MiB(static_cast<int64_t>(intercept)), slope / 1024.0, n,
            MiB(static_cast<int64_t>(max_residual)));
      }
      const double records =
          static_cast<double>(result.frames.size()) * sizeof(pcr::graph::FrameRecord) +
          static_cast<double>(result.events.size()) * sizeof(pcr::graph::StageEvent);
      std::printf(
          "per-run records kept by design: %zu frame records x %zu B + %zu stage events x %zu B "
          "= %.1f MiB\n",
          result.frames.size(), sizeof(pcr::graph::FrameRecord), result.events.size(),
          sizeof(pcr::graph::StageEvent), records / (1024.0 * 1024.0));
    }
    const bool pass = growth_pct <= 10.0;
    std::printf(
        "verdict: max RSS after warm-up %.1f MiB (frame %zu) %s: %s (target: at most 10%% "
        "above)%s\n",
        MiB(max_rss), max_frame,
        Versus(growth_pct, fmt::format("the RSS at warm-up end {:.1f} MiB (frame {})",
                                       MiB(at_warmup->rss), at_warmup->frame))
            .c_str(),
        !complete ? "INVALID"
        : pass    ? "PASS"
                  : "FAIL",
        invalid.c_str());
    // The same with per-frame statistics of each sampling window (a single sample can fall on a
    // moment with fewer frames in flight): the largest window value after the warm-up against
    // the warm-up's last window.
    auto window_verdict = [&](const char* label, int64_t Sample::*field) {
      int64_t after = 0;
      size_t frame = 0;
      for (const Sample& s : samples)
        if (s.frame > at_warmup->frame && s.*field > after) {
          after = s.*field;
          frame = s.frame;
        }
      if (after <= 0) return;
      const int64_t base = (*at_warmup).*field;
      const double pct = 100.0 * static_cast<double>(after - base) /
                         static_cast<double>(std::max<int64_t>(base, 1));
      std::printf(
          "%s: largest after warm-up %.1f MiB (window ending at frame %zu) %s: %s\n", label,
          MiB(after), frame,
          Versus(pct, fmt::format("the last warm-up window's {:.1f} MiB", MiB(base))).c_str(),
          !complete     ? "INVALID"
          : pct <= 10.0 ? "PASS"
                        : "FAIL");
    };
    window_verdict("window peaks (RSS at any frame)", &Sample::rss_peak);
    window_verdict("window means (mean RSS over the frames)", &Sample::rss_mean);
    window_verdict("window means of anonymous RSS (without library pages)", &Sample::anon_mean);
    return complete ? 0 : 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_memory: %s\n", e.what());
    return 1;
  }
}
