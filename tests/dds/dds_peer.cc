// Peer process for the DDS tests: publishes deterministic samples on the
// domain given by $MAGNAV_DOMAIN_ID, then optionally stays alive until SIGTERM.
//   dds_peer stream N      publish N GradiometerSamples to one matched reader, wait for acks, exit
//   dds_peer estimates N   publish N DipoleFix (transient-local), print "ready", wait for SIGTERM
//   dds_peer bad_payloads 1  publish a good, a non-CDR, a truncated and a good gradiometer payload
//                          (raw_payload.h) to one matched reader, wait for acks, print "sent 4", exit
//   dds_peer qos 0         print the history depth of a GradiometerSample writer and reader (the
//                          sensor_stream profiles, as $MAGNAV_DDS_PROFILES may override them)
#include <cstdio>
#include <cstdlib>
#include <string>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"
#include "raw_payload.h"
#include "sample_pattern.h"

using namespace std::chrono_literals;

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: dds_peer stream|estimates N\n");
    return 2;
  }
  magnav::dds::InstallShutdownHandlers();
  spdlog::set_default_logger(spdlog::stderr_color_mt("dds_peer"));  // stdout is the test's protocol
  const std::string mode = argv[1];
  const std::uint64_t n = std::strtoull(argv[2], nullptr, 10);
  try {
    magnav::dds::NodeOptions options;
    options.name = "dds_peer";
    magnav::dds::Node node(options);
    if (mode == "stream") {
      auto w = node.CreateWriter<magnav::dds::msg::GradiometerSample>();
      if (!w->WaitForMatched(1, 20s)) return 3;
      // The burst (10,000) is longer than the KEEP_LAST history: send it with
      // the adapter's acknowledgment-based flow control, as magnav replay does.
      w->SetFlowControl(500, 20s);
      for (std::uint64_t i = 0; i < n; ++i) {
        if (!w->Write(magnav::testing::PatternSample(static_cast<std::uint32_t>(i % 4), i))) return 4;
      }
      if (!w->WaitForAcknowledgments(30s)) return 5;
      std::printf("sent %llu\n", static_cast<unsigned long long>(n));
    } else if (mode == "estimates") {
      auto w = node.CreateWriter<magnav::dds::msg::DipoleFix>();
      for (std::uint64_t i = 0; i < n; ++i) w->Write(magnav::testing::PatternFix(i));
      std::printf("ready\n");
      std::fflush(stdout);
      while (!magnav::dds::WaitForShutdown(100ms)) {
      }
    } else if (mode == "bad_payloads") {
      auto w = node.CreateWriter<magnav::testing::RawPayload>();
      if (!w->WaitForMatched(1, 20s)) return 3;
      const auto payloads = magnav::testing::GoodBadBadGood();
      for (const auto& p : payloads) {
        if (!w->Write(p)) return 4;
      }
      if (!w->WaitForAcknowledgments(30s)) return 5;
      std::printf("sent %zu\n", payloads.size());
    } else if (mode == "qos") {
      auto w = node.CreateWriter<magnav::dds::msg::GradiometerSample>();
      auto r = node.CreateReader<magnav::dds::msg::GradiometerSample>(
          [](const magnav::dds::msg::GradiometerSample&, const auto&) {});
      std::printf("writer depth %d reader depth %d\n", w->qos().history().depth, r->qos().history().depth);
    } else {
      return 2;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dds_peer: %s\n", e.what());
    return 6;
  }
  return 0;  // entities deleted by the destructors above
}
