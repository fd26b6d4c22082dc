#pragma once
// Outputs of a pipeline run's profile: statistics as JSON and text, the Chrome trace (Trace Event
// Format, open in chrome://tracing or https://ui.perfetto.dev) and a per-stage timing chart.
#include <nlohmann/json.hpp>
#include <string>

#include "graph/pipeline.h"

namespace pcr::graph {

// Per stage: calls and mean/p50/p95/p99/max ms, queue waits, max queue depth; end-to-end latency
// percentiles, throughput, drops, stale masks, quality-level histogram and changes, max in flight.
nlohmann::json StatsToJson(const PipelineStats& stats);

// The same as a console table.
std::string FormatPipelineStats(const PipelineStats& stats);

// Loop closing: the closer's counters, detection times (p50/p99 per keyframe), and every outcome
// the map's owner dealt with (kind, keyframes, matches, correction size, step times).
nlohmann::json LoopToJson(const PipelineResult& result);
// One or two lines: loops closed, rejected jobs and candidates, times ("" without loop closing).
std::string FormatLoopSummary(const PipelineResult& result);

// Relocalisation's counters (RelocalisationStats) for stats.json, and as one line ("" when no
// frame had to be relocalised).
nlohmann::json RelocalisationToJson(const RelocalisationStats& stats);
std::string FormatRelocalisationSummary(const RelocalisationStats& stats);

// The map's parts when the run ended (MapSnapshot::keyframe_parts, frame_parts), in part order:
// part 0 holds the oldest keyframe; another part shares no point with it (a part tracking started
// after a loss, or beside a loaded map, that no loop joined), so its poses are in a frame of
// their own.
struct MapPartSummary {
  int part = 0;
  size_t keyframes = 0;
  int64_t first_keyframe_frame = -1;  // its oldest keyframe's frame of this run; -1: loaded
  size_t tracked_frames = 0;          // frames whose pose hangs on one of its keyframes
  int64_t first_tracked_frame = -1;   // the first of them; -1: none
};
std::vector<MapPartSummary> SummariseMapParts(const MapSnapshot& map);
// stats.json's map.parts: one object per part (the fields above).
nlohmann::json MapPartsToJson(const MapSnapshot& map);
// One line when the map ended in more than one part ("" otherwise).
std::string FormatMapPartsSummary(const MapSnapshot& map);

// Chrome trace: one "X" (complete) event per stage call on pid 1 with the thread as tid; one per
// frame on pid 2 (realtime: release -> retirement, else admission -> retirement), each on the
// first lane ("frames N") free at its start, so that no two frames overlap on a lane; an instant
// event per dropped frame. ts/dur in microseconds. Throws InputError when the file cannot be
// written.
void WriteChromeTrace(const std::string& path, const PipelineResult& result);

// PNG: a Gantt chart of the stage calls per thread over the run (or its first `max_seconds`),
// and per-stage p50/p95 bars. Throws InputError when the file cannot be written.
void WriteTimingChart(const std::string& path, const PipelineResult& result,
                      double max_seconds = 0);

}  // namespace pcr::graph
