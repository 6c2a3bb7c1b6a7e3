#include "magnav/core/limits.h"

#include "magnav/core/csv.h"

namespace magnav {

std::string OutOfRange(const Limit& limit, double value) {
  return FormatNumber(value) + " " + limit.unit + " is out of range (|value| > " + FormatNumber(limit.max_abs) + " " +
         limit.unit + "; " + limit.why + ")";
}

}  // namespace magnav
