// Running the inverter and the Monte-Carlo tracker over a 1-sensor pass and
// scoring them against its truth (the track-pass and held-out tests).
#pragma once

#include <cstdint>
#include <vector>

#include "magnav/core/gradiometer.h"
#include "magnav/inversion/inverter.h"
#include "reference_truth.h"

namespace magnav::inversion::testing {

inline constexpr double kMcHorizontalRange = 30.0;  // m, MC evaluation window

// Errors of every fix an Inverter with these options accepts.
magnav::testing::ErrorStats RunInverter(const std::vector<GradiometerSample>& samples,
                                        const magnav::testing::TruthTrack& truth, const InverterOptions& options);
// TED+EGT options with B0 and the uncertainty gates set (relative to range,
// absolute in m; 0 = off), the weak-signal gate at SNR 100 (its default until
// 2026-11-25, with which the sweeps of docs/ACCURACY.md "Uncertainty gate" were
// measured), every other gate at default.
InverterOptions SigmaGateOptions(const Eigen::Vector3d& B0, double relative, double absolute);
// RunInverter's errors for `samples_per_instant` samples (sensors) per truth
// row, and the largest |error| / range of an accepted fix.
struct RangeErrors {
  magnav::testing::ErrorStats err;
  double max_relative = 0.0;
};
RangeErrors RunInverterWithRange(const std::vector<GradiometerSample>& samples,
                                 const magnav::testing::TruthTrack& truth, const InverterOptions& options,
                                 std::size_t samples_per_instant = 1);
// The same with the default gates (`method`, B0 given).
magnav::testing::ErrorStats RunInverter(const std::vector<GradiometerSample>& samples,
                                        const magnav::testing::TruthTrack& truth, const Eigen::Vector3d& B0,
                                        Method method);

// MC (default options, this seed) over the epochs within kMcHorizontalRange
// horizontally of the sensor; samples[i] belongs to truth row i.
struct McRun {
  magnav::testing::ErrorStats err;  // epochs with an estimate
  int epochs = 0;                   // epochs in the window
};
McRun RunMonteCarlo(const std::vector<GradiometerSample>& samples, const magnav::testing::TruthTrack& truth,
                    const Eigen::Vector3d& B0, const Eigen::Vector3d& moment_body, std::uint64_t seed);

}  // namespace magnav::inversion::testing
