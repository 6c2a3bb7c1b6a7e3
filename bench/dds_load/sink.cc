// Load sink: receives DipoleFix, checks per-sensor sequence gaps (loss) and
// measures latency from the source's send stamp. Stops after EXPECTED fixes
// or IDLE_S seconds without one. With WINDOW_S (the soak), also prints one line
// per WINDOW_S seconds: "window T_S received N p50 .. p99 .. max .." (µs).
//   bench_dds_sink EXPECTED WARMUP_S IDLE_S [WINDOW_S]
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "load_common.h"
#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"

namespace msg = magnav::dds::msg;

int main(int argc, char** argv) {
  if (argc != 4 && argc != 5) {
    std::fprintf(stderr, "usage: bench_dds_sink EXPECTED WARMUP_S IDLE_S [WINDOW_S]\n");
    return 2;
  }
  const std::uint64_t expected = std::strtoull(argv[1], nullptr, 10);
  const double warmup_s = std::atof(argv[2]), idle_s = std::atof(argv[3]);
  const double window_s = argc == 5 ? std::atof(argv[4]) : 0.0;
  try {
    magnav::dds::InstallShutdownHandlers();
    magnav::dds::NodeOptions o;
    o.name = "bench_sink";
    magnav::dds::Node node(o);
    std::mutex mu;
    std::vector<std::uint32_t> latency_ns;
    latency_ns.reserve(window_s > 0 ? 0 : expected);  // the soak keeps its windows only
    std::vector<std::uint32_t> window_ns;
    std::unordered_map<std::uint32_t, std::uint64_t> next;
    std::uint64_t received = 0, gaps = 0, first_ns = 0, last_ns = 0;
    std::atomic<std::uint64_t> last_arrival{magnav::bench::MonotonicNanos()};
    auto r = node.CreateReader<msg::DipoleFix>([&](const msg::DipoleFix& f, const auto&) {
      const std::uint64_t now = magnav::bench::MonotonicNanos();
      std::lock_guard<std::mutex> lk(mu);
      if (received == 0) first_ns = now;
      last_ns = now;
      ++received;
      auto it = next.find(f.sensor_id());
      if (it != next.end() && f.sample_seq() != it->second) gaps += f.sample_seq() - it->second;
      next[f.sensor_id()] = f.sample_seq() + 1;
      if (static_cast<double>(now - first_ns) > warmup_s * 1e9 && now > f.stamp_ns()) {
        const auto l = static_cast<std::uint32_t>(std::min<std::uint64_t>(now - f.stamp_ns(), 4e9));
        (window_s > 0 ? window_ns : latency_ns).push_back(l);
      }
      last_arrival = now;
    });
    std::printf("sink ready\n");
    std::fflush(stdout);
    const std::uint64_t start_ns = magnav::bench::MonotonicNanos();
    std::uint64_t next_window_ns = start_ns + static_cast<std::uint64_t>(window_s * 1e9);
    std::uint64_t received_at_window = 0;
    while (!magnav::dds::ShutdownRequested()) {
      magnav::dds::WaitForShutdown(std::chrono::milliseconds(50));
      std::lock_guard<std::mutex> lk(mu);
      if (window_s > 0 && magnav::bench::MonotonicNanos() >= next_window_ns) {
        std::sort(window_ns.begin(), window_ns.end());
        auto at = [&](double p) {
          return window_ns.empty() ? 0.0 : window_ns[static_cast<std::size_t>(p * (window_ns.size() - 1))] / 1e3;
        };
        std::printf("window %.0f received %llu p50 %.1f p99 %.1f max %.1f\n", (next_window_ns - start_ns) / 1e9,
                    static_cast<unsigned long long>(received - received_at_window), at(0.5), at(0.99),
                    window_ns.empty() ? 0.0 : window_ns.back() / 1e3);
        std::fflush(stdout);
        // The whole run's percentiles from a bounded sample: every 100th latency of the window.
        for (std::size_t i = 0; i < window_ns.size(); i += 100) latency_ns.push_back(window_ns[i]);
        window_ns.clear();
        received_at_window = received;
        next_window_ns += static_cast<std::uint64_t>(window_s * 1e9);
      }
      if (received >= expected) break;
      if (received > 0 && (magnav::bench::MonotonicNanos() - last_arrival) > idle_s * 1e9) break;
    }
    std::lock_guard<std::mutex> lk(mu);
    std::sort(latency_ns.begin(), latency_ns.end());
    auto pct = [&](double p) {
      return latency_ns.empty() ? 0.0 : latency_ns[static_cast<std::size_t>(p * (latency_ns.size() - 1))] / 1e3;
    };
    const double secs = (last_ns - first_ns) / 1e9;
    std::printf("sink received %llu lost %llu middleware_lost %llu rate %.0f/s latency_us p50 %.1f p99 %.1f max %.1f\n",
                static_cast<unsigned long long>(received), static_cast<unsigned long long>(gaps + (expected - std::min(expected, received + gaps))),
                static_cast<unsigned long long>(r->stats().lost.load()), secs > 0 ? received / secs : 0.0, pct(0.5),
                pct(0.99), latency_ns.empty() ? 0.0 : latency_ns.back() / 1e3);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sink: %s\n", e.what());
    return 1;
  }
  return 0;
}
