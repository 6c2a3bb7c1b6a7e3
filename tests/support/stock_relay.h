// A stock DDS driver in front of a magnav service, for the service tests:
// tests/interop's cyclone_peer (Eclipse Cyclone DDS) reads what a test or
// `magnav replay` writes on one domain with magnav's QoS and writes every
// sample again on the service's domain with a stock writer QoS — Cyclone's
// default (RELIABLE, VOLATILE) or ROS 2's sensor-data (BEST_EFFORT,
// VOLATILE) — so that the service hears only a writer whose QoS is not
// magnav's. Available only where Cyclone DDS was found at configure time
// (MAGNAV_CYCLONE_PEER non-empty); tests skip otherwise, saying why.
#pragma once

#include <chrono>
#include <string>

#include "subprocess.h"

#ifndef MAGNAV_CYCLONE_PEER
#define MAGNAV_CYCLONE_PEER ""
#define MAGNAV_CYCLONE_CONFIG ""
#endif

namespace magnav::testing {

class StockRelay {
 public:
  static bool Available() { return std::string(MAGNAV_CYCLONE_PEER).size() > 0; }
  // The domain a test writes to when the relay feeds `service_domain`.
  static int InputDomain(int service_domain) { return service_domain + 1; }

  // qos: "default" or "sensor_data"; topics: "gradiometer",
  // "magnetometer,vessel_nav", ...; at most `rate` samples/s; the relay ends
  // `quiet_s` after the last sample. It is ready once each of its writers
  // has matched `readers` readers (the service, recorders): a volatile
  // writer's samples before that would be lost to them.
  StockRelay(const std::string& qos, const std::string& topics, int service_domain, double rate, int readers = 1,
             double quiet_s = 2.0)
      : proc_({MAGNAV_CYCLONE_PEER, "relay", qos, topics, std::to_string(InputDomain(service_domain)),
               std::to_string(rate), std::to_string(quiet_s), std::to_string(readers)},
              {{"MAGNAV_DOMAIN_ID", std::to_string(service_domain)},
               {"CYCLONEDDS_URI", std::string("file://") + MAGNAV_CYCLONE_CONFIG}},
              /*merge_stderr=*/true) {
    ready_ = proc_.ReadLine() == "ready";
  }
  bool ready() const { return ready_; }
  // Waits for the relay to end (quiet_s after the last sample); its output.
  std::string Finish(std::chrono::milliseconds timeout, int* rc) {
    *rc = proc_.Wait(timeout);
    return proc_.ReadAll();
  }

 private:
  Subprocess proc_;
  bool ready_ = false;
};

}  // namespace magnav::testing
