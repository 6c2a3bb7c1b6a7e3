// End-to-end latency of magnav-matcher's node on loopback DDS, in one
// process: a peer writes a VesselNav and then a MagnetometerSample (the
// crustal 0.1°-offset reference run, 3 nT, as `magnav replay --map-path`
// sends it) every 20 ms, the MatcherNode steps its filter and publishes a
// MapFix at every step (--fix-every 0), and the peer times sample written →
// MapFix received. Two hops plus one filter step. Prints median / 90 % / max
// for the first 20 steps (AFPF: up to 30 000 particles) and the rest.
// Usage: bench_matcher_latency [pf|afpf]... (domain: $MAGNAV_DOMAIN_ID, else from the pid)
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "magnav/mapmatch/path.h"
#include "matcher_node.h"

using namespace magnav;
using Clock = std::chrono::steady_clock;

namespace {

void Report(const char* method, const char* what, std::vector<double> us) {
  if (us.empty()) return;
  std::sort(us.begin(), us.end());
  const auto at = [&](double q) { return us[static_cast<std::size_t>(q * static_cast<double>(us.size() - 1))]; };
  std::printf("%-5s %-12s n %3zu  median %8.1f us  p90 %8.1f us  max %8.1f us\n", method, what, us.size(), at(0.5),
              at(0.9), us.back());
}

}  // namespace

int main(int argc, char** argv) {
  const std::string ref = MAGNAV_REFERENCE_DIR;
  const double f0 = std::sqrt(22838.121767602996 * 22838.121767602996 + 1452.8242542037194 * 1452.8242542037194 +
                              41845.01475649571 * 41845.01475649571);
  const mapmatch::GeoGrid grid = mapmatch::ReadGeoGridCsv(ref + "/map_crustal_anomaly.csv", {"anomaly_nT"});
  const mapmatch::MatchPath path = mapmatch::ReadMatchPath(ref + "/mappath_crustal_off0p1deg_noise3nT.csv", "meas_nT");
  std::vector<std::string> methods;
  for (int i = 1; i < argc; ++i) methods.push_back(argv[i]);
  if (methods.empty()) methods = {"pf", "afpf"};
  magnav::dds::NodeOptions no;
  no.name = "bench_matcher_latency";
  if (const char* d = std::getenv("MAGNAV_DOMAIN_ID")) {
    no.domain_id = std::atoi(d);
  } else {
    no.domain_id = 10 + static_cast<int>(::getpid() % 200);
  }
  for (const std::string& method : methods) {
    mapmatch::MatcherNodeOptions o;
    o.kind = method == "pf" ? mapmatch::ParticleFilterKind::kPf : mapmatch::ParticleFilterKind::kAfpf;
    o.fix_every_m = 0.0;
    o.reference_field_nT = f0;
    magnav::dds::Node service_node(no), peer(no);
    mapmatch::MatcherNode matcher(service_node, grid, 0, o);
    std::mutex mu;
    std::map<std::uint64_t, Clock::time_point> sent, got;
    auto reader = peer.CreateReader<magnav::dds::msg::MapFix>([&](const magnav::dds::msg::MapFix& f, const auto&) {
      const auto now = Clock::now();
      std::lock_guard<std::mutex> lk(mu);
      got[f.stamp_ns()] = now;
    });
    auto navs = peer.CreateWriter<magnav::dds::msg::VesselNav>();
    auto samples = peer.CreateWriter<magnav::dds::msg::MagnetometerSample>();
    if (!navs->WaitForMatched(1, std::chrono::seconds(20)) || !samples->WaitForMatched(1, std::chrono::seconds(20)) ||
        !reader->WaitForMatched(1, std::chrono::seconds(20))) {
      std::fprintf(stderr, "bench_matcher_latency: discovery failed on domain %d\n", *no.domain_id);
      return 1;
    }
    for (std::size_t k = 0; k < path.size(); ++k) {
      const std::uint64_t stamp = (k + 1) * 100000000ULL;
      navs->Write(mapmatch::InsNavMsg(0, stamp, path.lat_deg[k], path.lon_deg[k]));
      {
        std::lock_guard<std::mutex> lk(mu);
        sent[stamp] = Clock::now();
      }
      samples->Write(mapmatch::AnomalySampleMsg(0, stamp, k, path.measured_nT[k], f0));
      std::this_thread::sleep_for(std::chrono::milliseconds(k < 20 ? 60 : 20));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    std::vector<double> first, rest;
    std::lock_guard<std::mutex> lk(mu);
    for (const auto& [stamp, t] : got) {
      const double us = std::chrono::duration<double, std::micro>(t - sent.at(stamp)).count();
      (stamp <= 20 * 100000000ULL ? first : rest).push_back(us);
    }
    Report(method.c_str(), "steps 0-19", first);
    Report(method.c_str(), "steps 20-149", rest);
    std::printf("%-5s fixes received %zu of %zu\n", method.c_str(), got.size(), path.size());
  }
  return 0;
}
