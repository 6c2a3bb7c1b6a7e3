// The a-posteriori variance factor of the window (tracker/variance_factor.h;
// issue 24 item 6; docs/ACCURACY.md, "The a-posteriori variance factor"):
// the factor alone against the χ² quantile, and on the held-out overtaking
// (heldout/overtaking.toml, shortened to its first 60 s, fixed seed): the
// slow vessel's rows before the fast one is tracked carry the fast one's
// untracked field; the factor makes their σ say so (the window inside
// ANEES over 20 draws 59.3 → 2.70), and leaves the same vessel's σ alone
// when it is the only one in the field. This geometry was looked at for the
// change (not blind); fresh_sigma/ and fresh_sigma2/ are the blind checks.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <cstdio>
#include <string>

#include "magnav/cli/scenario_file.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/variance_factor.h"
#include "test_data.h"
#include "two_vessels.h"

namespace magnav::tracker {
namespace {

VarianceFactorOptions On() {
  VarianceFactorOptions o;
  o.enabled = true;
  return o;
}
VarianceFactorOptions Off() {
  VarianceFactorOptions o;
  o.enabled = false;
  return o;
}

TEST(VarianceFactor, OneUnlessTheFitIsPoorerThanChanceAllows) {
  // χ²(800) 0.99 quantile ≈ 894.4: s² = 1.10 is below it, 1.2 above.
  EXPECT_EQ(VarianceFactor(880.0, 800.0, On()), 1.0);
  EXPECT_NEAR(VarianceFactor(960.0, 800.0, On()), 1.2, 1e-12);
  EXPECT_NEAR(VarianceFactor(8.0e4, 800.0, On()), 100.0, 1e-9);
  // Never below 1, off means 1, capped, and nothing from no dof.
  EXPECT_EQ(VarianceFactor(100.0, 800.0, On()), 1.0);
  EXPECT_EQ(VarianceFactor(960.0, 800.0, Off()), 1.0);
  VarianceFactorOptions capped = On();
  capped.max_factor = 10.0;
  EXPECT_EQ(VarianceFactor(8.0e4, 800.0, capped), 10.0);
  EXPECT_EQ(VarianceFactor(960.0, 0.0, On()), 1.0);
  // The quantile is the bar: at 0.5 a fit only a little poor already counts.
  VarianceFactorOptions median = On();
  median.quantile = 0.5;
  EXPECT_NEAR(VarianceFactor(880.0, 800.0, median), 1.1, 1e-12);
}

TEST(VarianceFactor, WindowFactorFromTheSummary) {
  Summary s;
  s.usable = true;
  s.num_samples = 100;     // dof 800
  s.final_cost = 480.0;    // χ² 960
  EXPECT_NEAR(WindowVarianceFactor(s, On()), 1.2, 1e-12);
  s.usable = false;
  EXPECT_EQ(WindowVarianceFactor(s, On()), 1.0);
}

TEST(VarianceFactor, OptionsAreChecked) {
  std::string why;
  EXPECT_TRUE(VarianceFactorOptions{}.IsValid(&why));
  EXPECT_TRUE(VarianceFactorOptions{}.enabled);
  EXPECT_EQ(VarianceFactorOptions{}.statistic, VarianceFactorOptions::Statistic::kSensorMeans);
  VarianceFactorOptions o;
  o.quantile = 1.0;
  EXPECT_FALSE(o.IsValid(&why));
  o = VarianceFactorOptions{};
  o.max_factor = 0.5;
  EXPECT_FALSE(o.IsValid(&why));
  MultiTrackerOptions m;
  m.variance_factor.quantile = 0.0;
  EXPECT_FALSE(m.IsValid(&why));
}

// heldout/overtaking.toml (slow AUV 1 at 0.8 m/s from x = −60 m, fast AUV 2
// at 1.8 m/s from −110 m, 8 m apart; level at 50 s), its first 60 s.
FieldScenario Overtaking60() {
  FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                           "/generated/scenarios/heldout/overtaking.toml");
  for (auto& v : sc.vessels) v.segments = {{60.0, 0.0}};
  return sc;
}

struct EarlyRows {
  double anees = 0.0;       // mean 3-dof position NEES of vessel 1's rows up to t_until_s
  double sigma2 = 0.0;      // their mean trace of the position covariance, m²
  int n = 0;
};

// The window rows (MultiTracker, default options but the factor) nearest
// vessel 1 (within 5 m) up to t_until_s.
EarlyRows Vessel1Rows(const FieldScenario& sc, const MultiTrackerOptions& options, double t_until_s) {
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, options);
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  EarlyRows r;
  for (const auto& [id, e] : rows) {
    if (!e.usable || !e.has_covariance || e.t_s > t_until_s) continue;
    const long long k = std::llround(e.t_s * sc.rate_hz);
    const VesselTruth* mine = nullptr;
    double best = 5.0;
    for (std::size_t v = 0; v < f.truth.size(); ++v) {
      for (const auto& q : f.truth[v]) {
        if (std::llround(q.t_s * sc.rate_hz) != k) continue;
        const double d = (e.p_VinW - q.p_VinW).norm();
        if (d <= best) {
          best = d;
          mine = v == 0 ? &q : nullptr;
        }
      }
    }
    if (mine == nullptr) continue;
    const Eigen::Vector3d err = e.p_VinW - mine->p_VinW;
    const Eigen::Matrix3d P = e.cov_state.topLeftCorner<3, 3>();
    r.anees += err.dot(P.ldlt().solve(err));
    r.sigma2 += P.trace();
    ++r.n;
  }
  if (r.n > 0) {
    r.anees /= r.n;
    r.sigma2 /= r.n;
  }
  return r;
}

TEST(VarianceFactor, SlowVesselBeforeTheFastOneIsTrackedIsNoLongerOverconfident) {
  const FieldScenario sc = Overtaking60();
  MultiTrackerOptions off;
  off.variance_factor = Off();
  MultiTrackerOptions on;  // the default: on, kSensorMeans, 0.99
  ASSERT_TRUE(on.variance_factor.enabled);
  const EarlyRows a = Vessel1Rows(sc, off, 40.0);
  const EarlyRows b = Vessel1Rows(sc, on, 40.0);
  std::printf("overtaking, vessel 1's window rows to 40 s: %d / %d rows, ANEES %.3g -> %.3g, mean tr P %.3g -> %.3g m^2\n",
              a.n, b.n, a.anees, b.anees, a.sigma2, b.sigma2);
  ASSERT_GT(a.n, 50);
  EXPECT_EQ(a.n, b.n);  // the factor changes σ only, not which rows there are
  EXPECT_GT(a.anees, 50.0);  // without it: overconfident (the failing cell's rows)
  // Measured 7.36 (397 without the factor; 241 with kResiduals' white χ²,
  // measured once, not asserted):
  // held within 1.5x either way, so that a factor half or twice as large fails.
  EXPECT_LE(b.anees, 1.5 * 7.36);
  EXPECT_GE(b.anees, 7.36 / 1.5);
}

TEST(VarianceFactor, LeavesALoneVesselsSigmaAlone) {
  FieldScenario sc = Overtaking60();
  sc.vessels.resize(1);  // the slow vessel alone: nothing unmodelled in its samples
  MultiTrackerOptions off;
  off.variance_factor = Off();
  MultiTrackerOptions on;  // the default: on, kSensorMeans, 0.99
  ASSERT_TRUE(on.variance_factor.enabled);
  const EarlyRows a = Vessel1Rows(sc, off, 60.0);
  const EarlyRows b = Vessel1Rows(sc, on, 60.0);
  std::printf("the slow vessel alone, window rows to 60 s: %d rows, mean tr P %.4g -> %.4g m^2 (ANEES %.3g -> %.3g)\n",
              a.n, a.sigma2, b.sigma2, a.anees, b.anees);
  ASSERT_GT(a.n, 100);
  // Measured: the factor is 1 on every row (tr P 0.001224 m² both ways).
  EXPECT_LE(b.sigma2, 1.05 * a.sigma2);
  EXPECT_EQ(a.n, b.n);
}

}  // namespace
}  // namespace magnav::tracker
