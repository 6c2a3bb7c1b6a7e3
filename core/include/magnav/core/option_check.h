// Helpers of the options structs' IsValid(std::string* error) (every
// module): set the message and fail; the usual "finite and > 0" test.
#pragma once

#include <cmath>
#include <string>

namespace magnav {

// Writes `what` to *error (if given) and returns false.
inline bool Fail(std::string* error, const std::string& what) {
  if (error != nullptr) *error = what;
  return false;
}

inline bool PositiveFinite(double x) { return std::isfinite(x) && x > 0.0; }

}  // namespace magnav
