#include "graph/pipeline_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>

#include "slam/common/error.h"

namespace pcr::graph {
namespace {

nlohmann::json TimingJson(const TimingSummary& s) {
  return {{"count", s.count},   {"mean_ms", s.mean_ms}, {"p50_ms", s.p50_ms},
          {"p95_ms", s.p95_ms}, {"p99_ms", s.p99_ms},   {"max_ms", s.max_ms}};
}

double Us(int64_t ns) { return static_cast<double>(ns) * 1e-3; }

// Stages in pipeline order (others after, by name).
std::vector<std::string> OrderedStages(const std::vector<std::string>& present) {
  const std::vector<std::string> order = {kStagePreprocess, kStageOrbLeft, kStageOrbRight,
                                          kStageSegment,    kStageStereo,  kStageFilter,
                                          kStageTracking,   kStageMapping, kStageLoop,
                                          kStageGlobalBa,   kStageDevice,  kStageDeviceFlow};
  std::vector<std::string> out;
  for (const std::string& s : order) {
    if (std::find(present.begin(), present.end(), s) != present.end()) out.push_back(s);
  }
  for (const std::string& s : present) {
    if (std::find(out.begin(), out.end(), s) == out.end()) out.push_back(s);
  }
  return out;
}

cv::Scalar StageColour(const std::string& stage) {
  // BGR.
  if (stage == kStagePreprocess) return {160, 160, 160};
  if (stage == kStageOrbLeft) return {200, 120, 30};
  if (stage == kStageOrbRight) return {230, 170, 90};
  if (stage == kStageSegment) return {60, 60, 220};
  if (stage == kStageStereo) return {190, 80, 150};
  if (stage == kStageFilter) return {40, 170, 230};
  if (stage == kStageTracking) return {60, 170, 60};
  if (stage == kStageMapping) return {40, 110, 40};
  if (stage == kStageLoop) return {200, 40, 40};
  if (stage == kStageGlobalBa) return {140, 30, 90};
  if (stage == kStageDevice) return {30, 30, 140};
  if (stage == kStageDeviceFlow) return {20, 100, 140};
  return {120, 120, 120};
}

void Text(cv::Mat& image, const std::string& text, cv::Point at, double scale = 0.45,
          cv::Scalar colour = {30, 30, 30}, int thickness = 1) {
  cv::putText(image, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv::LINE_AA);
}

// A "nice" tick step (1, 2 or 5 times a power of ten) giving about `count` ticks over span.
double TickStep(double span, int count) {
  const double raw = span / std::max(1, count);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (raw <= m * p) return m * p;
  }
  return 10 * p;
}

// Bytes in MiB; -1 stays -1 (not known).
double MiB(int64_t bytes) { return bytes >= 0 ? static_cast<double>(bytes) / 1048576.0 : -1.0; }

// The trace's name of a profile lane (StageEvent::thread).
std::string LaneName(int thread) {
  if (thread == Profiler::kDeviceLane) return "device (GPU)";
  if (thread == Profiler::kFlowDeviceLane) return "device flow (GPU)";
  return fmt::format("worker {}", thread);
}

// Keyframes the place database dropped since the run started (the map culled them): it held the
// loaded map's, added keyframes_seen, and holds loop_database_keyframes at the end.
size_t DatabaseKeyframesCulled(const PipelineResult& result) {
  const size_t held = result.loop_database_keyframes_loaded +
                      static_cast<size_t>(std::max(result.loop_stats.keyframes_seen, 0));
  return held > result.loop_database_keyframes ? held - result.loop_database_keyframes : 0;
}

}  // namespace

nlohmann::json StatsToJson(const PipelineStats& s) {
  nlohmann::json j;
  j["policy"] = s.policy;
  j["threads"] = s.threads;
  j["memory"] = {{"resident_mib", MiB(s.resident_bytes)},
                 {"peak_resident_mib", MiB(s.peak_resident_bytes)},
                 {"allocator", s.allocator}};
  j["max_in_flight"] = s.max_in_flight;
  j["rate"] = s.rate;
  j["adaptive"] = s.adaptive;
  j["period_ms"] = s.period_ms;
  j["frames"] = {{"total", s.frames_total},
                 {"admitted", s.frames_admitted},
                 {"completed", s.frames_completed},
                 {"dropped", s.frames_dropped}};
  j["masks"] = {{"fresh", s.masks_fresh},         {"propagated", s.masks_propagated},
                {"stale", s.masks_stale},         {"skipped", s.masks_skipped},
                {"late", s.masks_late},           {"inference_busy", s.inferences_busy},
                {"late_results", s.late_results}, {"propagate_ms", TimingJson(s.propagate)}};
  j["wall_s"] = s.wall_s;
  j["last_retire_s"] = s.last_retire_s;
  j["fps"] = s.fps;
  j["latency_ms"] = TimingJson(s.latency);
  j["retire_ms"] = TimingJson(s.retire);
  j["frame_busy_ms"] = TimingJson(s.busy);
  j["max_in_flight_observed"] = s.max_in_flight_observed;
  j["threads_seen"] = s.profile_threads;
  for (const auto& [name, st] : s.stages) {
    nlohmann::json stage = TimingJson(st.time);
    stage["wait"] = TimingJson(st.wait);
    stage["max_queue_depth"] = st.max_queue_depth;
    j["stages"][name] = stage;
  }
  // Without adaptive quality every frame has the fixed settings (--model, --inference-every).
  if (!s.adaptive) j["quality"]["frames"]["fixed"] = s.frames_completed;
  for (int l = 0; s.adaptive && l < nodes::kNumQualityLevels; ++l) {
    j["quality"]["frames"][nodes::ToString(static_cast<nodes::QualityLevel>(l))] =
        s.quality_frames[static_cast<size_t>(l)];
  }
  j["quality"]["changes"] = s.quality_changes.size();
  nlohmann::json changes = nlohmann::json::array();
  for (const QualityChange& c : s.quality_changes) {
    changes.push_back({{"seq", c.seq},
                       {"from", nodes::ToString(c.from)},
                       {"to", nodes::ToString(c.to)},
                       {"available_ms", c.available_ms},
                       {"threshold_ms", c.threshold_ms}});
  }
  j["quality"]["log"] = changes;
  return j;
}

std::string FormatPipelineStats(const PipelineStats& s) {
  std::ostringstream o;
  o << fmt::format("pipeline {}: {} threads, {} in flight (max seen {}){}\n", s.policy, s.threads,
                   s.max_in_flight, s.max_in_flight_observed,
                   s.policy == "realtime" ? fmt::format(", rate {:.3g}", s.rate) : std::string());
  // The run's time includes what it waited for after its last frame (wall_s); say so when that
  // shows.
  const std::string tail =
      s.wall_s - s.last_retire_s >= 0.005
          ? fmt::format(" (the last frame retired at {:.2f} s)", s.last_retire_s)
          : std::string();
  o << fmt::format(
      "frames: {} of {} completed, {} dropped; {:.2f} s{}, {:.2f} fps; latency to pose p50 {:.1f} "
      "p95 {:.1f} p99 {:.1f} ms (to retirement, mapping included: p99 {:.1f} ms)\n",
      s.frames_completed, s.frames_total, s.frames_dropped, s.wall_s, tail, s.fps, s.latency.p50_ms,
      s.latency.p95_ms, s.latency.p99_ms, s.retire.p99_ms);
  o << fmt::format("masks: {} fresh, {} propagated, {} stale, {} skipped ({} late, {} busy)",
                   s.masks_fresh, s.masks_propagated, s.masks_stale, s.masks_skipped, s.masks_late,
                   s.inferences_busy);
  if (s.masks_propagated > 0)
    o << fmt::format("; propagation p50 {:.1f} p99 {:.1f} ms", s.propagate.p50_ms,
                     s.propagate.p99_ms);
  o << "\n";
  if (s.resident_bytes >= 0) {
    o << fmt::format("memory: {:.1f} MiB resident at the end, peak {:.1f} MiB ({})\n",
                     MiB(s.resident_bytes), MiB(s.peak_resident_bytes), s.allocator);
  }
  if (s.adaptive) {
    o << fmt::format(
        "quality: high {}, medium {}, low {} frames; {} changes (period {:.1f} ms, busy p50 "
        "{:.1f} ms)\n",
        s.quality_frames[2], s.quality_frames[1], s.quality_frames[0], s.quality_changes.size(),
        s.period_ms, s.busy.p50_ms);
  }
  o << "per node call (dropped frames' and discarded results' calls included):\n";
  o << fmt::format("{:<11} {:>6} {:>8} {:>8} {:>8} {:>8} {:>9} {:>6}\n", "stage", "calls",
                   "mean ms", "p50 ms", "p95 ms", "p99 ms", "wait p95", "queue");
  std::vector<std::string> names;
  for (const auto& [name, st] : s.stages) names.push_back(name);
  for (const std::string& name : OrderedStages(names)) {
    const StageStats& st = s.stages.at(name);
    o << fmt::format("{:<11} {:>6} {:>8.2f} {:>8.2f} {:>8.2f} {:>8.2f} {:>9.2f} {:>6}\n", name,
                     st.time.count, st.time.mean_ms, st.time.p50_ms, st.time.p95_ms, st.time.p99_ms,
                     st.wait.p95_ms, st.max_queue_depth);
  }
  return o.str();
}

nlohmann::json LoopToJson(const PipelineResult& result) {
  const LoopStats& st = result.loop_stats;
  TimingSeries verify, correct, graph, ba;
  nlohmann::json events = nlohmann::json::array();
  for (const LoopEvent& e : result.loop_events) {
    const LoopOutcome& o = e.outcome;
    nlohmann::json j = {{"frame", e.frame_index},
                        {"job", o.job},
                        {"kind", ToString(o.kind)},
                        {"query_keyframe", o.query.value},
                        {"candidates_tried", o.candidates_tried},
                        {"candidates_verified", o.candidates_verified}};
    if (o.match) {
      j["matched_keyframe"] = o.match->matched.value;
      j["bow_matches"] = o.match->bow_matches;
      j["ransac_inliers"] = o.match->ransac_inliers;
      j["sim3_inliers"] = o.match->sim3_inliers;
      j["loop_matches"] = o.match->matches.size();
      j["scale"] = o.match->query_from_matched.scale;
    }
    switch (o.kind) {
      case LoopOutcomeKind::kRejected:
        j["rejection"] = o.rejection;
        j["verify_ms"] = o.verify_ms;
        verify.Add(o.verify_ms);
        break;
      case LoopOutcomeKind::kCorrected:
        j["correction_m"] = o.correction_m;
        j["correction_deg"] = o.correction_deg;
        j["fused_points"] = o.fused_points;
        j["pose_graph_edges"] = o.pose_graph_edges;
        j["pose_graph_part_links"] = o.pose_graph_part_links;
        j["pose_graph_iterations"] = o.pose_graph_iterations;
        j["pose_graph_cost"] = {o.pose_graph_initial_cost, o.pose_graph_final_cost};
        j["verify_ms"] = o.verify_ms;
        j["correct_ms"] = o.correct_ms;
        j["pose_graph_ms"] = o.pose_graph_ms;
        verify.Add(o.verify_ms);
        correct.Add(o.correct_ms);
        graph.Add(o.pose_graph_ms);
        break;
      case LoopOutcomeKind::kGlobalBundleAdjustment:
        j["keyframes"] = o.ba_keyframes;
        j["points"] = o.ba_points;
        j["iterations"] = o.ba_iterations;
        j["aborted"] = o.ba_aborted;
        j["ba_ms"] = o.ba_ms;
        if (!o.ba_aborted) ba.Add(o.ba_ms);
        break;
    }
    events.push_back(j);
  }
  return {{"keyframes_seen", st.keyframes_seen},
          {"database_keyframes", result.loop_database_keyframes},
          {"database_keyframes_loaded", result.loop_database_keyframes_loaded},
          {"database_keyframes_culled", DatabaseKeyframesCulled(result)},
          {"detections", st.detections},
          {"candidates", st.candidates},
          {"consistent", st.consistent},
          {"jobs", st.jobs},
          {"loops_closed", st.corrections},
          {"jobs_rejected", st.rejected},
          {"candidates_rejected", st.candidates_rejected},
          {"candidates_prechecked", st.candidates_prechecked},
          {"candidates_ransac_prechecked", st.candidates_ransac_prechecked},
          {"global_bas", st.global_bas},
          {"global_bas_aborted", st.global_bas_aborted},
          {"jobs_with_map_copy", st.map_copies},
          {"jobs_with_map_edits", st.map_edit_jobs},
          {"map_edits_sent", st.map_edits},
          {"sequence_gated", st.sequence_gated},
          {"detect_ms", TimingJson(SummarizeTimes(st.detect_ms))},
          {"add_ms", TimingJson(SummarizeTimes(st.add_ms))},
          {"verify_ms", TimingJson(verify.Summarize())},
          {"correct_ms", TimingJson(correct.Summarize())},
          {"pose_graph_ms", TimingJson(graph.Summarize())},
          {"global_ba_ms", TimingJson(ba.Summarize())},
          {"events", events}};
}

std::string FormatLoopSummary(const PipelineResult& result) {
  const LoopStats& st = result.loop_stats;
  if (st.keyframes_seen == 0 && result.loop_database_keyframes == 0) return "";
  const TimingSummary d = SummarizeTimes(st.detect_ms);
  // What the database holds against the map's keyframes: those loaded with the map, those added
  // in this run, less those the map culled since (forgotten by the database).
  const size_t loaded = result.loop_database_keyframes_loaded;
  const size_t culled = DatabaseKeyframesCulled(result);
  std::string held = loaded > 0 ? fmt::format("{} loaded with the map, ", loaded) : "";
  held += fmt::format("{} added in this run", st.keyframes_seen);
  if (culled > 0) held += fmt::format(", {} {}culled since", culled, loaded > 0 ? "" : "of them ");
  std::string out = fmt::format(
      "loop closing: {} loops closed, {} global BAs ({} aborted); {} keyframes in the "
      "database ({}), {} queries, {} candidates, {} jobs rejected ({} candidates failed the "
      "geometry); detection {}\n",
      st.corrections, st.global_bas, st.global_bas_aborted, result.loop_database_keyframes, held,
      st.detections, st.candidates, st.rejected, st.candidates_rejected,
      // No detection timed (a localisation-only run): no time, not a measured 0.
      st.detect_ms.empty() ? std::string("not run")
                           : fmt::format("p50 {:.2f} p99 {:.2f} ms", d.p50_ms, d.p99_ms));
  for (const LoopEvent& e : result.loop_events) {
    const LoopOutcome& o = e.outcome;
    if (o.kind == LoopOutcomeKind::kCorrected && o.match)
      out += fmt::format(
          "  loop: keyframe {} -> {} ({} matches, scale {:.4f}): moved {:.3f} {} / {:.2f} deg, "
          "{} points fused, pose graph {} edges in {:.0f} ms\n",
          o.query.value, o.match->matched.value, o.match->matches.size(),
          o.match->query_from_matched.scale, o.correction_m, o.metric ? "m" : "map units",
          o.correction_deg, o.fused_points, o.pose_graph_edges, o.pose_graph_ms);
    else if (o.kind == LoopOutcomeKind::kGlobalBundleAdjustment)
      out += fmt::format("  global BA: {} keyframes, {} points, {} iterations, {:.0f} ms{}\n",
                         o.ba_keyframes, o.ba_points, o.ba_iterations, o.ba_ms,
                         o.ba_aborted ? " (aborted by a newer loop)" : "");
  }
  return out;
}

nlohmann::json RelocalisationToJson(const RelocalisationStats& st) {
  return {{"calls", st.calls},
          {"place_candidates", st.place_candidates},
          {"keyframes_tried", st.keyframes_tried},
          {"matched", st.matched},
          {"passed", st.passed},
          {"rejected", st.rejected},
          {"accepted", st.accepted},
          {"reinitialisations", st.reinitialisations},
          {"frames_lost_before_reinitialisation", st.frames_lost_before_reinitialisation}};
}

std::string FormatRelocalisationSummary(const RelocalisationStats& st) {
  if (st.calls == 0) return "";
  return fmt::format(
      "relocalisation: {} calls, {} accepted; {} place-recognition candidates, {} keyframes "
      "tried, {} with enough matches, {} held by PnP, {} of those rejected by the local map{}\n",
      st.calls, st.accepted, st.place_candidates, st.keyframes_tried, st.matched, st.passed,
      st.rejected,
      st.reinitialisations == 0
          ? std::string()
          : fmt::format("; {} new part(s) of the map started after {} lost frames",
                        st.reinitialisations, st.frames_lost_before_reinitialisation));
}

std::vector<MapPartSummary> SummariseMapParts(const MapSnapshot& map) {
  std::vector<MapPartSummary> parts;
  const auto part = [&parts](int p) -> MapPartSummary& {
    while (static_cast<int>(parts.size()) <= p) {
      parts.emplace_back();
      parts.back().part = static_cast<int>(parts.size()) - 1;
    }
    return parts[static_cast<size_t>(p)];
  };
  for (size_t i = 0; i < map.keyframes.size() && i < map.keyframe_parts.size(); ++i) {
    if (map.keyframe_parts[i] < 0) continue;
    MapPartSummary& p = part(map.keyframe_parts[i]);
    if (p.keyframes++ == 0) p.first_keyframe_frame = map.keyframes[i].frame_index;
  }
  for (const auto& [frame, p] : map.frame_parts) {  // by frame index
    if (p < 0) continue;
    MapPartSummary& s = part(p);
    if (s.tracked_frames++ == 0) s.first_tracked_frame = frame;
  }
  return parts;
}

nlohmann::json MapPartsToJson(const MapSnapshot& map) {
  nlohmann::json parts = nlohmann::json::array();
  for (const MapPartSummary& p : SummariseMapParts(map))
    parts.push_back({{"part", p.part},
                     {"keyframes", p.keyframes},
                     {"first_keyframe_frame", p.first_keyframe_frame},
                     {"tracked_frames", p.tracked_frames},
                     {"first_tracked_frame", p.first_tracked_frame}});
  return parts;
}

std::string FormatMapPartsSummary(const MapSnapshot& map) {
  const std::vector<MapPartSummary> parts = SummariseMapParts(map);
  if (parts.size() <= 1) return "";
  std::string others;
  for (size_t i = 1; i < parts.size(); ++i)
    others += fmt::format("{}part {}: {} keyframes from {}, {} tracked frames from frame {}",
                          i > 1 ? "; " : "", parts[i].part, parts[i].keyframes,
                          parts[i].first_keyframe_frame < 0
                              ? std::string("the loaded map")
                              : fmt::format("frame {}", parts[i].first_keyframe_frame),
                          parts[i].tracked_frames, parts[i].first_tracked_frame);
  return fmt::format(
      "map parts: the map ended in {} parts that share no point, as no loop joined them ({}); "
      "the first part ({} keyframes, {} tracked frames) is in the world's frame, each other one "
      "where a guess put it (the motion extrapolated over a loss, or a loaded map's origin), so "
      "an evaluation of the whole trajectory mixes frames\n",
      parts.size(), others, parts[0].keyframes, parts[0].tracked_frames);
}

void WriteChromeTrace(const std::string& path, const PipelineResult& result) {
  nlohmann::json events = nlohmann::json::array();
  events.push_back(
      {{"name", "process_name"}, {"ph", "M"}, {"pid", 1}, {"args", {{"name", "stages"}}}});
  events.push_back(
      {{"name", "process_name"}, {"ph", "M"}, {"pid", 2}, {"args", {{"name", "frames"}}}});
  std::set<int> threads;
  for (const StageEvent& e : result.events) {
    nlohmann::json args = {
        {"frame", e.frame_index},
        {"seq", e.seq},
        {"wait_ms", e.ready_ns >= 0 ? static_cast<double>(e.start_ns - e.ready_ns) * 1e-6 : 0.0}};
    // A call that waited for a device: a slice per stretch on its thread (the threads ran other
    // stages in the gaps), each saying which part of the call it is and how long the call took.
    const std::vector<StagePiece> pieces = HostStretches(e);
    if (!e.pieces.empty()) args["call_ms"] = static_cast<double>(e.end_ns - e.start_ns) * 1e-6;
    for (size_t i = 0; i < pieces.size(); ++i) {
      const StagePiece& piece = pieces[i];
      threads.insert(piece.thread);
      if (!e.pieces.empty()) args["part"] = fmt::format("{} of {}", i + 1, pieces.size());
      events.push_back({{"name", e.stage},
                        {"cat", "stage"},
                        {"ph", "X"},
                        {"ts", Us(piece.start_ns)},
                        {"dur", Us(piece.end_ns - piece.start_ns)},
                        {"pid", 1},
                        {"tid", piece.thread},
                        {"args", args}});
    }
  }
  for (int t : threads) {
    events.push_back({{"name", "thread_name"},
                      {"ph", "M"},
                      {"pid", 1},
                      {"tid", t},
                      {"args", {{"name", LaneName(t)}}}});
  }
  // Frame slices: realtime from the camera's release (a frame may wait for a slot), else from
  // the admission, to the retirement. Frames do not nest, and a lane of a Chrome trace must hold
  // slices that nest or do not overlap: each frame goes on the first lane free at its start (the
  // lanes are sub-lanes of the frames' process, not slots), so a lane shows frames one after the
  // other and there are as many lanes as frames existed at once (in flight, and in realtime
  // waiting for a slot too). Each frame's slot wait is in its args.
  const bool realtime = result.stats.policy == "realtime";
  std::vector<size_t> order(result.frames.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  auto from_of = [realtime](const FrameRecord& f) { return realtime ? f.release_ns : f.admit_ns; };
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return from_of(result.frames[a]) < from_of(result.frames[b]);
  });
  std::vector<int64_t> lane_free_at;  // per lane: the end of its last frame
  for (const size_t i : order) {
    const FrameRecord& f = result.frames[i];
    const int64_t from = from_of(f);
    const auto free = std::find_if(lane_free_at.begin(), lane_free_at.end(),
                                   [from](int64_t end) { return end <= from; });
    const int lane = static_cast<int>(free - lane_free_at.begin());
    if (free == lane_free_at.end()) {
      lane_free_at.push_back(f.done_ns);
      events.push_back({{"name", "thread_name"},
                        {"ph", "M"},
                        {"pid", 2},
                        {"tid", lane},
                        {"args", {{"name", fmt::format("frames {}", lane)}}}});
    } else {
      *free = f.done_ns;
    }
    events.push_back(
        {{"name", fmt::format("frame {}", f.frame_index)},
         {"cat", "frame"},
         {"ph", "X"},
         {"ts", Us(from)},
         {"dur", Us(f.done_ns - from)},
         {"pid", 2},
         {"tid", lane},
         {"args",
          {{"seq", f.seq},
           {"quality", result.stats.adaptive ? nodes::ToString(f.quality) : "fixed"},
           {"mask", nodes::ToString(f.mask)},
           {"mask_from_seq", f.mask_source_seq},
           {"propagate_ms", f.propagate_ms},
           {"segmentation", nodes::ToString(f.segmentation)},
           {"excluded", f.num_excluded},
           {"tracked", f.output.num_tracked},
           {"keyframe", f.output.keyframe_inserted},
           {"latency_to_pose_ms", f.latency_ms},
           {"wait_for_slot_ms", static_cast<double>(f.admit_ns - f.release_ns) * 1e-6}}}});
  }
  for (size_t i = 0; i < result.dropped_frame_indices.size(); ++i) {
    events.push_back({{"name", fmt::format("dropped frame {}", result.dropped_frame_indices[i])},
                      {"cat", "drop"},
                      {"ph", "i"},
                      {"s", "p"},
                      {"ts", Us(result.dropped_release_ns[i])},
                      {"pid", 2},
                      {"tid", 0}});
  }
  nlohmann::json trace = {{"traceEvents", events}, {"displayTimeUnit", "ms"}};
  std::ofstream out(path);
  out << trace.dump() << "\n";
  if (!out) throw InputError(path, 0, "cannot write the trace");
}

void WriteTimingChart(const std::string& path, const PipelineResult& result, double max_seconds) {
  const PipelineStats& s = result.stats;
  // The chart spans the run, wall_s (which ends with the last call it waited for).
  int64_t end_ns = std::max<int64_t>(1, std::llround(s.wall_s * 1e9));
  int num_threads = 1;
  std::vector<int> device_lanes;  // kDeviceLane first, then kFlowDeviceLane
  for (const StageEvent& e : result.events) {
    end_ns = std::max(end_ns, e.end_ns);
    num_threads = std::max(num_threads, e.thread + 1);
    for (const StagePiece& piece : e.pieces) num_threads = std::max(num_threads, piece.thread + 1);
    if (Profiler::IsDeviceLane(e.thread) &&
        std::find(device_lanes.begin(), device_lanes.end(), e.thread) == device_lanes.end())
      device_lanes.push_back(e.thread);
  }
  std::sort(device_lanes.rbegin(), device_lanes.rend());
  // Rows: the threads, then the devices' lanes (where device waits recorded passes).
  const int num_lanes = num_threads + static_cast<int>(device_lanes.size());
  auto lane_of = [num_threads, &device_lanes](int thread) {
    if (!Profiler::IsDeviceLane(thread)) return thread;
    return num_threads +
           static_cast<int>(std::find(device_lanes.begin(), device_lanes.end(), thread) -
                            device_lanes.begin());
  };
  if (max_seconds > 0) end_ns = std::min(end_ns, static_cast<int64_t>(max_seconds * 1e9));
  std::vector<std::string> names;
  for (const auto& [name, st] : s.stages) names.push_back(name);
  const std::vector<std::string> stages = OrderedStages(names);

  const int width = 1600, left = 110, right = 30, lane_h = 26;
  const int gantt_top = 60, gantt_h = num_lanes * lane_h;
  const int legend_top = gantt_top + gantt_h + 40;
  const int bars_top = legend_top + 40, bar_h = 22;
  const int height = bars_top + static_cast<int>(stages.size()) * (bar_h + 8) + 40;
  cv::Mat image(height, width, CV_8UC3, cv::Scalar(255, 255, 255));

  Text(image,
       fmt::format("PCR-ORB pipeline: {}, {} threads, {} in flight | {} frames in {:.2f} s, {:.2f} "
                   "fps, latency p50 {:.0f} / p95 {:.0f} ms, {} dropped, {} stale masks",
                   s.policy, s.threads, s.max_in_flight, s.frames_completed, s.wall_s, s.fps,
                   s.latency.p50_ms, s.latency.p95_ms, s.frames_dropped, s.masks_stale),
       {10, 25}, 0.55, {0, 0, 0}, 1);
  Text(image, "stage calls per worker thread over time", {10, gantt_top - 10});

  // Gantt.
  const double span_ms = static_cast<double>(end_ns) * 1e-6;
  const double px_per_ms = (width - left - right) / span_ms;
  for (int t = 0; t < num_lanes; ++t) {
    const int y = gantt_top + t * lane_h;
    cv::rectangle(image, {left, y}, {width - right, y + lane_h - 4}, {245, 245, 245}, cv::FILLED);
    Text(image,
         t < num_threads
             ? fmt::format("thread {}", t)
             : std::string(device_lanes[t - num_threads] == Profiler::kDeviceLane ? "device"
                                                                                  : "device flow"),
         {10, y + lane_h - 10});
  }
  for (const StageEvent& e : result.events) {
    // A call that waited for a device: its stretches on the threads that ran it.
    for (const StagePiece& piece : HostStretches(e)) {
      if (piece.start_ns >= end_ns) continue;
      const int x0 =
          left +
          static_cast<int>(std::lround(static_cast<double>(piece.start_ns) * 1e-6 * px_per_ms));
      const int x1 =
          left + static_cast<int>(std::lround(static_cast<double>(std::min(piece.end_ns, end_ns)) *
                                              1e-6 * px_per_ms));
      const int y = gantt_top + lane_of(piece.thread) * lane_h;
      cv::rectangle(image, {x0, y + 1}, {std::max(x0 + 1, x1), y + lane_h - 5},
                    StageColour(e.stage), cv::FILLED);
    }
  }
  // Where the run waited after its last frame: a mark at the last retirement.
  const int64_t last_retire_ns = std::llround(s.last_retire_s * 1e9);
  if (last_retire_ns > 0 && last_retire_ns < end_ns && end_ns - last_retire_ns >= 5'000'000) {
    const int x = left + static_cast<int>(
                             std::lround(static_cast<double>(last_retire_ns) * 1e-6 * px_per_ms));
    cv::line(image, {x, gantt_top - 4}, {x, gantt_top + gantt_h}, {0, 0, 0}, 1);
    Text(image, "last frame retired", {std::max(left, x - 150), gantt_top - 10}, 0.4);
  }
  const double step = TickStep(span_ms, 10);
  for (double t = 0; t <= span_ms + 1e-9; t += step) {
    const int x = left + static_cast<int>(std::lround(t * px_per_ms));
    cv::line(image, {x, gantt_top + gantt_h}, {x, gantt_top + gantt_h + 5}, {0, 0, 0});
    Text(image, step >= 1000 ? fmt::format("{:g} s", t / 1000) : fmt::format("{:g} ms", t),
         {x - 15, gantt_top + gantt_h + 20}, 0.4);
  }

  // Legend.
  int x = left;
  for (const std::string& stage : stages) {
    cv::rectangle(image, {x, legend_top - 12}, {x + 18, legend_top + 2}, StageColour(stage),
                  cv::FILLED);
    Text(image, stage, {x + 24, legend_top});
    x += 30 + static_cast<int>(stage.size()) * 9 + 20;
  }

  // Per-stage p50 (solid) and p95 (outline) bars.
  double max_ms = 1e-3;
  for (const std::string& stage : stages) max_ms = std::max(max_ms, s.stages.at(stage).time.p95_ms);
  const double bar_px_per_ms = (width - left - right - 420) / max_ms;
  Text(image, "per-stage time per call: p50 (filled), p95 (outline), calls", {10, bars_top - 12});
  for (size_t i = 0; i < stages.size(); ++i) {
    const StageStats& st = s.stages.at(stages[i]);
    const int y = bars_top + static_cast<int>(i) * (bar_h + 8);
    Text(image, stages[i], {10, y + bar_h - 6});
    const int p50 = static_cast<int>(std::lround(st.time.p50_ms * bar_px_per_ms));
    const int p95 = static_cast<int>(std::lround(st.time.p95_ms * bar_px_per_ms));
    cv::rectangle(image, {left, y}, {left + std::max(1, p50), y + bar_h}, StageColour(stages[i]),
                  cv::FILLED);
    cv::rectangle(image, {left, y}, {left + std::max(1, p95), y + bar_h}, {0, 0, 0}, 1);
    Text(image,
         fmt::format("p50 {:.1f}  p95 {:.1f}  p99 {:.1f} ms  ({} calls)", st.time.p50_ms,
                     st.time.p95_ms, st.time.p99_ms, st.time.count),
         {left + std::max(p95, p50) + 8, y + bar_h - 6});
  }
  if (!cv::imwrite(path, image)) throw InputError(path, 0, "cannot write the timing chart");
}

}  // namespace pcr::graph
