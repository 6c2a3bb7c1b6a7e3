// The door every service puts in front of its estimators: a sample from the
// wire that fails core's CheckSample (non-finite time, field, tensor,
// position or σ; an all-zero tensor) is counted and logged once per sensor
// and defect, and the caller skips it. Thread-safe (services are called from
// several receive threads).
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <set>
#include <string>
#include <utility>

#include "magnav/core/gradiometer.h"

namespace magnav::dds {

class SampleDoor {
 public:
  // `service` prefixes the log lines ("magnav-inverter").
  explicit SampleDoor(std::string service) : service_(std::move(service)) {}

  // The sample's defect (kNone: let it in). Counts and logs the others.
  SampleDefect Check(const GradiometerSample& sample);
  std::uint64_t rejected() const { return rejected_.load(); }

 private:
  std::string service_;
  std::atomic<std::uint64_t> rejected_{0};
  std::mutex mu_;
  std::set<std::pair<std::uint32_t, int>> logged_;  // (sensor, defect) already logged
};

}  // namespace magnav::dds
