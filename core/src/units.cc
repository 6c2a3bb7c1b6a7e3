#include "magnav/core/units.h"

#include <cmath>
#include <cstdio>
#include <limits>

namespace magnav {

std::uint64_t SecondsToNanos(double seconds) {
  if (!std::isfinite(seconds) || seconds <= 0.0) return 0;
  const double ns = std::round(seconds * 1e9);
  if (ns >= static_cast<double>(std::numeric_limits<std::uint64_t>::max())) {
    return std::numeric_limits<std::uint64_t>::max();
  }
  return static_cast<std::uint64_t>(ns);
}

std::string FormatNanosAsSeconds(std::uint64_t nanos) {
  std::string s = std::to_string(nanos / 1000000000ull);
  std::uint64_t frac = nanos % 1000000000ull;
  if (frac == 0) return s;
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%09llu", static_cast<unsigned long long>(frac));
  std::string f(buf);
  while (f.back() == '0') f.pop_back();
  return s + "." + f;
}

double WrapAngle(double a) {
  if (!std::isfinite(a)) return a;
  a = std::remainder(a, 2.0 * std::numbers::pi);  // [−π, π]
  if (a <= -std::numbers::pi) a += 2.0 * std::numbers::pi;
  return a;
}

}  // namespace magnav
