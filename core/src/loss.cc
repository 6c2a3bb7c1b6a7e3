#include "magnav/core/loss.h"

namespace magnav {

bool ParseLossType(const std::string& name, LossType* type) {
  if (name == "trivial") {
    *type = LossType::kTrivial;
  } else if (name == "huber") {
    *type = LossType::kHuber;
  } else if (name == "cauchy") {
    *type = LossType::kCauchy;
  } else {
    return false;
  }
  return true;
}

const char* LossTypeName(LossType type) {
  switch (type) {
    case LossType::kTrivial:
      return "trivial";
    case LossType::kHuber:
      return "huber";
    case LossType::kCauchy:
      return "cauchy";
  }
  return "?";
}

}  // namespace magnav
