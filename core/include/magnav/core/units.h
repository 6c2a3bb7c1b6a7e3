// Physical constants and unit conversions. Everything in magnav code is SI:
// metres, seconds, tesla, tesla per metre, A·m², radians. Conversions happen at
// the edges (files in nT or degrees, DDS time stamps in ns).
#pragma once

#include <chrono>
#include <cstdint>
#include <numbers>
#include <string>

namespace magnav {

// Vacuum permeability used by the field model, 4π·1e-7 H/m (the pre-2019 exact
// value, as in the reference data; CODATA 2022 differs by 1.3e-10 relative).
inline constexpr double kMu0 = 4.0 * std::numbers::pi * 1e-7;
// μ0/(4π) in H/m, the prefactor of every dipole expression.
inline constexpr double kMu0Over4Pi = 1e-7;

inline constexpr double kNanoTesla = 1e-9;  // T per nT
inline constexpr double kPicoTesla = 1e-12;  // T per pT
inline constexpr double kDegToRad = std::numbers::pi / 180.0;
inline constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// Seconds (double, scenario time) <-> nanoseconds (uint64, DDS time stamps).
// Negative or non-finite seconds map to 0.
std::uint64_t SecondsToNanos(double seconds);
inline double NanosToSeconds(std::uint64_t nanos) { return static_cast<double>(nanos) * 1e-9; }

// Nanoseconds as a decimal number of seconds, exact ("0.3", "12.000000001").
std::string FormatNanosAsSeconds(std::uint64_t nanos);

// Wraps an angle to (−π, π].
double WrapAngle(double radians);

// Wall-clock seconds from a to b (solve times in summaries).
inline double Seconds(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

}  // namespace magnav
