#include "nodes/loop_node.h"

namespace pcr::nodes {

LoopOutcomePtr LoopNode::Close(const LoopJob& job) {
  return std::make_shared<const LoopOutcome>(LoopCloser::CloseLoop(job));
}

LoopOutcomePtr LoopNode::GlobalBundleAdjustment(const LoopJob& job, const LoopOutcome& corrected,
                                                const std::atomic<bool>* abort) {
  return std::make_shared<const LoopOutcome>(
      LoopCloser::GlobalBundleAdjustment(job, corrected, abort));
}

void LoopNode::operator()(const LoopJob& job, const std::atomic<bool>* abort,
                          const std::function<void(LoopOutcomePtr)>& post) const {
  const LoopOutcomePtr corrected = Close(job);
  post(corrected);
  if (corrected->kind == LoopOutcomeKind::kCorrected && job.options.global_bundle_adjustment)
    post(GlobalBundleAdjustment(job, *corrected, abort));
}

}  // namespace pcr::nodes
