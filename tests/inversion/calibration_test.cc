// Covariance calibration of the inverter's single-sample fix over
// independent runs (issue 25 item 4; scripts/calibration, docs/ACCURACY.md
// "Calibration"): the first runs of two committed scenarios of
// scripts/calibration_scenarios/scenarios.csv (auv_squid seeds 1001..,
// auv_fluxgate seeds 1101..: the reference AUV pass geometry, new noise),
// TED+EGT with the default gates, NEES eᵀP⁻¹e of every valid fix (3 dof).
// Asserted: ANEES within the acceptance [0.5, 2] × 3, and at least 80 % of
// the epochs with the run-averaged NEES inside its two-sided 95 % χ²
// interval (95 % expected). The same fixes with every σ doubled or halved
// (P × 4 or ÷ 4) must fail both checks: the test can fail.
#include <gtest/gtest.h>

#include <cstdio>

#include <Eigen/Cholesky>

#include "magnav/core/nees.h"
#include "magnav/core/simulate.h"
#include "magnav/inversion/inverter.h"

namespace magnav::inversion {
namespace {

struct Scenario {
  const char* name;
  double sigma_B, sigma_T;  // magnav simulate --noise squid | fluxgate
  std::uint64_t first_seed;
  std::size_t min_fixes_per_run;
};

constexpr int kRuns = 6;

// NEES rows of kRuns runs.
std::vector<NeesSample> NeesRows(const Scenario& s) {
  std::vector<NeesSample> out;
  for (int r = 0; r < kRuns; ++r) {
    PassScenario sc;  // the reference AUV pass
    sc.sigma_B = s.sigma_B;
    sc.sigma_T = s.sigma_T;
    sc.seed = s.first_seed + static_cast<std::uint64_t>(r);
    const SimulatedPass pass = SimulatePass(sc);
    InverterOptions o;
    o.B0_W = sc.B0;
    EXPECT_TRUE(ParseMethod("ted-egt", &o.method));
    Inverter inv(o);
    std::size_t fixes = 0;
    for (std::size_t i = 0; i < pass.samples.size(); ++i) {
      const DipoleFix fix = inv.Process(pass.samples[i]);
      if (!fix.valid) continue;
      ++fixes;
      const Vec3 e = fix.p_DinW - pass.truth[i].p_VinW;
      out.push_back({r, static_cast<long long>(i), "fix", e.dot(fix.cov_p_DinW.ldlt().solve(e)), e.squaredNorm()});
    }
    EXPECT_GE(fixes, s.min_fixes_per_run) << s.name << " seed " << sc.seed;
  }
  return out;
}

class InverterCalibration : public ::testing::TestWithParam<Scenario> {};

TEST_P(InverterCalibration, AneesAndEpochShareHoldAndFailWithSigmaScaledByTwo) {
  const Scenario& s = GetParam();
  const std::vector<NeesSample> rows = NeesRows(s);
  const NeesRegimeStats st = ComputeNeesStats(rows, 3).at("fix");
  std::printf("%s: %d runs, %zu fixes, RMS %.4g m, ANEES %.3f (3 dof), epochs inside 95 %%: %zu of %zu\n", s.name,
              kRuns, st.samples, st.rms, st.anees, st.epochs_inside, st.epochs_tested);
  EXPECT_TRUE(st.anees_accepted) << st.anees;
  EXPECT_GE(st.share_inside(), 0.80);
  for (const double scale : {4.0, 0.25}) {  // σ × 2, σ ÷ 2: P × 4 or ÷ 4, NEES ÷ 4 or × 4
    std::vector<NeesSample> scaled = rows;
    for (NeesSample& x : scaled) x.nees /= scale;
    const NeesRegimeStats bad = ComputeNeesStats(scaled, 3).at("fix");
    EXPECT_FALSE(bad.anees_accepted) << "P x " << scale << ": ANEES " << bad.anees;
    EXPECT_LT(bad.share_inside(), 0.80) << "P x " << scale;
  }
}

INSTANTIATE_TEST_SUITE_P(Scenarios, InverterCalibration,
                         ::testing::Values(Scenario{"auv_squid", 1e-13, 1e-13, 1001, 1000},
                                           Scenario{"auv_fluxgate", 1e-9, 1.4e-9, 1101, 60}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace magnav::inversion
