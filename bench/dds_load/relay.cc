// Plain relay (the baseline of the service load benchmark): republishes each
// GradiometerSample as a DipoleFix without computing anything.
#include <cstdio>

#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"

namespace msg = magnav::dds::msg;

int main() {
  try {
    magnav::dds::InstallShutdownHandlers();
    magnav::dds::NodeOptions o;
    o.name = "bench_relay";
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
    while (!magnav::dds::WaitForShutdown(std::chrono::milliseconds(100))) {
    }
    std::printf("relay forwarded %llu\n", static_cast<unsigned long long>(w->stats().samples.load()));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "relay: %s\n", e.what());
    return 1;
  }
  return 0;
}
