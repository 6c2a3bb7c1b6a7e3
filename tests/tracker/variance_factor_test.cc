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
#include <limits>
#include <random>
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

// The batch's factor per epoch (SlidingVarianceFactors): white residuals
// give 1 everywhere; a bias at one sensor during 20-40 s scales the epochs
// whose ±10 s span holds it, not those far from it; a single wild sample is
// clipped and scales nothing.
TEST(BatchVarianceFactor, EpochsScaleWhereTheResidualsAroundThemSaySo) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  std::vector<WhitenedResidual> r;
  std::vector<double> times;
  for (int k = 0; k < 600; ++k) {  // 60 s at 10 Hz, 9 sensors
    times.push_back(0.1 * k);
    for (std::uint32_t j = 0; j < 9; ++j) {
      WhitenedResidual w;
      w.t_s = 0.1 * k;
      w.sensor_id = j;
      for (int i = 0; i < 8; ++i) w.e(i) = n01(rng);
      r.push_back(w);
    }
  }
  const VarianceFactorOptions on = On();
  const auto at = [&](const std::vector<double>& f, double t) { return f[static_cast<std::size_t>(std::lround(t / 0.1))]; };
  double pass = 0.0;
  std::vector<double> f = SlidingVarianceFactors(r, times, 20.0, 10.0, on, &pass);
  ASSERT_EQ(f.size(), times.size());
  // At the 0.99 point, about 1 epoch in 100 would scale by chance, but the
  // spans of neighbouring epochs overlap; this draw: none.
  int scaled = 0;
  for (double v : f) scaled += v > 1.0;
  std::printf("white residuals: %d of %zu epochs scaled\n", scaled, f.size());
  EXPECT_LE(scaled, 30);
  EXPECT_EQ(pass, 1.0);
  // One spike of 1e6 σ (a wild but finite sample that passed the door).
  std::vector<WhitenedResidual> spiked = r;
  spiked[100 * 9].e(0) = 1e6;  // t = 10 s
  const std::vector<double> g = SlidingVarianceFactors(spiked, times, 20.0, 10.0, on, &pass);
  EXPECT_EQ(at(g, 10.0), at(f, 10.0));
  EXPECT_LT(at(g, 10.0), 1.2);
  // Unclipped, the same spike would have scaled its neighbours by ~5e7.
  EXPECT_GT(at(SlidingVarianceFactors(spiked, times, 20.0, 1e12, on), 10.0), 1e3);
  // A bias of 0.5 σ on every residual of sensor 4 during 20-40 s: its mean
  // over 200 samples, n ||ē||² ≈ 200 · 8 · 0.25 = 400 against 72 dof.
  std::vector<WhitenedResidual> biased = r;
  for (auto& w : biased) {
    if (w.sensor_id == 4 && w.t_s >= 20.0 && w.t_s < 40.0) w.e.array() += 0.5;
  }
  f = SlidingVarianceFactors(biased, times, 20.0, 10.0, on, &pass);
  EXPECT_GT(at(f, 30.0), 4.0);  // (400 + 72) / 72 ≈ 6.6
  EXPECT_LT(at(f, 30.0), 9.0);
  EXPECT_EQ(at(f, 5.0), 1.0);   // its span ends at 15 s
  EXPECT_EQ(at(f, 55.0), 1.0);  // begins at 45 s
  EXPECT_GT(pass, 1.0);
  // Off: 1.
  f = SlidingVarianceFactors(biased, times, 20.0, 10.0, Off(), &pass);
  EXPECT_EQ(at(f, 30.0), 1.0);
  EXPECT_EQ(pass, 1.0);
}

TEST(BatchVarianceFactor, OptionsAreChecked) {
  std::string why;
  TrackerOptions t;
  EXPECT_TRUE(t.batch_variance_factor.enabled);  // on by default
  EXPECT_EQ(t.batch_variance_factor_span_s, 20.0);
  EXPECT_TRUE(t.batch_variance_factor_with_offsets);  // on top of solved offsets too
  EXPECT_TRUE(t.IsValid(&why)) << why;
  t.batch_variance_factor_span_s = 0.0;
  EXPECT_FALSE(t.IsValid(&why));
  t = TrackerOptions{};
  t.batch_variance_factor.quantile = 1.5;
  EXPECT_FALSE(t.IsValid(&why));
  MultiTrackerOptions m;
  EXPECT_EQ(m.batch_other_field_relative_error, MultiTrackerOptions::kOtherFieldRelativeError);
  m.batch_other_field_relative_error = -0.1;
  EXPECT_FALSE(m.IsValid(&why));
  EXPECT_NE(why.find("batch_other_field_relative_error"), std::string::npos);
  m.batch_other_field_relative_error = 0.02;
  EXPECT_TRUE(m.IsValid(&why)) << why;
}

// Batch rows of vessel 1 (within 5 m of it): mean 3-dof NEES and tr P.
EarlyRows BatchRowsOfVessel1(const FieldScenario& sc, const SimulatedField& f,
                             const std::vector<MultiTrackEstimate>& tracks) {
  EarlyRows r;
  for (const auto& [id, e] : magnav::testing::BatchRows(tracks)) {
    if (!e.has_covariance) continue;
    const long long k = std::llround(e.t_s * sc.rate_hz);
    for (const auto& q : f.truth[0]) {
      if (std::llround(q.t_s * sc.rate_hz) != k) continue;
      const Eigen::Vector3d err = e.p_VinW - q.p_VinW;
      if (err.norm() > 5.0) break;
      const Eigen::Matrix3d P = e.cov_state.topLeftCorner<3, 3>();
      r.anees += err.dot(P.ldlt().solve(err));
      r.sigma2 += P.trace();
      ++r.n;
      break;
    }
  }
  if (r.n > 0) {
    r.anees /= r.n;
    r.sigma2 /= r.n;
  }
  return r;
}

// The RMS of the batch rows within 5 m of vessel 1 (m).
double RmsOfVessel1(const FieldScenario& sc, const SimulatedField& f, const std::vector<MultiTrackEstimate>& tracks) {
  double sum = 0.0;
  int n = 0;
  for (const auto& [id, e] : magnav::testing::BatchRows(tracks)) {
    const long long k = std::llround(e.t_s * sc.rate_hz);
    for (const auto& q : f.truth[0]) {
      if (std::llround(q.t_s * sc.rate_hz) != k) continue;
      const double d = (e.p_VinW - q.p_VinW).norm();
      if (d <= 5.0) {
        sum += d * d;
        ++n;
      }
      break;
    }
  }
  return n > 0 ? std::sqrt(sum / n) : std::numeric_limits<double>::infinity();
}

// heldout/drift.toml: one AUV under a 4 nT/min per-sensor drift. The batch's
// estimate carries the drift's bias (RMS 0.39 m) while its σ, conditional on
// a fixed B0, says centimetres: mean NEES in the thousands. With the factor
// the same estimates carry a σ that says so; the same vessel without the
// drift keeps its σ. The factor's case is a field the batch does not model,
// so its runs have the batch's sensor offsets off. With the defaults
// (SensorOffsetOptions::batch and batch_score_test; docs/ACCURACY.md "The
// batch's sensor offsets, where its B residuals call for them") the B
// residuals of the solve without offsets call for them (χ² in the hundred
// thousands on ~150 dof), the offsets are solved and the drift's bias leaves
// the estimate, with a σ that has the offsets marginalised; without the
// drift the test does not fire and every estimate is the one without
// offsets, bit for bit.
TEST(BatchVarianceFactor, ABatchUnderADriftSaysSoTheOffsetsTakeItOutAndACleanOneIsLeftAlone) {
  FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                           "/generated/scenarios/heldout/drift.toml");
  MultiTrackerOptions off;
  off.track.batch_variance_factor.enabled = false;
  off.track.sensor_offset.batch = false;
  MultiTrackerOptions on;  // the default but the offsets
  on.track.sensor_offset.batch = false;
  ASSERT_TRUE(on.track.batch_variance_factor.enabled);
  {
    const SimulatedField f = SimulateField(sc);
    const auto epochs = GroupEpochs(f.samples, on.track.epoch_tolerance_s);
    const auto t_off = SolveBatchMulti(epochs, sc.B0, off);
    const auto t_on = SolveBatchMulti(epochs, sc.B0, on);
    const EarlyRows a = BatchRowsOfVessel1(sc, f, t_off), b = BatchRowsOfVessel1(sc, f, t_on);
    std::printf("drift, batch rows of vessel 1: %d / %d, ANEES %.4g -> %.4g, mean tr P %.3g -> %.3g m^2\n", a.n, b.n,
                a.anees, b.anees, a.sigma2, b.sigma2);
    ASSERT_GT(a.n, 500);
    EXPECT_EQ(a.n, b.n);
    ASSERT_EQ(t_off.size(), t_on.size());
    for (std::size_t i = 0; i < t_off.size(); ++i) {  // the estimates are the same
      ASSERT_EQ(t_off[i].track.epochs.size(), t_on[i].track.epochs.size());
      for (std::size_t k = 0; k < t_off[i].track.epochs.size(); ++k) {
        EXPECT_EQ(t_off[i].track.epochs[k].p_VinW, t_on[i].track.epochs[k].p_VinW);
      }
    }
    EXPECT_GT(a.anees, 100.0);  // overconfident without it
    // Measured 3.19 (1152 without; 3 dof): within [0.5, 2] x 3; a factor half
    // as large (ANEES 6.4) fails, as does one twice as large (1.6).
    EXPECT_LE(b.anees, 6.0);
    EXPECT_GE(b.anees, 2.0);
    EXPECT_GT(t_on[0].track.summary.num_variance_factor_epochs, 0);
    EXPECT_EQ(t_off[0].track.summary.num_variance_factor_epochs, 0);
    // The defaults: the offsets solved behind their score test.
    const MultiTrackerOptions defaults;
    ASSERT_TRUE(defaults.track.sensor_offset.batch && defaults.track.sensor_offset.batch_score_test);
    ASSERT_FALSE(defaults.track.sensor_offset.window);
    const auto t_def = SolveBatchMulti(epochs, sc.B0, defaults);
    ASSERT_FALSE(t_def.empty());
    const Summary& s = t_def[0].track.summary;
    const EarlyRows d = BatchRowsOfVessel1(sc, f, t_def);
    const double rms_def = RmsOfVessel1(sc, f, t_def), rms_off = RmsOfVessel1(sc, f, t_on);
    std::printf("drift, defaults: offsets %s (chi2 %.4g on %d dof); vessel 1 RMS %.4g m (offsets off %.4g m), "
                "ANEES %.4g over %d rows\n",
                s.offsets_solved ? "solved" : "not solved", s.offset_score_chi2, s.offset_score_dof, rms_def, rms_off,
                d.anees, d.n);
    EXPECT_TRUE(s.offsets_solved);
    EXPECT_GT(s.offset_score_chi2, 100.0 * s.offset_score_dof);
    ASSERT_GT(d.n, 500);
    // m; measured 0.0543 with the joint solve (SensorOffsetOptions::
    // batch_joint), 0.109 with the rounds alone, which this bound fails
    // (offsets off: 0.974).
    EXPECT_LE(rms_def, 1.6 * 0.0543);
    ASSERT_TRUE(defaults.track.sensor_offset.batch_joint);
    EXPECT_GE(rms_off, 8.0 * rms_def);  // measured 17.9x
    // 3 dof; measured 1.04 with the joint solve: conservative in this run
    // (the acceptance is [0.5, 2] x 3; over 20 draws the drift's cells are
    // 2.04 inside, 1.36 outside, docs/ACCURACY.md "The batch's offsets solved
    // jointly with the track"). σ halved (4x the NEES, 4.2) or doubled (0.26)
    // fails; so did the rounds alone before the joint solve with 20 s
    // segments and 8 rounds (NEES 17.6).
    EXPECT_LE(d.anees, 2.1);
    EXPECT_GE(d.anees, 0.5);
  }
  sc.background_drift_Tps.clear();  // the same vessel and noise, no drift
  const SimulatedField f = SimulateField(sc);
  const auto epochs = GroupEpochs(f.samples, on.track.epoch_tolerance_s);
  const auto t_on = SolveBatchMulti(epochs, sc.B0, on);
  const EarlyRows b = BatchRowsOfVessel1(sc, f, t_on);
  // The defaults: the score test does not fire; the estimates are the ones
  // without offsets, bit for bit.
  const auto t_def = SolveBatchMulti(epochs, sc.B0, MultiTrackerOptions{});
  ASSERT_EQ(t_def.size(), t_on.size());
  for (std::size_t i = 0; i < t_def.size(); ++i) {
    const Summary& s = t_def[i].track.summary;
    std::printf("no drift, defaults, track %zu: offsets %s (chi2 %.4g on %d dof)\n", i,
                s.offsets_solved ? "solved" : "not solved", s.offset_score_chi2, s.offset_score_dof);
    EXPECT_FALSE(s.offsets_solved);
    EXPECT_GT(s.offset_score_dof, 0);
    ASSERT_EQ(t_def[i].track.epochs.size(), t_on[i].track.epochs.size());
    for (std::size_t k = 0; k < t_def[i].track.epochs.size(); ++k) {
      EXPECT_EQ(t_def[i].track.epochs[k].p_VinW, t_on[i].track.epochs[k].p_VinW);
    }
  }
  std::printf("no drift, batch rows of vessel 1 with the factor: %d, ANEES %.4g, mean tr P %.4g m^2\n", b.n, b.anees,
              b.sigma2);
  ASSERT_GT(b.n, 500);
  // Measured: no epoch's factor above 1, so every σ is the solve's own
  // (ANEES 1.47, tr P 0.0017 m², as with the factor off).
  ASSERT_FALSE(t_on.empty());
  for (const auto& t : t_on) EXPECT_EQ(t.track.summary.num_variance_factor_epochs, 0);
  EXPECT_LT(b.anees, 2.5);  // measured 1.47: twice that fails
}

// heldout/far_ship.toml: an AUV crosses the grid while a ship (4.2e5 A m²)
// passes 114 m off its edge. The ship's B calls for the batch's sensor
// offsets, which are solved; its tensor, below the noise per sample, is a
// bias in the sensors' residual means over 20 s that barely moves the AUV's
// estimate. With TrackerOptions::batch_variance_factor_with_offsets off the
// factor is not applied on top of the solved offsets: the same estimates, bit
// for bit, with the covariance the offsets' marginalisation gives. Over 20
// draws that σ is accepted (ANEES 1.85 / 1.91 inside / outside the reach),
// the default's (the factor on top) conservative (1.18 / 1.29); the option is
// not the default because it leaves more rows overconfident beside another
// vessel (docs/ACCURACY.md).
TEST(BatchVarianceFactor, OnTopOfTheSolvedOffsetsBesideAFarShipOrNot) {
  const FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                                 "/generated/scenarios/heldout/far_ship.toml");
  const MultiTrackerOptions with;  // the defaults
  ASSERT_TRUE(with.track.batch_variance_factor_with_offsets);
  ASSERT_TRUE(with.track.batch_variance_factor.enabled);
  MultiTrackerOptions without = with;
  without.track.batch_variance_factor_with_offsets = false;
  const SimulatedField f = SimulateField(sc);
  const auto epochs = GroupEpochs(f.samples, with.track.epoch_tolerance_s);
  const auto t_off = SolveBatchMulti(epochs, sc.B0, without);
  const auto t_with = SolveBatchMulti(epochs, sc.B0, with);
  ASSERT_FALSE(t_off.empty());
  ASSERT_EQ(t_off.size(), t_with.size());
  const EarlyRows o = BatchRowsOfVessel1(sc, f, t_off), w = BatchRowsOfVessel1(sc, f, t_with);
  const Summary& s = t_off[0].track.summary;
  std::printf("far ship, batch rows of vessel 1: %d; offsets %s (chi2 %.4g on %d dof); ANEES %.4g (option off) vs "
              "%.4g (the defaults, the factor on top: %d epochs, up to %.3g), mean tr P %.3g vs %.3g m^2\n",
              o.n, s.offsets_solved ? "solved" : "not solved", s.offset_score_chi2, s.offset_score_dof, o.anees,
              w.anees, t_with[0].track.summary.num_variance_factor_epochs,
              t_with[0].track.summary.max_variance_factor, o.sigma2, w.sigma2);
  ASSERT_TRUE(s.offsets_solved);
  ASSERT_GT(o.n, 500);
  for (std::size_t i = 0; i < t_off.size(); ++i) {  // the same estimates
    EXPECT_EQ(t_off[i].track.summary.num_variance_factor_epochs, 0);
    ASSERT_EQ(t_off[i].track.epochs.size(), t_with[i].track.epochs.size());
    for (std::size_t k = 0; k < t_off[i].track.epochs.size(); ++k) {
      EXPECT_EQ(t_off[i].track.epochs[k].p_VinW, t_with[i].track.epochs[k].p_VinW);
    }
  }
  EXPECT_GT(t_with[0].track.summary.num_variance_factor_epochs, 100);
  // 3 dof; measured 2.43 with the option off, 1.59 with the defaults (697
  // epochs scaled by up to 3.6). The acceptance is [0.5, 2] x 3: σ halved
  // (9.7) or doubled (0.61) fails.
  EXPECT_GE(o.anees, 1.5);
  EXPECT_LE(o.anees, 6.0);
  EXPECT_LT(w.anees, 0.8 * o.anees);
}

}  // namespace
}  // namespace magnav::tracker
