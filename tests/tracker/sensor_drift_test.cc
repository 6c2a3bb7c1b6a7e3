// Each sensor's drift line (tracker/sensor_drift.h; issue 24 item 1): it
// follows a drift of a few nT/min, and it takes little of a near vessel's
// B bell (hundreds of nT within seconds) — measured here with no sample
// rule at all (in the tracker the bell's core does not even enter: its
// tensor is above the gate). 1 nT noise per axis.
#include "magnav/tracker/options.h"
#include "magnav/tracker/sensor_drift.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>

#include "magnav/core/dipole.h"
#include "magnav/tracker/far_source.h"
#include "quiet_offset.h"

namespace magnav::tracker {
namespace {

constexpr double kNt = 1e-9;

std::vector<DriftSample> Series(const std::function<Eigen::Vector3d(double)>& b, double t0, double t1,
                                unsigned seed, double step = 1.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, kNt);
  std::vector<DriftSample> out;
  for (double t = t0; t <= t1 + 1e-9; t += step) out.push_back({7, t, b(t) + Eigen::Vector3d(n(rng), n(rng), n(rng)), kNt});
  return out;
}

TEST(SensorDrift, FollowsADriftOfAFewNanoteslaPerMinute) {
  // 5 nT/min in a slanted direction, 15 nT of offset already at t = 0.
  const Eigen::Vector3d dir = Eigen::Vector3d(0.3, -0.8, 0.5).normalized();
  const auto drift = [&](double t) -> Eigen::Vector3d { return dir * (15.0 * kNt + 5.0 * kNt / 60.0 * t); };
  double worst = 0.0, worst_next = 0.0, worst_rate = 0.0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    DriftLine line;
    ASSERT_TRUE(FitDriftLine(Series(drift, 100.0, 400.0, seed), SensorDriftOptions{}, &line));
    worst = std::max(worst, (line.At(400.0) - drift(400.0)).norm());
    worst_next = std::max(worst_next, (line.At(401.0) - drift(401.0)).norm());  // before the next fit
    worst_rate = std::max(worst_rate, (line.rate_W - dir * 5.0 * kNt / 60.0).norm() * 60.0);
    EXPECT_LT(line.SigmaAt(400.0), 0.5 * kNt);
  }
  std::printf("drift 5 nT/min over 300 s, 20 seeds: largest error at the newest sample %.3f nT, 1 s later %.3f nT, "
              "rate %.3f nT/min\n",
              worst / kNt, worst_next / kNt, worst_rate / kNt);
  EXPECT_LT(worst, 0.6 * kNt);        // measured 0.386 nT
  EXPECT_LT(worst_next, 0.6 * kNt);   // measured 0.389 nT
  EXPECT_LT(worst_rate, 0.2 * kNt);   // nT/min; measured 0.133
}

// An AUV (2000 A·m²) passing 8 m from the sensor at 1.5 m/s, 3 m above it:
// a bell of ~350 nT, above the 1 nT noise for ±30 s, on a sensor that does
// not drift. The window (300 s, a sample every 1 s, as the far source keeps
// them) slides past it, its newest sample from 30 s before the closest
// approach to 60 s after; the largest offset the line takes at its newest
// sample is what would be removed from that sensor's samples. Measured with
// no sample rule (every sample enters: a worst case) and with the tracker's
// rule for a vessel no track explains (a sample whose tensor exceeds the
// gate, ‖T‖_F > 6 σ_T, does not enter; quiet_sample.h). A tracked vessel's
// samples enter with its predicted field removed, or not at all.
TEST(SensorDrift, TakesLittleOfANearVesselsBell) {
  const Eigen::Vector3d m(2000.0, 300.0, 800.0);
  const auto at = [](double t) { return Eigen::Vector3d(1.5 * (t - 400.0), 8.0, -3.0); };  // sensor at the origin
  const auto bell = [&](double t) -> Eigen::Vector3d { return DipoleB(-at(t), m); };
  const auto quiet = [&](double t) {
    Eigen::Vector3d B;
    Eigen::Matrix3d T;
    DipoleBT(-at(t), m, &B, &T);
    return T.norm() <= 6.0 * 1.4e-9;
  };
  double peak = 0.0;
  for (double t = 390.0; t <= 410.0; t += 0.1) peak = std::max(peak, bell(t).norm());
  double taken_huber = 0.0, taken_ls = 0.0, taken_rule = 0.0;
  SensorDriftOptions o;
  o.max_rate_T_per_s = 1.0;  // no rate cap: the line alone
  SensorDriftOptions ls = o;
  ls.huber_sigmas = ls.reject_sigmas = 1e9;  // plain least squares: what the loss is for
  for (double end = 370.0; end <= 460.0; end += 1.0) {
    std::mt19937 rng(static_cast<unsigned>(end));
    std::normal_distribution<double> n(0.0, kNt);
    std::vector<DriftSample> all, ruled;
    for (double t = end - 300.0; t <= end + 1e-9; t += 1.0) {
      const DriftSample d{7, t, bell(t) + Eigen::Vector3d(n(rng), n(rng), n(rng)), kNt};
      all.push_back(d);
      if (quiet(t)) ruled.push_back(d);
    }
    DriftLine a, b, c;
    ASSERT_TRUE(FitDriftLine(all, o, &a));
    ASSERT_TRUE(FitDriftLine(all, ls, &b));
    ASSERT_TRUE(FitDriftLine(ruled, o, &c));
    taken_huber = std::max(taken_huber, a.At(end).norm());
    taken_ls = std::max(taken_ls, b.At(end).norm());
    taken_rule = std::max(taken_rule, c.At(end).norm());
  }
  std::printf("near vessel bell %.0f nT peak: the line takes at most %.2f nT with the tensor gate, %.2f nT with no "
              "rule (Huber), %.1f nT with no rule (least squares)\n",
              peak / kNt, taken_rule / kNt, taken_huber / kNt, taken_ls / kNt);
  EXPECT_GT(peak, 300.0 * kNt);            // hundreds of nT within seconds
  EXPECT_LT(taken_rule, 4.5 * kNt);        // measured 2.97 nT (0.9 % of the peak)
  EXPECT_LT(taken_huber, 4.5 * kNt);       // measured 2.97 nT
  EXPECT_GT(taken_ls, 2.0 * taken_huber);  // the loss matters: measured 25.8 nT
}

TEST(SensorDrift, TooFewSamplesKeepTheLine) {
  SensorDriftOptions on;
  on.enabled = true;  // off by default
  on.min_span_s = 10.0;               // a minute of samples below
  on.confirm_min_rate_T_per_s = 0.0;  // a flat line removed too
  on.confirm_rate_sigmas = 0.0;
  SensorDrift d(on);
  const auto flat = [](double) -> Eigen::Vector3d { return Eigen::Vector3d(3.0, 0.0, 0.0) * kNt; };
  d.Fit(Series(flat, 0.0, 60.0, 1, 0.5));
  double sigma = 0.0;
  EXPECT_NEAR(d.At(7, 60.0, &sigma).x(), 3.0 * kNt, 0.5 * kNt);
  EXPECT_GT(sigma, 0.0);
  d.Fit(Series(flat, 60.0, 62.0, 2, 0.5));  // 5 samples over 2 s: not refitted
  EXPECT_EQ(d.lines().at(7).t_ref_s, 60.0);
  EXPECT_EQ(d.At(8, 60.0), Eigen::Vector3d::Zero());  // never seen
  SensorDrift o;  // off
  o.Fit(Series(flat, 0.0, 60.0, 1));
  EXPECT_EQ(o.At(7, 60.0), Eigen::Vector3d::Zero());
}

// A line is removed only once its trend is confirmed (rate ≥ 1.5 nT/min
// and ≥ 5 σ of its own): not a flat offset, nor the 0.6–1.2 nT/min that
// vessels' B tails leave in lines on files with no drift; a 2 nT/min drift is.
TEST(SensorDrift, OnlyAConfirmedTrendIsRemoved) {
  SensorDriftOptions on;
  on.enabled = true;
  for (const auto& [rate_nt_per_min, removed] : {std::pair{0.0, false}, {1.0, false}, {2.0, true}, {6.0, true}}) {
    SCOPED_TRACE(rate_nt_per_min);
    SensorDrift d(on);
    const double r = rate_nt_per_min;
    d.Fit(Series([r](double t) -> Eigen::Vector3d { return Eigen::Vector3d(3.0 + r * t / 60.0, 0.0, 0.0) * kNt; },
                 0.0, 180.0, 3));
    ASSERT_EQ(d.lines().count(7), 1u);  // fitted (a warm start) either way
    const Eigen::Vector3d at = d.At(7, 180.0);
    if (removed) {
      EXPECT_NEAR(at.x(), (3.0 + r * 3.0) * kNt, 0.6 * kNt);
    } else {
      EXPECT_EQ(at, Eigen::Vector3d::Zero());
    }
  }
  // A minute of samples is too short a span for the default (60 s): no line.
  SensorDrift d(on);
  d.Fit(Series([](double t) -> Eigen::Vector3d { return Eigen::Vector3d(5.0 * t / 60.0, 0.0, 0.0) * kNt; }, 0.0, 50.0, 4));
  EXPECT_EQ(d.lines().count(7), 0u);
}

TEST(SensorDrift, OptionsAreChecked) {
  SensorDriftOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.rate_prior_sigma_T_per_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  o = {};
  o.min_samples = 1;
  EXPECT_FALSE(o.IsValid(&why));
  FarSourceOptions f;
  f.drift.huber_sigmas = -1.0;
  EXPECT_FALSE(f.IsValid(&why));
  EXPECT_NE(why.find("sensor_drift"), std::string::npos);
}

// The per-sensor B offset in a track's solve (TrackerOptions::sensor_offset):
// its prior σ grows with the drift since B0 held, its options are checked.
TEST(SensorOffset, PriorGrowsWithTheDriftAndOptionsAreChecked) {
  SensorOffsetOptions o;
  EXPECT_FALSE(o.window);  // the window's, an option, off
  EXPECT_TRUE(o.batch);    // the batch's, on behind its score test
  EXPECT_TRUE(o.batch_score_test);
  EXPECT_TRUE(o.batch_joint);  // and its joint solve after the rounds
  EXPECT_NEAR(o.PriorSigma(0.0), o.floor_T, 1e-15);
  EXPECT_NEAR(o.PriorSigma(600.0), std::hypot(o.floor_T, 60e-9), 1e-12);  // 6 nT/min over 10 min
  EXPECT_NEAR(o.StepSigma(), 1e-9, 1e-15);                                 // 6 nT/min over 10 s
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.passes = 0;
  EXPECT_FALSE(o.IsValid(&why));
  o = {};
  o.segment_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  TrackerOptions t;
  t.sensor_offset.floor_T = -1.0;
  EXPECT_FALSE(t.IsValid(&why));
  EXPECT_NE(why.find("sensor_offset"), std::string::npos);
}

// The window's offset carried between windows and the tensor gate
// (SensorOffsetOptions::carry, min_tensor_snr): off by default, the carry
// only with the offset, the gate a finite SNR ≥ 0.
TEST(SensorOffset, CarryAndTensorGateAreOffAndChecked) {
  SensorOffsetOptions o;
  EXPECT_FALSE(o.carry);
  EXPECT_EQ(o.min_tensor_snr, 0.0);
  std::string why;
  o.carry = true;
  EXPECT_FALSE(o.IsValid(&why));  // without window
  EXPECT_NE(why.find("carry"), std::string::npos);
  o.window = true;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.min_tensor_snr = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
  o.min_tensor_snr = std::nan("");
  EXPECT_FALSE(o.IsValid(&why));
  o.min_tensor_snr = 20.0;
  EXPECT_TRUE(o.IsValid(&why)) << why;
}

// The score test's persistence (SensorOffsetOptions::window_score_persist_s;
// its effect: HarbourScenario.WindowScoreTestLatchedAfterItPersists…): off by
// default, finite, ≥ 0, and only with the score test.
TEST(SensorOffset, ScoreTestPersistenceIsOffAndChecked) {
  SensorOffsetOptions so;
  EXPECT_EQ(so.window_score_persist_s, 0.0);
  so.window_lines = true;
  std::string error;
  so.window_score_persist_s = 3.0;
  EXPECT_FALSE(so.IsValid(&error));
  EXPECT_NE(error.find("window_score_persist_s"), std::string::npos) << error;
  so.window_score_test = true;
  EXPECT_TRUE(so.IsValid(&error)) << error;
  so.window_score_persist_s = -1.0;
  EXPECT_FALSE(so.IsValid(&error));
  so.window_score_persist_s = std::nan("");
  EXPECT_FALSE(so.IsValid(&error));
}

// Each sensor's offset from its quiet data (SensorOffsetOptions::quiet,
// tracker/src/quiet_offset.h): 20 s of a 5 nT/min drift with 1 nT noise at
// 10 Hz, 10 % of the samples spoilt by a vessel's 300 nT — the median sits on
// the drift at the samples' median time (within 0.5 nT: the vessel's share
// would move a mean by 30 nT), its σ is the median's (≈ 1.25 · 1 nT/√200) and
// grows by the 6 nT/min walk after; too few samples give no prior.
TEST(SensorOffset, QuietOffsetIsTheQuietMedianWalkedAtTheDriftBound) {
  SensorOffsetOptions o;
  EXPECT_FALSE(o.quiet);  // an option, off
  o.window = true;
  o.quiet = true;
  std::string why;
  ASSERT_TRUE(o.IsValid(&why)) << why;
  internal::QuietOffsets q(o);
  const Eigen::Vector3d rate_W = Eigen::Vector3d(3.0, -4.0, 0.0) * kNt / 60.0;  // 5 nT/min
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0.0, kNt);
  Eigen::Vector3d mean_W;
  double sigma = 0.0;
  EXPECT_FALSE(q.Prior(4, 0.0, &mean_W, &sigma));  // nothing yet
  int k = 0;
  for (double t = 100.0; t < 130.0 - 1e-9; t += 0.1, ++k) {  // 30 s: the first 10 s leave the 20 s span
    Eigen::Vector3d r = rate_W * t + Eigen::Vector3d(n(rng), n(rng), n(rng));
    if (k % 10 == 3) r += Eigen::Vector3d(300.0, -200.0, 150.0) * kNt;
    q.Add(4, t, r);
  }
  EXPECT_NEAR(q.num_quiet(4), 201, 1);
  EXPECT_FALSE(q.Prior(5, 130.0, &mean_W, &sigma));  // another sensor: none
  ASSERT_TRUE(q.Prior(4, 120.0, &mean_W, &sigma));  // the samples' median time
  EXPECT_LE((mean_W - rate_W * 120.0).norm(), 0.5 * kNt);
  EXPECT_GT(sigma, 0.04 * kNt);
  EXPECT_LT(sigma, 0.2 * kNt);  // 1.2533 · 1.4826 · MAD/√201 ≈ 0.09 nT
  ASSERT_TRUE(q.Prior(4, 180.0, &mean_W, &sigma));  // 60 s later: the walk's 6 nT
  EXPECT_NEAR(sigma, 6.0 * kNt, 0.05 * kNt);
  o.quiet_min_samples = 1000;
  internal::QuietOffsets few(o);
  few.Add(4, 0.0, Eigen::Vector3d::Zero());
  EXPECT_FALSE(few.Prior(4, 0.0, &mean_W, &sigma));
  // Checked: only with the offset, a positive span and count.
  o = {};
  o.quiet = true;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("quiet"), std::string::npos);
  o.window = true;
  o.quiet_span_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  o.quiet_span_s = 20.0;
  o.quiet_min_samples = 0;
  EXPECT_FALSE(o.IsValid(&why));
  o.quiet_min_samples = 50;
  o.quiet_tensor_mean_s = std::nan("");
  EXPECT_FALSE(o.IsValid(&why));
}

// The quiet offset as a line (SensorOffsetOptions::quiet_rate): 60 s of a
// 5 nT/min drift with 1 nT noise at 10 Hz, 10 % of the samples spoilt by a
// vessel's 300 nT; predicted 45 s after the last sample (a sensor occupied by
// a vessel) it is within 1 nT of the drift, where the median walked at the
// bound (the option off) is 6.25 nT behind (75 s × 5 nT/min); its rate within
// 1 nT/min of the drift's; its σ grows with the extrapolation; a rate beyond
// the bound is held at it; a store shorter than the baseline gives no rate.
TEST(SensorOffset, QuietOffsetRateFollowsTheDriftRampWhileTheSensorIsOccupied) {
  SensorOffsetOptions o;
  EXPECT_FALSE(o.quiet_rate);  // an option, off
  EXPECT_FALSE(o.quiet_approach);
  o.window = true;
  o.quiet = true;
  o.quiet_rate = true;
  std::string why;
  ASSERT_TRUE(o.IsValid(&why)) << why;
  const Eigen::Vector3d rate_W = Eigen::Vector3d(3.0, -4.0, 0.0) * kNt / 60.0;  // 5 nT/min
  const auto fill = [&](internal::QuietOffsets* q, const Eigen::Vector3d& rate, double t0, double t1) {
    std::mt19937 rng(12);
    std::normal_distribution<double> n(0.0, kNt);
    int k = 0;
    for (double t = t0; t < t1 - 1e-9; t += 0.1, ++k) {
      Eigen::Vector3d r = rate * t + Eigen::Vector3d(n(rng), n(rng), n(rng));
      if (k % 10 == 3) r += Eigen::Vector3d(300.0, -200.0, 150.0) * kNt;
      q->Add(4, t, r);
    }
  };
  internal::QuietOffsets q(o);
  fill(&q, rate_W, 90.0, 160.0);  // 70 s: the first 10 s leave the 60 s span
  EXPECT_NEAR(q.num_quiet(4), 601, 1);
  Eigen::Vector3d mean_W, rate_fit;
  double sigma_now = 0.0, sigma_later = 0.0;
  ASSERT_TRUE(q.Rate(4, &rate_fit));
  EXPECT_LE((rate_fit - rate_W).norm(), 1.0 * kNt / 60.0);
  ASSERT_TRUE(q.Prior(4, 130.0, &mean_W, &sigma_now));
  ASSERT_TRUE(q.Prior(4, 205.0, &mean_W, &sigma_later));
  EXPECT_LE((mean_W - rate_W * 205.0).norm(), 1.0 * kNt);  // measured 0.74 nT (the spoilt 10 % move the level)
  EXPECT_GT(sigma_later, 2.0 * sigma_now);  // the rate's σ × 75 s on the level's
  EXPECT_LT(sigma_later, 1.5 * kNt);
  // The option off: the median at the samples' median time, 6.25 nT behind.
  SensorOffsetOptions off = o;
  off.quiet_rate = false;
  off.quiet_span_s = 60.0;
  internal::QuietOffsets walked(off);
  fill(&walked, rate_W, 90.0, 160.0);
  ASSERT_TRUE(walked.Prior(4, 205.0, &mean_W, &sigma_later));
  EXPECT_GT((mean_W - rate_W * 205.0).norm(), 5.0 * kNt);
  // A drift beyond the bound (20 nT/min on x): its rate held at 6 nT/min.
  internal::QuietOffsets steep(o);
  fill(&steep, Eigen::Vector3d(20.0, 0.0, 0.0) * kNt / 60.0, 90.0, 160.0);
  ASSERT_TRUE(steep.Rate(4, &rate_fit));
  EXPECT_NEAR(rate_fit.x(), o.max_rate_T_per_s, 1e-15);
  // 5 s of samples: no rate (the median and the walk).
  internal::QuietOffsets brief(o);
  fill(&brief, rate_W, 100.0, 105.0);
  EXPECT_FALSE(brief.Rate(4, &rate_fit));
  // Checked: only with the quiet offset; a positive span.
  o = {};
  o.window = true;
  o.quiet_rate = true;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("quiet_rate"), std::string::npos);
  o.quiet_rate = false;
  o.quiet_approach = true;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("quiet_approach"), std::string::npos);
  o.quiet = true;
  ASSERT_TRUE(o.IsValid(&why)) << why;
  o.quiet_rate_span_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  o.quiet_rate_span_s = std::nan("");
  EXPECT_FALSE(o.IsValid(&why));
}

// A confirmed track's approach out of the quiet store (QuietOffsets::TakeOut,
// SensorOffsetOptions::quiet_approach): 30 s of quiet samples with no drift
// (1 nT noise), the last 10 s holding an untracked vessel's approach B that
// grows from 0 to 8 nT along x. With the rate fitted the approach sets a
// steep rate (held at the 6 nT/min bound) and the offset 20 s later is
// nT off; once the track's field is taken out (dropped where it reaches
// 3 nT, subtracted below) the offset is back within 1 nT of zero.
TEST(SensorOffset, QuietTakeOutRemovesANewTracksApproachFromTheStore) {
  SensorOffsetOptions o;
  o.window = true;
  o.quiet = true;
  o.quiet_rate = true;
  o.quiet_approach = true;
  internal::QuietOffsets q(o);
  const auto approach = [](double t) { return Eigen::Vector3d(t > 120.0 ? 0.8 * (t - 120.0) * kNt : 0.0, 0.0, 0.0); };
  std::mt19937 rng(13);
  std::normal_distribution<double> n(0.0, kNt);
  for (double t = 100.0; t < 130.0 - 1e-9; t += 0.1) {
    q.Add(4, t, approach(t) + Eigen::Vector3d(n(rng), n(rng), n(rng)), Eigen::Vector3d(1.0, 2.0, 0.0), kNt, 1.4 * kNt);
  }
  Eigen::Vector3d mean_W;
  double sigma = 0.0;
  ASSERT_TRUE(q.Prior(4, 150.0, &mean_W, &sigma));
  EXPECT_GT(mean_W.norm(), 2.0 * kNt);  // the approach's B and its rate
  const internal::QuietTakeOutStats st =
      q.TakeOut([&](std::uint32_t id, double t, const Eigen::Vector3d& p, double sigma_B, double, Eigen::Vector3d* B,
                    bool* not_quiet) {
        EXPECT_EQ(id, 4u);
        EXPECT_EQ(p, Eigen::Vector3d(1.0, 2.0, 0.0));  // the stored sample's sensor position
        *B = approach(t);
        *not_quiet = B->norm() >= 3.0 * sigma_B;
        return true;
      });
  EXPECT_NEAR(st.dropped, 62, 1);  // 123.8–129.9 s: B ≥ 3 nT
  EXPECT_NEAR(st.corrected, 238, 1);
  ASSERT_TRUE(q.Prior(4, 150.0, &mean_W, &sigma));
  EXPECT_LE(mean_W.norm(), 1.0 * kNt);  // measured 0.46 nT (the noise's rate over 36 s of extrapolation)
}

}  // namespace
}  // namespace magnav::tracker
