// The Ceres loss of a LossType (core/loss.h), for the modules that solve with
// Ceres (tracker, localizer). Header-only on purpose: core does not link or
// include Ceres itself; only a target that links Ceres::ceres includes this.
#pragma once

#include <ceres/loss_function.h>

#include <memory>

#include "magnav/core/loss.h"

namespace magnav {

// A new loss of a type with scale a (in σ of the whitened residual norm:
// ρ(s) is quadratic for s = ‖e‖² ≤ a²); null for kTrivial (squared loss).
inline std::unique_ptr<ceres::LossFunction> MakeCeresLoss(LossType type, double scale_sigma) {
  switch (type) {
    case LossType::kTrivial:
      return nullptr;
    case LossType::kHuber:
      return std::make_unique<ceres::HuberLoss>(scale_sigma);
    case LossType::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(scale_sigma);
  }
  return nullptr;
}

}  // namespace magnav
