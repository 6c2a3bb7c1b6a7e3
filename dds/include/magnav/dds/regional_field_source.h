// Where a service takes the regional (Earth) field B0 from: given (--b0), or
// estimated per sensor from the stream's quiet stretches (core
// RegionalFieldEstimator). Never a silent zero: until a sensor's B0 is known
// its samples get no B0 and the service says so (the inverter publishes the
// fix rejected with reason "no_b0", the tracker holds the sample back).
// Logs where B0 comes from, each sensor's estimate when it is found, and a
// sensor whose σ is unknown (so B0 cannot be estimated), once. Thread-safe.
// Units: tesla, world NED.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>

#include <Eigen/Core>

#include "magnav/core/gradiometer.h"
#include "magnav/core/regional_field.h"

namespace magnav::dds {

class RegionalFieldSource {
 public:
  // B0 given by the user, the same for every sensor.
  RegionalFieldSource(std::string service, const Eigen::Vector3d& B0_W);
  // B0 estimated per sensor. Throws InputError if the options are invalid.
  RegionalFieldSource(std::string service, const RegionalFieldOptions& options);

  // B0 for the sensor of this (door-checked) sample, feeding the estimator
  // first; nullopt while it is not known.
  std::optional<Eigen::Vector3d> For(const GradiometerSample& sample);
  // One line for the start-up log.
  std::string Describe() const;
  bool estimated() const { return estimator_.has_value(); }
  // Samples that came while their sensor's B0 was unknown.
  std::uint64_t waiting() const { return waiting_.load(); }

 private:
  std::string service_;
  std::optional<Eigen::Vector3d> fixed_;
  RegionalFieldOptions options_;
  std::mutex mu_;
  std::optional<RegionalFieldEstimator> estimator_;
  std::set<std::uint32_t> unknown_sigma_logged_;
  std::atomic<std::uint64_t> waiting_{0};
};

// The given B0 for every sensor, or (nullopt) the per-sensor estimate with
// these noise fallbacks for samples that carry no σ.
std::unique_ptr<RegionalFieldSource> MakeRegionalFieldSource(const std::string& service,
                                                             const std::optional<Eigen::Vector3d>& given,
                                                             double sigma_B_fallback, double sigma_T_fallback);

}  // namespace magnav::dds
