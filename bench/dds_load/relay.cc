// Plain relay (the baseline of the service load benchmark): republishes each
// GradiometerSample as a DipoleFix without computing anything.
//   bench_dds_relay                 its reader as every magnav reader: the
//                                   profile's DataReader, and the any-writer
//                                   companion once a stock writer appears
//                                   (node.h; none with the bench's source)
//   bench_dds_relay single-reader   the profile's DataReader alone, never a
//                                   companion
//   bench_dds_relay companion       the companion made at the start, as in a
//                                   field with a stock writer on the topic:
//                                   every sample of magnav's source then
//                                   reaches both DataReaders (its cost:
//                                   docs/BENCHMARKS.md)
#include <cstdio>
#include <stdexcept>
#include <string>

#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"

namespace msg = magnav::dds::msg;

int main(int argc, char** argv) {
  try {
    const std::string mode = argc == 2 ? argv[1] : "";
    const bool single = mode == "single-reader", companion = mode == "companion";
    if (argc > 2 || (argc == 2 && !single && !companion)) {
      std::fprintf(stderr, "usage: bench_dds_relay [single-reader|companion]\n");
      return 2;
    }
    magnav::dds::InstallShutdownHandlers();
    magnav::dds::NodeOptions o;
    o.name = "bench_relay";
    o.any_writer = !single;
    magnav::dds::Node node(o);
    auto w = node.CreateWriter<msg::DipoleFix>();
    auto r = node.CreateReader<msg::GradiometerSample>([&](const msg::GradiometerSample& s, const auto&) {
      msg::DipoleFix f;
      f.sensor_id(s.sensor_id());
      f.stamp_ns(s.stamp_ns());
      f.sample_seq(s.seq());
      f.method(msg::METHOD_OTHER);
      f.valid(false);
      f.reason("relay");
      w->Write(f);
    });
    if (companion) {
      r->ListenToAnyWriter();
      if (!r->WaitForCompanion(std::chrono::seconds(10))) throw std::runtime_error("no companion reader");
    }
    while (!magnav::dds::WaitForShutdown(std::chrono::milliseconds(100))) {
    }
    std::printf("relay forwarded %llu (%s; duplicates dropped %llu)\n",
                static_cast<unsigned long long>(w->stats().samples.load()),
                r->has_companion() ? "profile reader + any-writer companion" : "profile reader only",
                static_cast<unsigned long long>(r->stats().duplicates.load()));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "relay: %s\n", e.what());
    return 1;
  }
  return 0;
}
