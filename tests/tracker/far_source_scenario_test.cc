// The far source (tracker/far_source.h, on by default) in the window
// tracker on the held-out far-ship scenario (tests/data/generated/scenarios/
// heldout/far_ship.toml: an AUV crosses a 3 × 3 grid while a 4.2e5 A·m²
// ship passes 114 m off its edge): with the ship's B removed the AUV keeps
// one id and its RMS falls from 0.54 m (the defaults; docs/ACCURACY.md, "A
// far ship as a dipole outside the array") to 0.03 m.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "magnav/cli/scenario_file.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"
#include "test_data.h"
#include "two_vessels.h"

namespace magnav::tracker {
namespace {

// A committed scenario (tests/data/generated/scenarios/NAME.toml) through the
// window tracker with `opt`, scored against its truth and printed.
auto WindowScores(const std::string& name, const MultiTrackerOptions& opt, const std::string& what) {
  const FieldScenario sc =
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/" + name + ".toml");
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, opt);
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  const auto s = magnav::testing::ScoreField(sc, f, rows);
  magnav::testing::PrintFieldScores((name + ", " + what).c_str(), s);
  return s;
}

TEST(FarSourceScenario, WindowKeepsTheAuvOnTrackWhileAFarShipPasses) {
  const FieldScenario sc =
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/heldout/far_ship.toml");
  const SimulatedField f = SimulateField(sc);
  MultiTrackerOptions opt;
  opt.far_source.enabled = true;
  MultiTracker tracker(sc.B0, opt);
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  const auto s = magnav::testing::ScoreField(sc, f, rows);
  magnav::testing::PrintFieldScores("held-out far ship, far source on, window", s);
  EXPECT_GE(s.coverage[0], 0.8);  // the issue's; measured 0.915 (defaults 0.61)
  EXPECT_EQ(s.ids[0], 1u);        // defaults: 2
  EXPECT_LE(s.rms[0], 0.065);     // m, measured 0.032 (defaults 0.542)
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
  // The fit is the ship's: outside the bound, of a ship's moment.
  const FarSourceModel& m = tracker.FarSource();
  ASSERT_TRUE(m.valid);
  EXPECT_GT(m.d_m, m.min_range_m + 5.0);
  EXPECT_GT(m.m_W.norm(), 1e5);
}

// fresh_farsrc/far_ship_150 (blind when the far source was written; its
// failure diagnosed since): a 4.5e5 A·m² ship comes north from 330 m south of
// abeam, 150 m off the grid's eastern edge, while an AUV crosses the grid.
// With the fit's first form (Huber loss) the far source went to a wrong basin
// or against its bound while the ship was still 200–300 m along its line —
// the AUV's B at the sensors beside it outweighed the ship's 2–6 nT — and
// the AUV's track took the ship's B: RMS 0.37 m (window). With the Cauchy
// loss the ship is found by ~50 s and the AUV's RMS is within the target.
// (Since session 20 the AUV's B from before its track is given back to the
// kept samples by default, FarSourceOptions::back_predict_new_tracks, which
// also mends the Huber form: the first form is compared with it off.)
TEST(FarSourceScenario, WindowFindsAShipStillFarAlongItsLineWhileAnAuvPasses) {
  const FieldScenario sc =
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/fresh_farsrc/far_ship_150.toml");
  const SimulatedField f = SimulateField(sc);
  const auto run = [&](LossType loss, bool back_predict, MultiSummary* summary) {
    MultiTrackerOptions opt;
    opt.far_source.loss = loss;
    opt.far_source.back_predict_new_tracks = back_predict;
    MultiTracker tracker(sc.B0, opt);
    const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
    *summary = tracker.summary();
    return magnav::testing::ScoreField(sc, f, rows);
  };
  MultiSummary now, huber;
  ASSERT_EQ(MultiTrackerOptions{}.far_source.loss, LossType::kCauchy);
  ASSERT_TRUE(MultiTrackerOptions{}.far_source.back_predict_new_tracks);
  const auto s = run(LossType::kCauchy, true, &now);
  magnav::testing::PrintFieldScores("fresh_farsrc/far_ship_150, window, the defaults (Cauchy loss)", s);
  const auto h = run(LossType::kHuber, false, &huber);
  magnav::testing::PrintFieldScores("fresh_farsrc/far_ship_150, window, the first form (Huber loss, nothing given back)", h);
  std::printf("%s\n%s\n", now.far_source.BriefReport().c_str(), huber.far_source.BriefReport().c_str());
  EXPECT_GE(s.coverage[0], 0.8);  // measured 0.91
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_LE(s.rms[0], 0.3);  // m, the target; measured 0.239 (session 19: 0.25; the first form 0.366)
  EXPECT_GT(h.rms[0], 0.3);  // what the loss is for
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  // The summary says it acted: accepted fits, most of the time modelled,
  // and the last accepted fit near the ship.
  const FarSourceStats& st = now.far_source;
  EXPECT_TRUE(now.far_source_enabled);
  EXPECT_GT(st.num_accepted, 0);
  EXPECT_GT(st.active_s, 100.0);  // s of the 206 s of data
  ASSERT_TRUE(st.has_accepted);
  const auto& ship = f.truth[1];
  const auto at = std::min_element(ship.begin(), ship.end(), [&](const VesselTruth& a, const VesselTruth& b) {
    return std::abs(a.t_s - st.last_t_s) < std::abs(b.t_s - st.last_t_s);
  });
  // The last accepted fit is at the end of the data, the ship ~380 m away
  // (its position poorly held there: 78 m off, 312 m from the centroid):
  // on the ship's bearing from the sensors' centroid (measured 3° off).
  const double bearing_true = std::atan2(at->p_VinW.y(), at->p_VinW.x());
  const double bearing_fit = std::atan2(st.last_p_W.y(), st.last_p_W.x());
  EXPECT_LT(std::abs(std::remainder(bearing_fit - bearing_true, 2.0 * M_PI)), 20.0 * M_PI / 180.0);
  EXPECT_GT(st.last_range_m, 86.4 + 5.0);  // outside the bound
}

// fresh_ghost2/far_ship_120: a weak AUV (tensor SNR 10–20 at 11–13 m) crosses
// the grid while a 4.5e5 A·m² ship 120 m off is still far along its line. The
// far source's fits are a mirror of the ship, then refused at the bound, until
// ~60 s, and 1.5–9 nT of the ship's B at the AUV's sensors is left or removed
// wrongly while its track starts (docs/ACCURACY.md, "A weak AUV beside a far
// ship: the window's failures and an allowance for the unexplained far
// field"). With that far field's allowance in σ_B
// (FarSourceOptions::unexplained_sigma_T, 3 nT; an option, off) the start and
// the track lean on the tensor: window RMS within 15 m 0.109 m (0.336 m off,
// 0.028 m with the ship taken out of the scenario).
TEST(FarSourceScenario, WindowWithTheUnexplainedFarFieldKeepsAWeakAuvOnTrack) {
  MultiTrackerOptions opt;
  opt.far_source.unexplained_sigma_T = 3e-9;
  const auto s = WindowScores("fresh_ghost2/far_ship_120", opt, "window, --far-unexplained-sigma 3e-9");
  EXPECT_GE(s.coverage[0], 0.8);  // measured 0.88
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_LE(s.rms[0], 0.2);  // m, measured 0.109 (a 2x regression fails; the target is 0.3)
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
}

// fresh_farsrc3/far_ship_112: a weak 1.6e3 A·m² AUV 8.6 m from its sensors
// while a 4.4e5 A·m² ship passes 112 m off. At 52–57 s the far source fits
// the ship, still far along its line, against the bound with a ship's moment
// (2.4e5–4.2e5 A·m²; its B within 1.5–2.4 nT of the ship's), and the default
// refuses it: the ship's 11–24 nT is left in the samples until 65 s and the
// window's AUV is 1.5–2.3 m off there (docs/ACCURACY.md, "Far-ship files that
// still failed"). With such fits accepted (FarSourceOptions::
// bound_accept_moment_Am2 2e5; an option, off) the window RMS is 0.241 m
// (0.516 m off, 0.037 m with the ship taken out of the scenario).
TEST(FarSourceScenario, WindowAcceptsAShipAtTheBoundBesideAWeakAuv) {
  MultiTrackerOptions opt;
  opt.far_source.bound_accept_moment_Am2 = 2e5;
  const auto s = WindowScores("fresh_farsrc3/far_ship_112", opt, "window, --far-bound-accept-moment 2e5");
  EXPECT_GE(s.coverage[0], 0.8);  // measured 0.90
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_LE(s.rms[0], 0.35);  // m, measured 0.241, 0.516 with the default (a 2x regression fails; the target is 0.3)
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
}

// fresh_farsrc4/crossing_far_ship_141 (blind in session 17, where it failed
// with every setting): two AUVs crossing 6.4 m apart while a 4.7e5 A·m² ship
// passes 140 m off. Their B from before their tracks sat in the far source's
// 60 s window, so its fits were off (docs/ACCURACY.md, "Far-ship files that
// still failed"; "The AUV's B from before its track in the far source's
// samples"). With each kept sample given the later tracks' back-predicted
// field (FarSourceOptions::back_predict_new_tracks; on by default since
// session 20) the window's RMS is 0.162 / 0.174 m (session 18's form 0.145 /
// 0.158 m; without it 1.13 / 0.43 m).
TEST(FarSourceScenario, WindowKeepsACrossingPairBesideAShipWithTheirEarlierBGivenBack) {
  const MultiTrackerOptions opt;  // the defaults
  EXPECT_TRUE(opt.far_source.back_predict_new_tracks);
  const auto s = WindowScores("fresh_farsrc4/crossing_far_ship_141", opt, "window, the defaults");
  for (int v = 0; v < 2; ++v) {
    SCOPED_TRACE(v);
    EXPECT_GE(s.coverage[v], 0.8);  // measured 0.98 / 1.00
    EXPECT_EQ(s.ids[v], 1u);
    EXPECT_LE(s.rms[v], 0.3);  // m, the target; measured 0.162 / 0.174 (a 2x regression fails)
  }
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
}

}  // namespace
}  // namespace magnav::tracker
