// One outlier inside the door's limits must not move the localizer's
// estimate (issue 25 item 2): one GNSS fix 9e6 m off (the file door allows
// 1e7 m) and one magnetometer sample with a 10 µT spike (10⁴ σ), each alone,
// on the reference pass and on a scenario the defaults were not tuned on.
// Bound: RMSE with the outlier ≤ max(1.5 × clean RMSE, clean RMSE + 2 × the
// clean estimate's RMS σ), for the EKF (NIS gate) and the batch (robust
// losses), and the outlier is counted in the summary. Without the gate or
// the robust losses these fail (EKF 21 km / 0.55 m, batch 32.7 m on the
// reference pass). Figures: docs/ACCURACY.md "Trust: one outlier".
#include <cmath>
#include <functional>
#include <random>

#include <gtest/gtest.h>

#include "localize_data.h"
#include "magnav/core/error.h"
#include "magnav/core/nees.h"
#include "magnav/core/simulate.h"
#include "magnav/localizer/batch.h"
#include "magnav/localizer/ekf.h"

namespace magnav::localizer {
namespace {

using test::ScoreSensors;

struct Scenario {
  std::string name;
  Pass pass;
  std::vector<Eigen::Vector2d> truth;
};

Scenario Reference() {
  Scenario s{"reference", test::ReferencePass().pass, {}};
  s.truth = test::TruthSensors(s.pass);
  return s;
}

// Held out: not the reference pass and not heldout_test.cc's scenario: east-west legs
// joined by left half-turns (radius 15 m), 5 sensors at 20 m depth, another moment and
// speed, 2 Hz, GNSS σ 2.5 m at 1 Hz, deployment σ 8 m; core's simulator, seed 300.
Scenario HeldOut() {
  PassScenario sc;
  sc.moment_body = {20000.0, -8000.0, 15000.0};
  sc.start_position = {-60.0, -110.0, 0.0};
  sc.speed_mps = 1.8;
  sc.start_heading_rad = M_PI / 2;  // east
  const double half_turn_s = M_PI / 0.12;
  sc.segments = {{120.0, 0.0}, {half_turn_s, -0.12}, {120.0, 0.0}, {half_turn_s, 0.12}, {120.0, 0.0}};
  sc.rate_hz = 2.0;
  sc.sensors = {{-75.0, -60.0, 20.0}, {-45.0, 20.0, 20.0}, {-15.0, 80.0, 20.0}, {-60.0, 60.0, 20.0}, {10.0, -30.0, 20.0}};
  sc.B0 = Eigen::Vector3d::Zero();
  sc.sigma_B = 1e-9;
  sc.seed = 300;
  const SimulatedPass sim = SimulatePass(sc);

  Scenario s{"held out", {}, {}};
  s.pass.vessel = {sc.moment_body, 0.0};
  std::mt19937_64 rng(300 * 7919 + 13);
  std::normal_distribution<double> n(0.0, 1.0);
  for (std::size_t j = 0; j < sc.sensors.size(); ++j) {
    s.truth.push_back(sc.sensors[j].head<2>());
    const Eigen::Vector3d guess(sc.sensors[j].x() + 8.0 * n(rng), sc.sensors[j].y() + 8.0 * n(rng), 20.0);
    s.pass.sensors.push_back({static_cast<std::uint32_t>(j), guess, 8.0});
  }
  for (const auto& m : sim.samples) s.pass.samples.push_back({m.t_s, m.sensor_id, m.B});
  for (const auto& v : sim.truth) {
    if (std::abs(v.t_s - std::round(v.t_s)) < 1e-9) {
      s.pass.gnss.push_back({v.t_s, v.p_VinW.head<2>() + 2.5 * Eigen::Vector2d(n(rng), n(rng)), 2.5});
    }
  }
  return s;
}

// The outliers: at the middle of their stream, and early: the GNSS fix among
// those the EKF starts from (its first 10 s), the spike in the first 5 % of the
// pass, while the sensors are still metres off.
void GnssJump(Pass* p) { p->gnss[p->gnss.size() / 2].p_xy_m.x() += 9e6; }
void GnssJumpAtStart(Pass* p) { p->gnss[3].p_xy_m.x() += 9e6; }
void MagSpike(Pass* p) { p->samples[p->samples.size() / 2].B_T.x() += 10e-6; }
void MagSpikeEarly(Pass* p) { p->samples[p->samples.size() / 20].B_T.x() += 10e-6; }

struct Figures {
  test::Score ekf, batch;
  Summary ekf_summary, batch_summary;
};

Figures Solve(const Scenario& s, const std::function<void(Pass*)>& corrupt) {
  Pass pass = s.pass;
  if (corrupt) corrupt(&pass);
  const LocalizerOptions opt;
  const Localization ekf = RunEkf(pass, opt);
  const Localization batch = SolveBatch(pass, opt, &ekf);
  return {ScoreSensors(ekf.sensors, s.truth), ScoreSensors(batch.sensors, s.truth), ekf.summary, batch.summary};
}

// The bound, and the σ (finite, not made small or large by the outlier).
void ExpectWithinBound(const std::string& what, const test::Score& clean, const test::Score& outlier,
                       ::testing::Test* t) {
  const double bound = std::max(1.5 * clean.rmse_m, clean.rmse_m + 2.0 * clean.rms_sigma_m);
  t->RecordProperty(what + "_rmse_m", std::to_string(outlier.rmse_m));
  t->RecordProperty(what + "_clean_rmse_m", std::to_string(clean.rmse_m));
  t->RecordProperty(what + "_rms_sigma_m", std::to_string(outlier.rms_sigma_m));
  t->RecordProperty(what + "_bound_m", std::to_string(bound));
  EXPECT_LE(outlier.rmse_m, bound) << what << ": clean " << clean.rmse_m << " m, σ " << clean.rms_sigma_m << " m";
  // Measured ≤ 1.05 × clean in every case: a partial regression breaks this first.
  EXPECT_LE(outlier.rmse_m, 1.2 * clean.rmse_m) << what;
  EXPECT_TRUE(std::isfinite(outlier.rms_sigma_m)) << what;
  EXPECT_GT(outlier.rms_sigma_m, 0.8 * clean.rms_sigma_m) << what;
  EXPECT_LT(outlier.rms_sigma_m, 1.25 * clean.rms_sigma_m) << what;
}

void CheckScenario(const Scenario& s, ::testing::Test* t) {
  const Figures clean = Solve(s, nullptr);
  const Figures gnss = Solve(s, GnssJump);
  const Figures gnss_start = Solve(s, GnssJumpAtStart);
  const Figures mag = Solve(s, MagSpike);
  const Figures mag_early = Solve(s, MagSpikeEarly);
  SCOPED_TRACE(s.name);
  // Clean: the gate refuses almost nothing (p 0.9999 per update) and nothing by GNSS.
  EXPECT_TRUE(clean.ekf_summary.converged) << clean.ekf_summary.BriefReport();
  EXPECT_TRUE(clean.batch_summary.converged) << clean.batch_summary.BriefReport();
  EXPECT_LE(clean.ekf_summary.magnetometer_outliers, 1 + static_cast<int>(s.pass.samples.size()) / 1000)
      << clean.ekf_summary.BriefReport();
  EXPECT_EQ(clean.ekf_summary.gnss_outliers, 0) << clean.ekf_summary.BriefReport();

  ExpectWithinBound("gnss_jump_ekf", clean.ekf, gnss.ekf, t);
  ExpectWithinBound("gnss_jump_batch", clean.batch, gnss.batch, t);
  ExpectWithinBound("gnss_jump_start_ekf", clean.ekf, gnss_start.ekf, t);
  ExpectWithinBound("gnss_jump_start_batch", clean.batch, gnss_start.batch, t);
  ExpectWithinBound("mag_spike_ekf", clean.ekf, mag.ekf, t);
  ExpectWithinBound("mag_spike_batch", clean.batch, mag.batch, t);
  ExpectWithinBound("mag_spike_early_ekf", clean.ekf, mag_early.ekf, t);
  ExpectWithinBound("mag_spike_early_batch", clean.batch, mag_early.batch, t);
  // Counted, and only it: one more than clean.
  EXPECT_EQ(gnss.ekf_summary.gnss_outliers, 1) << gnss.ekf_summary.BriefReport();
  EXPECT_EQ(gnss.batch_summary.gnss_outliers, 1 + clean.batch_summary.gnss_outliers) << gnss.batch_summary.BriefReport();
  EXPECT_EQ(gnss_start.batch_summary.gnss_outliers, 1 + clean.batch_summary.gnss_outliers)
      << gnss_start.batch_summary.BriefReport();
  EXPECT_EQ(mag.ekf_summary.magnetometer_outliers, 1 + clean.ekf_summary.magnetometer_outliers)
      << mag.ekf_summary.BriefReport();
  EXPECT_EQ(mag_early.ekf_summary.magnetometer_outliers, 1 + clean.ekf_summary.magnetometer_outliers)
      << mag_early.ekf_summary.BriefReport();
  EXPECT_EQ(mag.batch_summary.magnetometer_outliers, 1 + clean.batch_summary.magnetometer_outliers)
      << mag.batch_summary.BriefReport();
  EXPECT_TRUE(gnss.batch_summary.converged) << gnss.batch_summary.BriefReport();
  EXPECT_TRUE(mag.batch_summary.converged) << mag.batch_summary.BriefReport();
  EXPECT_NE(gnss.ekf_summary.message.find("refused by the NIS gate"), std::string::npos) << gnss.ekf_summary.message;
}

TEST(LocalizerOutlier, OneOutlierStaysWithinTheBoundOnTheReferencePass) { CheckScenario(Reference(), this); }

TEST(LocalizerOutlier, OneOutlierStaysWithinTheBoundHeldOut) { CheckScenario(HeldOut(), this); }

// A time no float step can hold (t = 1e300 s, which the file readers refuse)
// reaching the library: the update fails, is counted, and leaves every number
// finite; the summary says so instead of "every sample used".
TEST(LocalizerOutlier, ASampleAtTime1e300IsRefusedAndCounted) {
  Scenario s = HeldOut();
  MagSample late = s.pass.samples.back();
  late.t_s = 1e300;
  s.pass.samples.push_back(late);
  const Localization ekf = RunEkf(s.pass, LocalizerOptions{});
  EXPECT_FALSE(ekf.summary.converged);
  EXPECT_NE(ekf.summary.message.find("1 updates failed"), std::string::npos) << ekf.summary.message;
  for (const auto& e : ekf.sensors) {
    EXPECT_TRUE(e.p_SinW_m.allFinite());
    EXPECT_TRUE(e.cov_xy_m2.allFinite());
    EXPECT_TRUE(e.crlb_joint_m2.allFinite());
    EXPECT_GT(e.crlb_joint_m2.trace(), 0.0);
  }
  EXPECT_LE(ScoreSensors(ekf.sensors, s.truth).rmse_m, 1.0);
  // The batch refuses such a pass (without that check: "converged" after one step, 0.46 m off).
  EXPECT_THROW(SolveBatch(s.pass, LocalizerOptions{}, &ekf), InputError);
}

TEST(LocalizerOutlier, GateProbabilityIsChecked) {
  LocalizerOptions o;
  std::string why;
  o.gate_probability = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  o.gate_probability = 1.0;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.gnss_loss_scale_sigma = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
}

}  // namespace
}  // namespace magnav::localizer
