#include "graph/pipeline_options.h"

#include <cmath>

namespace pcr::graph {

const char* ToString(Policy policy) {
  switch (policy) {
    case Policy::kSequential:
      return "sequential";
    case Policy::kPipelined:
      return "pipelined";
    case Policy::kRealtime:
      return "realtime";
  }
  return "?";
}

bool ParsePolicy(const std::string& text, Policy* policy) {
  for (Policy p : {Policy::kSequential, Policy::kPipelined, Policy::kRealtime}) {
    if (text == ToString(p)) {
      *policy = p;
      return true;
    }
  }
  return false;
}

bool PipelineOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (threads < 1 || threads > 256) return fail("threads must be in [1, 256]");
  if (max_in_flight < 1 || max_in_flight > 1024) return fail("max_in_flight must be in [1, 1024]");
  if (!(std::isfinite(rate) && rate >= 0)) return fail("rate must be finite and >= 0");
  if (waiting_capacity < 1) return fail("waiting_capacity must be >= 1");
  if (inference_every < 1 || inference_every > 1000)
    return fail("inference_every must be in [1, 1000]");
  if (!(std::isfinite(mask_deadline_ms) && mask_deadline_ms >= 0))
    return fail("mask_deadline_ms must be finite and >= 0");
  if (trim_heap_every < 0) return fail("trim_heap_every must be >= 0");
  // At most a minute a frame: the delay is slept in whole microseconds (an int64).
  if (!(std::isfinite(tracking_delay_ms) && tracking_delay_ms >= 0 && tracking_delay_ms <= 6e4))
    return fail("tracking_delay_ms must be in [0, 60000]");
  std::string inner;
  if (!levels.IsValid(&inner)) return fail("levels: " + inner);
  if (!controller.IsValid(&inner)) return fail("controller: " + inner);
  if (!carry.IsValid(&inner)) return fail("carry: " + inner);
  if (!scorer.IsValid(&inner)) return fail("scorer: " + inner);
  return true;
}

}  // namespace pcr::graph
