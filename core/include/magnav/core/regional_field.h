// Running estimate of the regional (background, Earth) field B0 of each
// gradiometer from its own stream, for services that are not told B0.
//
// Frames and units: B in tesla, sensor axes = world NED (as every sample);
// T in tesla per metre; time in seconds.
//
// A sensor's B0 is the mean of B over its latest QUIET stretch: window_s of
// samples (at least min_samples) over which
//   * the tensor is at noise level: RMS of ‖T‖_F ≤ max_tensor_rms_sigmas · σ_T
//     (noise alone gives ≈ 3 σ_T for 9 elements of σ_T each), and
//   * B is stationary: the standard deviation of each axis ≤
//     max_field_std_sigmas · σ_B (noise alone gives σ_B), and the means of
//     the stretch's two halves differ by at most max_drift_sigmas standard
//     errors of their difference (2 σ_B/√n) on every axis.
// Of the quiet stretches the FIRST gives the estimate; a later one replaces
// it only refresh_after_s later (to follow the slow daily variation of the
// Earth field): a stretch closer to a passing vessel is never preferred to an
// earlier, farther one. A vessel near the sensor fails the first test; a vessel farther away that
// still adds a field moves, so its field changes and fails the second (at
// 1 m/s a dipole field of |b| at range r changes by ≈ 3|b|/r per second). A
// magnetic object that does not move is indistinguishable from background.
// The estimate's 1-σ error per axis is σ_B/√n (n samples of the stretch).
// Without σ_B and σ_T (samples carry 0 and no fallback is set) no stretch can
// be judged quiet and no estimate is made (Status::kUnknownSigma).
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <unordered_map>

#include <Eigen/Core>

#include "magnav/core/gradiometer.h"

namespace magnav {

struct RegionalFieldOptions {
  double window_s = 10.0;             // length of a quiet stretch, s
  int min_samples = 50;               // samples a stretch needs at least
  double max_tensor_rms_sigmas = 4.5;  // quiet: RMS ‖T‖_F ≤ this · σ_T
  double max_field_std_sigmas = 1.5;   // quiet: std of each B axis ≤ this · σ_B
  double max_drift_sigmas = 3.0;       // quiet: halves' means differ ≤ this · 2σ_B/√n
  double refresh_after_s = 600.0;      // a newer quiet stretch replaces the estimate after this, s
  double sigma_B_fallback = 0.0;       // T, for samples that carry sigma_B = 0
  double sigma_T_fallback = 0.0;       // T/m, for samples that carry sigma_T = 0

  bool IsValid(std::string* error) const;
};

class RegionalFieldEstimator {
 public:
  enum class Status {
    kNotReady,      // no quiet stretch seen yet for this sensor
    kBecameReady,   // this sample completed the sensor's first quiet stretch
    kReady,         // the sensor has an estimate (possibly just refreshed)
    kUnknownSigma,  // σ_B or σ_T unknown: quiet cannot be judged
    kBadSample,     // CheckSample failed: the sample was not used
  };

  // Throws InputError if the options are invalid.
  explicit RegionalFieldEstimator(const RegionalFieldOptions& options);

  // Feeds one sample of any sensor (non-decreasing time per sensor; an older
  // sample restarts that sensor's stretch).
  Status Add(const GradiometerSample& sample);
  // The sensor's current estimate (T, NED), if any.
  std::optional<Eigen::Vector3d> B0(std::uint32_t sensor_id) const;
  // Samples in the stretch the current estimate came from (0 = none).
  int num_samples(std::uint32_t sensor_id) const;

 private:
  struct Entry {
    double t_s;
    Eigen::Vector3d B;
    double t_norm_sq;
  };
  struct Sensor {
    std::deque<Entry> window;
    std::optional<Eigen::Vector3d> B0;
    double t_estimate_s = 0.0;  // end of the stretch the estimate came from
    int n = 0;
  };
  RegionalFieldOptions options_;
  std::unordered_map<std::uint32_t, Sensor> sensors_;
};

}  // namespace magnav
