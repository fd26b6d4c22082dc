#include "nodes/loop_node.h"

namespace pcr::nodes {

LoopOutcomePtr LoopNode::Close(const LoopJobPtr& job, LoopJobPtr* resolved) {
  *resolved = replica_.Resolve(job);
  return std::make_shared<const LoopOutcome>(LoopCloser::CloseLoop(**resolved));
}

LoopOutcomePtr LoopNode::GlobalBundleAdjustment(const LoopJob& job, const LoopOutcome& corrected,
                                                const std::atomic<bool>* abort) {
  return std::make_shared<const LoopOutcome>(
      LoopCloser::GlobalBundleAdjustment(job, corrected, abort));
}

}  // namespace pcr::nodes
