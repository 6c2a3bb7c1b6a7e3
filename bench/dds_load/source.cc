// Load source: publishes GradiometerSamples from a pass file (cycled) at a
// fixed rate for a fixed time; stamp_ns = send time (CLOCK_MONOTONIC).
//   bench_dds_source FILE RATE_PER_S DURATION_S
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <unordered_map>

#include "load_common.h"
#include "magnav/core/gradiometer.h"
#include "magnav/dds/convert.h"
#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: bench_dds_source FILE RATE_PER_S DURATION_S\n");
    return 2;
  }
  try {
    magnav::dds::InstallShutdownHandlers();
    const magnav::GradiometerFile file = magnav::ReadGradiometerFile(argv[1]);
    const double rate = std::atof(argv[2]), duration = std::atof(argv[3]);
    magnav::dds::NodeOptions o;
    o.name = "bench_source";
    magnav::dds::Node node(o);
    auto w = node.CreateWriter<magnav::dds::msg::GradiometerSample>();
    if (!w->WaitForMatched(1, std::chrono::seconds(20))) {
      std::fprintf(stderr, "source: no reader\n");
      return 3;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let the rest of discovery settle
    std::unordered_map<std::uint32_t, std::uint64_t> seq;
    const auto total = static_cast<std::uint64_t>(rate * duration);
    const auto start = std::chrono::steady_clock::now();
    std::uint64_t sent = 0, refused = 0;
    std::size_t k = 0;
    while (sent < total && !magnav::dds::ShutdownRequested()) {
      // Send what is due by now (1 ms ticks).
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      const auto due = std::min<std::uint64_t>(total, static_cast<std::uint64_t>(elapsed * rate) + 1);
      while (sent < due) {
        const magnav::GradiometerSample& s = file.samples[k];
        k = (k + 1) % file.samples.size();
        auto m = magnav::dds::ToMsg(s, seq[s.sensor_id]++);
        m.stamp_ns(magnav::bench::MonotonicNanos());
        if (!w->Write(m)) ++refused;
        ++sent;
      }
      std::this_thread::sleep_until(start + std::chrono::microseconds(
                                                static_cast<long>(1e6 * (static_cast<double>(sent) / rate))));
    }
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    w->WaitForAcknowledgments(std::chrono::seconds(10));
    std::printf("source sent %llu refused %llu in %.2f s (%.0f/s)\n", static_cast<unsigned long long>(sent),
                static_cast<unsigned long long>(refused), secs, sent / secs);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "source: %s\n", e.what());
    return 1;
  }
  return 0;
}
