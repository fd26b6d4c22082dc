#pragma once
// Small pieces shared by the Ceres problems of slam/optim: the Huber cost of a chi-square value
// and the iteration callback that stops a solve when the caller's abort flag is set.
#include <ceres/iteration_callback.h>

#include <atomic>
#include <cmath>

namespace pcr::optim {

// Huber's rho of a squared whitened residual chi2 with threshold delta^2.
inline double HuberCost(double chi2, double threshold) {
  if (chi2 <= threshold) return chi2;
  return 2.0 * std::sqrt(threshold * chi2) - threshold;
}

// Stops the solve at its next iteration once *abort is true (read with acquire order; the flag
// is owned by the caller and may be set from any thread).
class AbortCallback final : public ceres::IterationCallback {
 public:
  explicit AbortCallback(const std::atomic<bool>* abort) : abort_(abort) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return abort_->load(std::memory_order_acquire) ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const std::atomic<bool>* abort_;
};

}  // namespace pcr::optim
