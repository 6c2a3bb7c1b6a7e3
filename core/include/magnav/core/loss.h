// Robust-loss choice shared by the estimators (tracker, localizer): the kind
// of loss applied to a whitened residual block, and its name on command lines
// and in config files. The Ceres loss it stands for is in core/ceres_loss.h
// (header-only: core itself does not link Ceres).
#pragma once

#include <string>

namespace magnav {

// Robust loss on a whitened residual block (its scale in σ of the norm).
enum class LossType { kTrivial, kHuber, kCauchy };

// Parses "trivial" | "huber" | "cauchy"; false on anything else.
bool ParseLossType(const std::string& name, LossType* type);
const char* LossTypeName(LossType type);

}  // namespace magnav
