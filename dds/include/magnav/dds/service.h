// The run loop of a service main: errors to exit codes, periodic work until
// SIGINT/SIGTERM (no command line here: that is magnav::cli).
#pragma once

#include <chrono>
#include <cstdio>
#include <exception>
#include <functional>

#include "magnav/core/error.h"
#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"

namespace magnav::dds {

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
