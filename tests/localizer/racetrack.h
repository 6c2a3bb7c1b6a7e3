// A long survey for the bounded-localizer checks (tests and bench): the
// held-out field of heldout_test.cc (moment (−15000, 5000, 20000) A·m²,
// 2.5 m/s, 6 sensors at 25 m depth, 2 Hz, 1 nT, GNSS σ 2 m at 1 Hz,
// deployment σ 10 m), flown as a racetrack over it — 200 s legs north and
// south, half-turns of radius 50 m — repeated for `duration_s` of data.
// Simulated with core's scenario simulator (core/simulate.h), not the
// localizer's models.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "magnav/core/simulate.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer::test {

struct Racetrack {
  Pass pass;
  std::vector<Eigen::Vector2d> truth;  // sensor (x, y), pass.sensors order
};

// The localizer's pass from a simulated scenario (no B0, 1 nT): the
// magnetometer samples, GNSS fixes at 1 Hz with σ = 2 m, and deployment
// guesses 10 m (1σ) off the true sensors; up to `duration_s` of data.
inline Racetrack PassFromScenario(PassScenario sc, double duration_s, std::uint64_t seed) {
  sc.B0 = Eigen::Vector3d::Zero();
  sc.sigma_B = 1e-9;
  sc.seed = seed;
  const SimulatedPass sim = SimulatePass(sc);
  Racetrack d;
  d.pass.vessel = {sc.moment_body, 0.0};
  std::mt19937_64 rng(seed * 7919 + 11);
  std::normal_distribution<double> n(0.0, 1.0);
  for (std::size_t j = 0; j < sc.sensors.size(); ++j) {
    d.truth.push_back(sc.sensors[j].head<2>());
    const Eigen::Vector3d guess(sc.sensors[j].x() + 10.0 * n(rng), sc.sensors[j].y() + 10.0 * n(rng), 25.0);
    d.pass.sensors.push_back({static_cast<std::uint32_t>(j), guess, 10.0});
  }
  for (const auto& s : sim.samples) {
    if (s.t_s > duration_s) break;
    d.pass.samples.push_back({s.t_s, s.sensor_id, s.B});
  }
  for (const auto& v : sim.truth) {
    if (v.t_s > duration_s) break;
    if (std::abs(v.t_s - std::round(v.t_s)) < 1e-9) {  // GNSS at 1 Hz, σ = 2 m
      d.pass.gnss.push_back({v.t_s, v.p_VinW.head<2>() + 2.0 * Eigen::Vector2d(n(rng), n(rng)), 2.0});
    }
  }
  return d;
}

inline Racetrack SimulateRacetrack(double duration_s, std::uint64_t seed = 100) {
  PassScenario sc;
  sc.moment_body = {-15000.0, 5000.0, 20000.0};
  sc.start_position = {-250.0, -60.0, 0.0};
  sc.speed_mps = 2.5;
  sc.start_heading_rad = 0.0;
  const double loop_s = 2.0 * 200.0 + 2.0 * 20.0 * M_PI;  // two legs, two half-turns at 0.05 rad/s
  for (double t = 0.0; t < duration_s; t += loop_s) {
    for (const TurnSegment& s : {TurnSegment{200.0, 0.0}, TurnSegment{20.0 * M_PI, 0.05}, TurnSegment{200.0, 0.0},
                                 TurnSegment{20.0 * M_PI, 0.05}}) {
      sc.segments.push_back(s);
    }
  }
  sc.segments.erase(sc.segments.begin(), sc.segments.begin() + 3);  // the defaults
  sc.rate_hz = 2.0;
  sc.sensors = {{-80.0, -40.0, 25.0}, {0.0, -70.0, 25.0}, {70.0, -30.0, 25.0},
                {-40.0, 15.0, 25.0},  {40.0, 20.0, 25.0}, {100.0, 30.0, 25.0}};
  return PassFromScenario(sc, duration_s, seed);
}

}  // namespace magnav::localizer::test
