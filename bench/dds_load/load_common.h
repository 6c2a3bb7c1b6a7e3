// Shared bits of the service load benchmark (source -> node under test -> sink).
#pragma once

#include <time.h>

#include <cstdint>

namespace magnav::bench {

// CLOCK_MONOTONIC in ns: comparable across processes on one host, so the
// sink can compute end-to-end latency from the source's stamp.
inline std::uint64_t MonotonicNanos() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<std::uint64_t>(ts.tv_nsec);
}

}  // namespace magnav::bench
