#include "reference_truth.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "test_data.h"

namespace magnav::testing {

TruthTrack LoadTruthTrack(const std::string& vessel) {
  const CsvTable c = CsvTable::Read(ReferencePath("track_truth_" + vessel + ".csv"));
  TruthTrack out;
  for (std::size_t i = 0; i < c.num_rows(); ++i) {
    out.t.push_back(c.number(i, c.column("t")));
    out.p.emplace_back(c.number(i, c.column("x")), c.number(i, c.column("y")), c.number(i, c.column("z")));
    out.heading.push_back(c.number(i, c.column("heading")));
  }
  return out;
}

TruthTrack TruthOf(const SimulatedPass& pass) {
  TruthTrack out;
  for (const VesselTruth& v : pass.truth) {
    out.t.push_back(v.t_s);
    out.p.push_back(v.p_VinW);
    out.heading.push_back(v.heading_rad);
  }
  return out;
}

void ErrorStats::Add(double e) {
  ++count;
  sum_sq += e * e;
  max = std::max(max, e);
}

double ErrorStats::rms() const { return count ? std::sqrt(sum_sq / count) : std::nan(""); }

void ExpectErrorFigure(double measured, double documented, const std::string& what) {
  EXPECT_LE(measured, kFigureMargin * documented)
      << what << ": measured " << measured << ", docs/ACCURACY.md says " << documented;
}

void ExpectCountFigure(double measured, double documented, const std::string& what, double margin) {
  EXPECT_GE(measured, documented / margin)
      << what << ": measured " << measured << ", docs/ACCURACY.md says " << documented;
}

std::vector<HeldOutPass> HeldOutPasses() {
  // Neither reference vessel's moment, heading (0.7 rad), closest approach
  // (4 m / 11 m) nor noise draws; one turns left.
  return {
      {"auv-like, 5 m, left turn", {1500.0, -400.0, 1000.0}, -2.0, 5.0, -0.02, 7},
      {"auv-like, 4 m", {1800.0, -1000.0, 900.0}, 2.0, -4.0, 0.02, 5},
      {"ship-like, 8 m", {300000.0, -80000.0, 150000.0}, 2.5, -8.0, 0.02, 11},
  };
}

PassScenario HeldOutScenario(const HeldOutPass& pass, double sigma_B, double sigma_T) {
  PassScenario sc;
  sc.moment_body = pass.moment_body;
  sc.start_heading_rad = pass.heading_rad;
  sc.speed_mps = 1.0;
  const Eigen::Vector3d v(std::cos(pass.heading_rad), std::sin(pass.heading_rad), 0.0);
  const Eigen::Vector3d left(std::sin(pass.heading_rad), -std::cos(pass.heading_rad), 0.0);
  // At t = 75 s (first, straight segment) the vessel is `closest_m` to the
  // left of the sensor at the origin (to the right if negative), 5 m above it.
  const Eigen::Vector3d closest = pass.closest_m * left + Eigen::Vector3d(0.0, 0.0, -5.0);
  sc.start_position = closest - 75.0 * sc.speed_mps * v;
  sc.segments = {{80.0, 0.0}, {60.0, pass.turn_rps}, {60.0, 0.0}};
  sc.sigma_B = sigma_B;
  sc.sigma_T = sigma_T;
  sc.seed = pass.seed;
  return sc;
}

}  // namespace magnav::testing
