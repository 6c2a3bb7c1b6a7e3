// Shared pieces of the accuracy tests (docs/ACCURACY.md): the reference truth
// tracks, position-error statistics, the assertion of a documented figure, and
// held-out simulated passes (scenarios the defaults were not tuned on).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "magnav/core/simulate.h"

namespace magnav::testing {

// True vessel track at the sample instants (one row per instant).
struct TruthTrack {
  std::vector<double> t;
  std::vector<Eigen::Vector3d> p;  // vessel = dipole position, NED, m
  std::vector<double> heading;     // rad
};

// tests/data/reference/track_truth_<vessel>.csv (vessel "auv" or "ship").
TruthTrack LoadTruthTrack(const std::string& vessel);
// The truth of a simulated pass.
TruthTrack TruthOf(const SimulatedPass& pass);

// RMS / max of 3-D position errors.
struct ErrorStats {
  int count = 0;
  double sum_sq = 0.0, max = 0.0;
  void Add(double e);
  double rms() const;  // NaN when empty
};

// A documented figure may regress by at most this factor before its test
// fails: a 2× regression always does, float and platform noise never should.
inline constexpr double kFigureMargin = 1.5;

// Asserts an error figure of docs/ACCURACY.md: measured ≤ kFigureMargin × documented.
void ExpectErrorFigure(double measured, double documented, const std::string& what);
// Asserts a count or coverage figure: measured ≥ documented / margin.
void ExpectCountFigure(double measured, double documented, const std::string& what,
                       double margin = kFigureMargin);

// A held-out pass: the reference scenario shape (5 m above the sensor plane,
// 1 m/s, 80 s straight / 60 s turn / 60 s straight, 10 Hz, one sensor at the
// origin) with its own moment, heading, closest approach, turn direction and
// noise seed. The closest approach (horizontal `closest_m`) is at t = 75 s.
struct HeldOutPass {
  std::string name;
  Eigen::Vector3d moment_body;
  double heading_rad = 0.0;
  double closest_m = 0.0;   // horizontal distance at t = 75 s, m (sensor on the left if > 0)
  double turn_rps = 0.02;   // second segment
  std::uint64_t seed = 1;
};
// The held-out passes used by the inversion and tracker tests.
std::vector<HeldOutPass> HeldOutPasses();
// Scenario of a held-out pass with the given noise (fluxgate: 1e-9 T,
// 1.4e-9 T/m; SQUID: 1e-13, 1e-13).
PassScenario HeldOutScenario(const HeldOutPass& pass, double sigma_B, double sigma_T);

inline constexpr double kFluxgateSigmaB = 1e-9, kFluxgateSigmaT = 1.4e-9;
inline constexpr double kSquidSigmaB = 1e-13, kSquidSigmaT = 1e-13;

}  // namespace magnav::testing
