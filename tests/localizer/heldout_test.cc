// Held-out check of the default options: a scenario they were not tuned on
// (another vessel moment, speed, depth, pattern, sensor layout, GNSS and
// deployment noise), simulated with core's scenario simulator (the dipole
// forward model and coordinated turn of core/), several noise draws. The
// covariance is checked by NEES over all draws (one draw's NEES is dominated
// by its common shift, so the reference pass alone cannot check it well).
// Figures: docs/ACCURACY.md "Localizer, held out".
#include <Eigen/Cholesky>
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "magnav/core/simulate.h"
#include "magnav/localizer/batch.h"
#include "magnav/localizer/ekf.h"
#include "racetrack.h"

namespace magnav::localizer {
namespace {

using Draw = test::Racetrack;  // a pass and its true sensors

Draw Simulate(std::uint64_t seed) {
  PassScenario sc;
  sc.moment_body = {-15000.0, 5000.0, 20000.0};
  sc.start_position = {-120.0, -60.0, 0.0};
  sc.speed_mps = 2.5;
  sc.start_heading_rad = 0.0;
  // Three legs north/south/north joined by half-turns (radius 25 m).
  sc.segments = {{100.0, 0.0}, {10.0 * M_PI, 0.1}, {100.0, 0.0}, {10.0 * M_PI, -0.1}, {100.0, 0.0}};
  sc.rate_hz = 2.0;
  sc.sensors = {{-80.0, -40.0, 25.0}, {0.0, -70.0, 25.0}, {70.0, -30.0, 25.0},
                {-40.0, 15.0, 25.0},  {40.0, 20.0, 25.0}, {100.0, 60.0, 25.0}};
  return test::PassFromScenario(sc, std::numeric_limits<double>::infinity(), seed);
}

TEST(LocalizerHeldOut, DefaultsReachTheBoundAndTheirCovarianceHoldsOverDraws) {
  constexpr int kDraws = 6;
  const LocalizerOptions opt;
  double nees[2] = {0, 0}, se[2] = {0, 0}, crlb[2] = {0, 0}, deploy = 0;
  int sensors = 0;
  for (int r = 0; r < kDraws; ++r) {
    const Draw d = Simulate(100 + static_cast<std::uint64_t>(r));
    const Localization ekf = RunEkf(d.pass, opt);
    const Localization batch = SolveBatch(d.pass, opt, &ekf);
    ASSERT_TRUE(batch.summary.converged) << batch.summary.BriefReport() << " / " << ekf.summary.BriefReport();
    const Localization* l[2] = {&ekf, &batch};
    for (int m = 0; m < 2; ++m) {
      Eigen::VectorXd e(12);
      for (std::size_t j = 0; j < 6; ++j) {
        e.segment<2>(2 * static_cast<int>(j)) = l[m]->sensors[j].p_SinW_m.head<2>() - d.truth[j];
        crlb[m] += l[m]->sensors[j].crlb_joint_m2.trace();
      }
      se[m] += e.squaredNorm();
      nees[m] += e.dot(l[m]->cov_sensors_m2.ldlt().solve(e)) / kDraws;
    }
    for (std::size_t j = 0; j < 6; ++j) deploy += (d.pass.sensors[j].p_SinW_m.head<2>() - d.truth[j]).squaredNorm();
    sensors += 6;
  }
  for (int m = 0; m < 2; ++m) {
    SCOPED_TRACE(m == 0 ? "ekf" : "batch");
    const double rmse = std::sqrt(se[m] / sensors), rms_crlb = std::sqrt(crlb[m] / sensors);
    RecordProperty(m == 0 ? "ekf_rmse_m" : "batch_rmse_m", std::to_string(rmse));
    RecordProperty(m == 0 ? "ekf_nees12" : "batch_nees12", std::to_string(nees[m]));
    RecordProperty(m == 0 ? "ekf_rms_crlb_m" : "batch_rms_crlb_m", std::to_string(rms_crlb));
    // Mean NEES of 12 dof over 6 draws: χ²₇₂/6, two-sided 99 % [7.57, 17.4].
    EXPECT_GT(nees[m], 7.57);
    EXPECT_LT(nees[m], 17.4);
    EXPECT_LE(rmse, (m == 0 ? 3.0 : 2.0) * rms_crlb);  // the targets
    EXPECT_LE(rmse, 1.4 * rms_crlb);  // measured 0.94 × (ekf and batch): a 2× regression breaks this
    EXPECT_GE(std::sqrt(deploy / sensors) / rmse, 10.0);
  }
}

}  // namespace
}  // namespace magnav::localizer
