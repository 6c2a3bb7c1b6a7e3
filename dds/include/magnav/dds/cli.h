// Command-line options every DDS program shares (the magnav tool's replay and
// record commands, and each service): domain id, extra XML profiles,
// participant profile. Kept here so services and tools parse them alike.
#pragma once

#include <cstdio>
#include <functional>
#include <string>

#include <CLI/CLI.hpp>

#include "magnav/core/error.h"
#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"

namespace magnav::dds {

struct DdsArgs {
  int domain_id = -1;               // -1: $MAGNAV_DOMAIN_ID, else $ROS_DOMAIN_ID, else 0
  std::string profiles_file;        // extra Fast DDS XML profiles
  std::string participant_profile;  // "": $MAGNAV_DDS_PARTICIPANT or magnav_loopback

  NodeOptions ToNodeOptions(const std::string& name) const {
    NodeOptions o;
    o.name = name;
    if (domain_id >= 0) o.domain_id = domain_id;
    o.profiles_file = profiles_file;
    o.participant_profile = participant_profile;
    return o;
  }
};

inline void AddDdsOptions(CLI::App& app, DdsArgs* out) {
  app.add_option("--domain", out->domain_id, "DDS domain id (default $MAGNAV_DOMAIN_ID, $ROS_DOMAIN_ID, 0)")
      ->check(CLI::Range(0, 232));
  app.add_option("--dds-profiles", out->profiles_file, "extra Fast DDS XML profiles file (e.g. config/magnav_multihost.xml)")
      ->check(CLI::ExistingFile);
  app.add_option("--dds-participant", out->participant_profile,
                 "participant profile (default magnav_loopback: 127.0.0.1 + shared memory only)");
}

// Runs a service's body and turns its errors into a message and an exit code:
// 2 for bad input or options (InputError), 4 for the middleware (DdsError),
// 3 for anything else. The body returns when a shutdown was requested.
inline int RunService(const char* name, const std::function<void()>& body) {
  try {
    body();
  } catch (const InputError& e) {
    std::fprintf(stderr, "%s: error: %s\n", name, e.what());
    return 2;
  } catch (const DdsError& e) {
    std::fprintf(stderr, "%s: DDS error: %s\n", name, e.what());
    return 4;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: internal error: %s\n", name, e.what());
    return 3;
  }
  return 0;
}

// Sleeps in periods of period_s (1 s if period_s <= 0) until a shutdown is
// requested, calling on_period after each full period when period_s > 0.
inline void RunUntilShutdown(double period_s, const std::function<void()>& on_period) {
  const auto period = std::chrono::milliseconds(period_s > 0 ? static_cast<long>(period_s * 1000) : 1000);
  while (!WaitForShutdown(period)) {
    if (period_s > 0) on_period();
  }
}

}  // namespace magnav::dds
