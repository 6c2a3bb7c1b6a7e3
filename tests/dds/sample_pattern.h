// Deterministic sample content shared by the DDS test and its peer process, so
// the receiver can check every field bit for bit.
#pragma once

#include <cmath>
#include <cstdint>

#include "magnav/dds/topics.h"

namespace magnav::testing {

inline dds::msg::GradiometerSample PatternSample(std::uint32_t sensor_id, std::uint64_t i) {
  dds::msg::GradiometerSample m;
  m.sensor_id(sensor_id);
  m.stamp_ns(1'000'000'000ull + i * 100'000'000ull);
  m.seq(i);
  const double x = static_cast<double>(i);
  m.sensor_position({x * 0.25, -x / 3.0, 5.0 + 1e-9 * x});
  m.B({2e-5 + 1e-12 * x, std::sin(x) * 1e-9, 4.5e-5 - std::cos(x) * 1e-9});
  std::array<double, 9> T;
  for (int k = 0; k < 9; ++k) T[k] = std::ldexp(std::sin(x + k), -30) / (k + 1);
  m.T(T);
  m.sigma_B(1e-9);
  m.sigma_T(1.4e-9 + x * 1e-20);
  return m;
}

inline dds::msg::DipoleFix PatternFix(std::uint64_t i) {
  dds::msg::DipoleFix f;
  f.sensor_id(7);
  f.stamp_ns(i * 1000);
  f.sample_seq(i);
  f.method(dds::msg::METHOD_TED_EGT);
  f.valid(i % 2 == 0);
  f.reason(i % 2 == 0 ? "" : "weak_signal");
  f.position({1.0 * i, 2.0, -5.0});
  f.condition_number(3.5 + i);
  return f;
}

}  // namespace magnav::testing
