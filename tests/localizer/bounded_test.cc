// The bounded live localizer (StreamOptions::bounded, RunEkfBounded,
// `magnav localize --method ekf-bounded`, what magnav-localizer runs): the
// same EKF estimates as the unbounded one, a bound within 1.2× of the bound
// over the whole pass, and nothing kept that grows with the items consumed.
// Figures: docs/ACCURACY.md "Localizer, bounded"; speed and memory against
// uptime: bench/localizer_bench.cc (docs/BENCHMARKS.md).
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "localize_data.h"
#include "magnav/localizer/batch.h"
#include "magnav/localizer/ekf.h"
#include "magnav/localizer/stream.h"
#include "racetrack.h"

namespace magnav::localizer {
namespace {

double RmsBound(const Localization& l) {
  double s = 0.0;
  for (const auto& e : l.sensors) s += e.crlb_joint_m2.trace();
  return std::sqrt(s / static_cast<double>(l.sensors.size()));
}

double Rmse(const Localization& l, const std::vector<Eigen::Vector2d>& truth) {
  double s = 0.0;
  for (std::size_t j = 0; j < truth.size(); ++j) s += (l.sensors[j].p_SinW_m.head<2>() - truth[j]).squaredNorm();
  return std::sqrt(s / static_cast<double>(truth.size()));
}

// With a window that never folds before the end, the recursion evaluates
// every epoch where ComputeCrlb does: the chain's elimination one epoch at a
// time is the batch's Schur complement, so the bounds are equal.
TEST(LocalizerBounded, UnfoldedRecursionEqualsTheWholePassBound) {
  const Pass pass = test::ReferencePass().pass;
  const LocalizerOptions opt;
  IncrementalCrlbOptions whole;
  whole.lag_s = 1e12;
  whole.max_window_items = std::numeric_limits<std::size_t>::max();
  const Localization a = RunEkf(pass, opt);
  const Localization b = RunEkfBounded(pass, opt, whole);
  IncrementalCrlbOptions folded;  // and folding as it goes at the estimate of each time, lag 0
  folded.lag_s = 0.0;
  const Localization c = RunEkfBounded(pass, opt, folded);
  ASSERT_EQ(a.sensors.size(), b.sensors.size());
  for (std::size_t j = 0; j < a.sensors.size(); ++j) {
    SCOPED_TRACE(j);
    EXPECT_EQ(a.sensors[j].p_SinW_m, b.sensors[j].p_SinW_m);
    EXPECT_EQ(a.sensors[j].cov_xy_m2, b.sensors[j].cov_xy_m2);
    EXPECT_EQ(a.sensors[j].p_SinW_m, c.sensors[j].p_SinW_m);
    for (int k = 0; k < 4; ++k) {
      EXPECT_NEAR(b.sensors[j].crlb_joint_m2(k), a.sensors[j].crlb_joint_m2(k), 1e-7 * a.sensors[j].crlb_joint_m2(0));
      EXPECT_NEAR(b.sensors[j].crlb_known_trajectory_m2(k), a.sensors[j].crlb_known_trajectory_m2(k),
                  1e-7 * a.sensors[j].crlb_known_trajectory_m2(0));
    }
  }
  EXPECT_EQ(b.summary.magnetometer_updates, a.summary.magnetometer_updates);
  EXPECT_EQ(b.summary.gnss_updates, a.summary.gnss_updates);
  EXPECT_EQ(b.summary.method, "ekf-bounded");
  RecordProperty("lag0_over_whole_bound", std::to_string(RmsBound(c) / RmsBound(a)));
}

// The defaults on the reference pass: estimates = the unbounded EKF's, bound
// within 1.2× of the whole-pass one (measured: docs/ACCURACY.md).
TEST(LocalizerBounded, ReferenceBoundWithinOnePointTwoOfTheWholePassBound) {
  const PassFile f = test::ReferencePass();
  const std::vector<Eigen::Vector2d> truth = test::TruthSensors(f.pass);
  const LocalizerOptions opt;
  const Localization a = RunEkf(f.pass, opt);
  const Localization b = RunEkfBounded(f.pass, opt);
  const double ratio = RmsBound(b) / RmsBound(a);
  RecordProperty("ekf_rmse_m", std::to_string(Rmse(a, truth)));
  RecordProperty("bounded_rmse_m", std::to_string(Rmse(b, truth)));
  RecordProperty("ekf_rms_bound_m", std::to_string(RmsBound(a)));
  RecordProperty("bounded_rms_bound_m", std::to_string(RmsBound(b)));
  EXPECT_EQ(Rmse(a, truth), Rmse(b, truth));
  EXPECT_GT(ratio, 1.0 / 1.2);
  EXPECT_LT(ratio, 1.2);
  for (std::size_t j = 0; j < a.sensors.size(); ++j) {  // per sensor too
    const double r = std::sqrt(b.sensors[j].crlb_joint_m2.trace() / a.sensors[j].crlb_joint_m2.trace());
    EXPECT_GT(r, 1.0 / 1.2) << j;
    EXPECT_LT(r, 1.2) << j;
  }
}

// The window's item cap: past it the oldest epochs are folded early (at the
// estimate of that time); the window never holds more than the cap plus the
// newest epoch, and the bound stays within 1.2× of the whole-pass one.
TEST(LocalizerBounded, WindowCapFoldsEarly) {
  const Pass pass = test::ReferencePass().pass;
  const LocalizerOptions opt;
  IncrementalCrlbOptions capped;
  capped.lag_s = 1e12;
  capped.max_window_items = 100;
  IncrementalCrlb crlb(pass.vessel, pass.sensors, opt, capped);
  const Localization whole = RunEkf(pass, opt);
  std::size_t peak = 0;
  for (std::size_t i = 0; i < whole.trajectory.size() && i < 500; ++i) {  // feed the filtered states back
    Eigen::VectorXd state(5 + 2 * static_cast<int>(pass.sensors.size()));
    state.head<5>() = whole.trajectory[i];
    for (std::size_t j = 0; j < pass.sensors.size(); ++j) {
      state.segment<2>(5 + 2 * static_cast<int>(j)) = whole.sensors[j].p_SinW_m.head<2>();
    }
    for (const MagSample& s : pass.samples) {
      if (std::abs(s.t_s - whole.trajectory_t_s[i]) <= opt.epoch_tolerance_s) crlb.Add(s, state);
    }
    peak = std::max(peak, crlb.window_items());
  }
  EXPECT_LE(peak, 100u + pass.sensors.size());
  EXPECT_GT(crlb.folded_epochs(), 0u);
  const Localization b = RunEkfBounded(pass, opt, capped);
  const double ratio = RmsBound(b) / RmsBound(whole);
  RecordProperty("cap100_over_whole_bound", std::to_string(ratio));
  EXPECT_GT(ratio, 1.0 / 1.2);
  EXPECT_LT(ratio, 1.2);
}

// What a stream keeps after N and after 10 N s of a racetrack survey: the
// same in bounded mode (the reorder buffer is empty after each item here:
// reorder delay 0), 10× in unbounded mode (so this test can fail).
TEST(LocalizerBounded, NothingKeptGrowsWithUptime) {
  const test::Racetrack d = test::SimulateRacetrack(4000.0);
  const auto retained_at = [&d](bool bounded, double until_s) {
    StreamOptions so;
    so.reorder_delay_s = 0.0;
    so.bounded = bounded;
    StreamingLocalizer s(d.pass.vessel, d.pass.sensors, LocalizerOptions{}, so);
    std::size_t g = 0, peak = 0;
    for (const MagSample& m : d.pass.samples) {
      if (m.t_s > until_s) break;
      while (g < d.pass.gnss.size() && d.pass.gnss[g].t_s <= m.t_s) s.Add(d.pass.gnss[g++]);
      s.Add(m);
      peak = std::max(peak, s.retained_items());
    }
    EXPECT_TRUE(s.initialized());
    EXPECT_GT(s.consumed(), 0.8 * 13.0 * until_s);  // 12 samples + 1 fix per s
    return std::make_pair(s.retained_items(), peak);
  };
  const auto [b1, b1_peak] = retained_at(true, 400.0);
  const auto [b10, b10_peak] = retained_at(true, 4000.0);
  RecordProperty("bounded_retained_400s", std::to_string(b1));
  RecordProperty("bounded_retained_4000s", std::to_string(b10));
  EXPECT_LE(b10_peak, b1_peak + 20);  // one epoch more or less in the window
  EXPECT_LE(b10_peak, 61u * 13u + 20u);  // lag 60 s of items
  const auto [u1, u1_peak] = retained_at(false, 400.0);
  const auto [u10, u10_peak] = retained_at(false, 4000.0);
  EXPECT_GT(u10, 9 * u1);  // the unbounded stream keeps everything
  (void)u1_peak;
  (void)u10_peak;
}

// Held out, long: the racetrack survey for 2 h 5 min of data (23 loops).
// Bounded vs unbounded EKF vs offline batch (about 5 s). Figures:
// docs/ACCURACY.md; run alone:
//   build/bin/localizer_bounded_test --gtest_filter='*TwoHour*' --gtest_output=xml:/tmp/bounded.xml
TEST(LocalizerBounded, TwoHourRacetrackWithinOnePointTwoOfBatchAndBound) {
  const test::Racetrack d = test::SimulateRacetrack(7500.0);
  const LocalizerOptions opt;
  const Localization a = RunEkf(d.pass, opt);
  const Localization b = RunEkfBounded(d.pass, opt);
  const Localization c = SolveBatch(d.pass, opt, &a);
  double deploy = 0.0;
  for (std::size_t j = 0; j < d.truth.size(); ++j) deploy += (d.pass.sensors[j].p_SinW_m.head<2>() - d.truth[j]).squaredNorm();
  RecordProperty("deployment_rmse_m", std::to_string(std::sqrt(deploy / static_cast<double>(d.truth.size()))));
  RecordProperty("ekf_rmse_m", std::to_string(Rmse(a, d.truth)));
  RecordProperty("bounded_rmse_m", std::to_string(Rmse(b, d.truth)));
  RecordProperty("batch_rmse_m", std::to_string(Rmse(c, d.truth)));
  RecordProperty("ekf_rms_bound_m", std::to_string(RmsBound(a)));
  RecordProperty("bounded_rms_bound_m", std::to_string(RmsBound(b)));
  RecordProperty("batch_rms_bound_m", std::to_string(RmsBound(c)));
  RecordProperty("ekf_time_s", std::to_string(a.summary.solve_time_s + a.summary.crlb_time_s));
  RecordProperty("bounded_time_s", std::to_string(b.summary.solve_time_s + b.summary.crlb_time_s));
  RecordProperty("batch_time_s", std::to_string(c.summary.solve_time_s + c.summary.crlb_time_s));
  EXPECT_TRUE(c.summary.converged) << c.summary.BriefReport();
  EXPECT_LE(Rmse(b, d.truth), 1.2 * Rmse(c, d.truth));
  EXPECT_LT(RmsBound(b) / RmsBound(a), 1.2);
  EXPECT_GT(RmsBound(b) / RmsBound(a), 1.0 / 1.2);
}

}  // namespace
}  // namespace magnav::localizer
