// DipoleFix covariances mean what they say: cov_p_DinW is the covariance of
// the fix's position (m², per axis, not a 3-D RMS on every diagonal entry),
// checked against the independent reference truth over the accepted fixes:
// mean |e|² / mean trace(cov) within [0.5, 2] (1 when calibrated), and the
// per-axis NEES (|e|² in the covariance's metric) near 3. And a Monte-Carlo
// fix is valid only when its filter was updated by the sample.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include <Eigen/Cholesky>

#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "magnav/inversion/inverter.h"
#include "magnav/inversion/particle_filter.h"
#include "reference_truth.h"
#include "test_data.h"

namespace magnav::inversion {
namespace {

struct Calibration {
  int n = 0;
  double sum_e2 = 0.0, sum_trace = 0.0, sum_nees = 0.0;
  void Add(const Vec3& e, const Mat3& cov) {
    ++n;
    sum_e2 += e.squaredNorm();
    sum_trace += cov.trace();
    sum_nees += e.dot(cov.ldlt().solve(e));
  }
  double ratio() const { return sum_e2 / sum_trace; }
  double nees() const { return sum_nees / n; }
};

std::vector<Vec3> TruthPositions(const std::string& vessel) { return testing::LoadTruthTrack(vessel).p; }

class AnalyticCovariance : public ::testing::TestWithParam<const char*> {};

// TED+EGT with the default gates. Before the fix the published covariance
// put the 3-D RMS σ² on every diagonal entry: trace 3× too large, ratio ≈ 1/3.
TEST_P(AnalyticCovariance, IsCalibratedOnTheReferencePass) {
  const std::string name = GetParam();
  const std::string vessel = name.substr(0, name.find('_'));
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_" + name + ".csv"));
  const std::vector<Vec3> truth = TruthPositions(vessel);
  InverterOptions o;
  o.B0_W = *f.B0;
  Inverter inv(o);
  Calibration c;
  for (std::size_t i = 0; i < f.samples.size(); ++i) {
    const DipoleFix fix = inv.Process(f.samples[i]);
    if (!fix.valid) continue;
    ASSERT_TRUE(fix.cov_p_DinW.allFinite());
    EXPECT_NEAR(std::sqrt(fix.cov_p_DinW.trace()), fix.position_sigma_3d_m, 1e-12);
    c.Add(fix.p_DinW - truth[i], fix.cov_p_DinW);
  }
  std::printf("%s: %d fixes, mean |e|^2 / mean trace %.3f, mean NEES %.2f (3 dof)\n", name.c_str(), c.n, c.ratio(),
              c.nees());
  ASSERT_GE(c.n, 30);
  EXPECT_GE(c.ratio(), 0.5);
  EXPECT_LE(c.ratio(), 2.0);
}

INSTANTIATE_TEST_SUITE_P(Passes, AnalyticCovariance,
                         ::testing::Values("auv_1sensor_squid", "ship_1sensor_squid", "ship_1sensor_fluxgate"));

// Monte-Carlo: the particles' weighted covariance, over the fixes within 30 m
// horizontal range (where the filter tracks). It is NOT calibrated: the cloud
// is kept wider than the error by the position random walk (0.1 m/√s) and
// the 1 % model error that let it follow the turn (docs/ACCURACY.md), so the
// trace overstates the squared error ≈ 5× (σ ≈ 2.2× too large): a
// conservative covariance. Asserted as measured (0.21), so that a change
// either way is seen.
TEST(MonteCarloCovariance, IsCalibratedOnTheShipFluxgatePass) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  const std::vector<Vec3> truth = TruthPositions("ship");
  MonteCarloTrackerOptions mc;
  mc.filter.moment_body_Am2 = *f.moment_body;
  mc.init_inverter.B0_W = *f.B0;
  MonteCarloTracker tracker(mc);
  Calibration c;
  for (std::size_t i = 0; i < f.samples.size(); ++i) {
    const DipoleFix fix = tracker.Process(f.samples[i]);
    if (!fix.valid || truth[i].head<2>().norm() > 30.0) continue;
    c.Add(fix.p_DinW - truth[i], fix.cov_p_DinW);
  }
  std::printf("MC ship fluxgate: %d fixes, mean |e|^2 / mean trace %.3f\n", c.n, c.ratio());
  ASSERT_GE(c.n, 300);
  EXPECT_GE(c.ratio(), 0.12);
  EXPECT_LE(c.ratio(), 0.4);
}

// σ_T unknown (the samples carry 0 and no fallback is set): the filter cannot
// weigh a sample, so no fix is valid — before, 1996 of 2001 were.
TEST(MonteCarloValidity, NoValidFixWithoutTheTensorNoise) {
  GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  MonteCarloTrackerOptions mc;
  mc.filter.moment_body_Am2 = *f.moment_body;
  mc.init_inverter.B0_W = *f.B0;
  mc.init_inverter.sigma_B_fallback = 1e-9;  // the initialiser still gets its fixes
  mc.init_inverter.sigma_T_fallback = 1.4e-9;
  MonteCarloTracker tracker(mc);
  int valid = 0, unknown_sigma = 0;
  for (auto s : f.samples) {
    s.sigma_T = 0.0;
    const DipoleFix fix = tracker.Process(s);
    valid += fix.valid ? 1 : 0;
    unknown_sigma += fix.reason == RejectReason::kUnknownSigma ? 1 : 0;
  }
  EXPECT_EQ(valid, 0);
  EXPECT_GT(unknown_sigma, 500);  // every sample once the filter has started
}

}  // namespace
}  // namespace magnav::inversion
