#pragma once
// The loss of one observation under the dynamic filter's weight: weight * rho(chi2), rho being
// the observation's Huber kernel in robust rounds and the identity otherwise. The weight scales
// the cost, not the residual, so chi2 tests on the whitened residual do not depend on it (shared
// by the pose optimiser and bundle adjustment).
#include <ceres/loss_function.h>

#include <memory>

namespace pcr::optim {

class WeightedLoss {
 public:
  WeightedLoss() = default;  // unweighted, no kernel: Get() is null
  // huber: this observation's kernel, not owned (it must outlive this object).
  WeightedLoss(double weight, ceres::LossFunction* huber) : huber_(huber) {
    if (weight == 1.0) return;  // the plain kernels serve unweighted observations
    plain_ = std::make_unique<ceres::ScaledLoss>(nullptr, weight, ceres::DO_NOT_TAKE_OWNERSHIP);
    robust_ = std::make_unique<ceres::ScaledLoss>(huber, weight, ceres::DO_NOT_TAKE_OWNERSHIP);
  }

  // The loss to give Problem::AddResidualBlock (null: the squared norm); not owned by Ceres.
  ceres::LossFunction* Get(bool robust) const {
    if (robust) return robust_ ? robust_.get() : huber_;
    return plain_.get();
  }

 private:
  ceres::LossFunction* huber_ = nullptr;
  std::unique_ptr<ceres::LossFunction> plain_, robust_;
};

}  // namespace pcr::optim
