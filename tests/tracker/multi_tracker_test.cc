// The multi-vessel tracker on a field built here (two_vessels.h: two
// AUV-sized vessels cross a 3x3 gradiometer grid at the same time, 50-60 m
// apart; held-out: the management defaults were chosen on the reference
// field, not on this one).
// Scored against the simulator's truth (not the tracker's helpers): one track
// per vessel, coverage near the sensors, RMS, no false rows.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "magnav/core/error.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"
#include "two_vessels.h"

namespace magnav::tracker {
namespace {

using testing::FieldScores;
using testing::ScoreField;

TEST(MultiTracker, WindowFollowsTwoVesselsWithOneTrackEach) {
  const FieldScenario sc = testing::TwoVesselScenario();
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, MultiTrackerOptions{});
  const testing::TrackRows rows = testing::WindowRows(&tracker, f.samples);
  const FieldScores s = ScoreField(sc, f, rows);
  testing::PrintFieldScores("window", s);
  EXPECT_EQ(tracker.Tracks().size(), 2u);
  EXPECT_EQ(s.false_rows, 0u);
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v;
    EXPECT_GE(s.coverage[v], 0.85) << "vessel " << v;  // measured 0.908, 0.907
    EXPECT_LE(s.rms[v], 0.04) << "vessel " << v;       // measured 0.0135, 0.0231 m
  }
}

// The windows' turn-onset counts (MultiSummary::turn_onset; docs/ACCURACY.md,
// "The window's turn onset at scale"): the engines' counters summed over
// every engine, live or gone (after Flush every engine is gone). On the two
// vessels with the option on (measured: 1836 rows, 347 window solves, 124
// triggered, 124 tries, 33 of them grid searches, 789 candidates, none
// chosen: they go straight). A window solve emits its epochs since the last
// (5 at 10 Hz every 0.5 s), so the rows are at most 5 per window solve plus
// the back-filled start rows (at most one window, 201, per track): an engine
// left out of the sum fails it. ~1.7 s.
TEST(MultiTracker, TurnOnsetCountsSumEveryEngine) {
  const FieldScenario sc = testing::TwoVesselScenario();
  const SimulatedField f = SimulateField(sc);
  MultiTrackerOptions opt;
  opt.track.window_turn_onset_model = true;
  MultiTracker tracker(sc.B0, opt);
  const testing::TrackRows rows = testing::WindowRows(&tracker, f.samples);
  const TurnOnsetCounts& c = tracker.summary().turn_onset;
  std::cout << "turn onset on: " << rows.size() << " rows, " << c.window_solves << " window solves, " << c.triggered
            << " triggered, " << c.tries << " tries (" << c.grid_searches << " grid), " << c.candidate_solves
            << " candidates, " << c.chosen << " chosen\n";
  EXPECT_GT(c.window_solves, 0);
  EXPECT_LE(rows.size(), 5u * static_cast<std::size_t>(c.window_solves) + 2u * 201u);
  EXPECT_GT(c.tries, 0);
  EXPECT_LE(c.tries, c.window_solves);
  EXPECT_LE(c.triggered, c.window_solves);
  EXPECT_LE(c.grid_searches, c.tries);
  EXPECT_GE(c.candidate_solves, c.tries);
  EXPECT_GE(c.iterations, c.candidate_solves / 2);
  EXPECT_EQ(c.noise_vetoes, 0);  // the noise test is off by default
}

TEST(MultiTracker, BatchRefinesEveryVessel) {
  const FieldScenario sc = testing::TwoVesselScenario();
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions opt;
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), sc.B0, opt);
  const testing::TrackRows rows = testing::BatchRows(tracks);
  const FieldScores s = ScoreField(sc, f, rows);
  testing::PrintFieldScores("batch", s);
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(s.false_rows, 0u);
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v;
    EXPECT_GE(s.coverage[v], 0.93) << "vessel " << v;  // measured 0.992, 0.974
    EXPECT_LE(s.rms[v], 0.017) << "vessel " << v;      // measured 0.0087, 0.0108 m
  }
}

// Held out, a known limit measured (docs/ACCURACY.md, "Several vessels"): an
// AUV crosses a 3x3 field when a ship appears 190 m off. The ship's far B
// (tens of nT at the AUV's sensors, little tensor) spoils the AUV's fit
// before the ship has a track: the AUV's window track ends ("missed") and a
// second one starts once the ship is tracked (under the first one's id since
// re-acquisition, 2026-11-27), with the ship's model error in
// its B (0.3 m RMS where a lone AUV gets 0.02 m). The batch keeps the AUV
// covered with no false rows. Detection on the tensor alone would keep one
// id but, with B still used by the solver, costs accuracy on the reference
// field (its vessel 2: 0.05 -> 0.35 m): not done; a per-sensor B bias
// estimated with the tracks is the way, left open.
TEST(MultiTracker, FarShipArrivingWhileAnAuvIsTracked) {
  FieldScenario sc;
  sc.sensors = SensorGrid(3, 3, 40.0);
  FieldVessel auv;
  auv.vessel_id = 1;
  auv.moment_body = {2200.0, -200.0, 700.0};
  auv.start_position = {-100.0, -38.0, -5.5};
  auv.start_heading_rad = 0.0;
  auv.speed_mps = 1.2;
  auv.segments = {{170.0, 0.0}};
  FieldVessel ship;
  ship.vessel_id = 2;
  ship.moment_body = {350000.0, 40000.0, 180000.0};
  ship.start_position = {-62.0, 140.0, -12.0};
  ship.start_heading_rad = -M_PI / 2;
  ship.speed_mps = 2.5;
  ship.segments = {{110.0, 0.0}};
  ship.t_start_s = 90.0;
  sc.vessels = {auv, ship};
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 23;
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions opt;
  MultiTracker window(sc.B0, opt);
  const testing::TrackRows wrows = testing::WindowRows(&window, f.samples);
  const FieldScores w = ScoreField(sc, f, wrows);
  testing::PrintFieldScores("ship arrives, window", w);
  // One id since re-acquisition (reacquire.h, on by default since
  // 2026-11-27): the AUV's second track continues its first (2 ids before).
  EXPECT_EQ(w.ids[0], 1u);
  EXPECT_GE(w.coverage[0], 0.75);  // measured 0.820
  EXPECT_LE(w.rms[0], 0.44);       // measured 0.220 m (0.298 m with the far source off)
  // Measured 0 with the default end rule (out_of_reach_s 2 s, since
  // 2026-11-26); 172 (9.3 %) without it: the second AUV track drifted as the AUV left.
  EXPECT_LE(static_cast<double>(w.false_rows), 0.05 * static_cast<double>(w.rows));
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), sc.B0, opt);
  const testing::TrackRows rows = testing::BatchRows(tracks);
  const FieldScores s = ScoreField(sc, f, rows);
  testing::PrintFieldScores("ship arrives, batch", s);
  EXPECT_EQ(tracks.size(), 2u);  // the AUV once (its second track re-acquired: 3 before), the ship once
  EXPECT_EQ(s.false_rows, 0u);
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_GE(s.coverage[0], 0.90);  // measured 1.000 (0.970 before the default end rule)
  // m, measured 0.0484 with the defaults of 2026-11-26 evening: 0.0122 with
  // the end rule alone (0.331 before it), 0.0271 after the merges of the residual
  // start and the batch's turn-onset cost (not separated), 0.0484 with the far source on by default
  // too (the ship, once near enough to be a track, is also partly taken by
  // the far source; the window gains: 0.298 -> 0.220 m). Not diagnosed further.
  // 0.0165 m since re-acquisition: the batch refines one path over both of
  // the AUV's window tracks.
  EXPECT_LE(s.rms[0], 1.5 * 0.0165);
}

// An overtaking pair built here (not a scored scenario file): the fast AUV
// leaves the 3x3 grid first and its window track ends "out_of_reach" while its
// B is still tens of σ_B at the sensors the slow track uses. Without the ghost
// field (TrackManagementOptions::ghost_field_s = 0; 30 s by default) that B is in
// the slow track's samples unmodelled and its error grows; with it the ended
// track's predicted field is subtracted from them (and nothing is published
// for it). The slow vessel's RMS over the 15 s after the fast track's end:
// 0.36 m without, 0.023 m with (the figures below).
struct OvertakingRun {
  double t_fast_end_s = -1.0;
  double slow_rms_after_m = 0.0;  // the slow vessel's rows in [end, end + 15 s]
  std::size_t rows_after = 0, fast_rows_after = 0, false_rows = 0;
};

OvertakingRun RunOvertaking(double ghost_field_s) {
  FieldScenario sc;
  sc.sensors = SensorGrid(3, 3, 36.0);
  FieldVessel slow;
  slow.vessel_id = 1;
  slow.moment_body = {1900.0, -250.0, 850.0};
  slow.start_position = {-45.0, 5.0, -5.0};
  slow.speed_mps = 0.8;
  slow.segments = {{95.0, 0.0}};
  FieldVessel fast;
  fast.vessel_id = 2;
  fast.moment_body = {2300.0, 350.0, 650.0};
  fast.start_position = {-80.0, -4.0, -5.0};
  fast.speed_mps = 1.8;
  fast.segments = {{95.0, 0.0}};
  sc.vessels = {slow, fast};
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 29;
  const SimulatedField f = SimulateField(sc);
  MultiTrackerOptions opt;
  opt.management.ghost_field_s = ghost_field_s;
  MultiTracker tracker(sc.B0, opt);
  const testing::TrackRows rows = testing::WindowRows(&tracker, f.samples);
  const FieldScores scores = ScoreField(sc, f, rows);
  OvertakingRun run;
  run.false_rows = scores.false_rows;
  for (const TrackEvent& e : tracker.TakeEvents()) {
    if (e.kind == TrackEvent::Kind::kEnded && e.reason.rfind("out_of_reach", 0) == 0 && run.t_fast_end_s < 0.0) {
      run.t_fast_end_s = e.t_s;
    }
  }
  if (run.t_fast_end_s < 0.0) return run;
  std::map<long long, Eigen::Vector3d> truth_slow, truth_fast;
  for (const auto& t : f.truth[0]) truth_slow[std::llround(t.t_s * 10.0)] = t.p_VinW;
  for (const auto& t : f.truth[1]) truth_fast[std::llround(t.t_s * 10.0)] = t.p_VinW;
  double sum_sq = 0.0;
  for (const auto& [id, e] : rows) {
    if (e.t_s < run.t_fast_end_s || e.t_s > run.t_fast_end_s + 15.0) continue;
    const long long k = std::llround(e.t_s * 10.0);
    const auto fast_at = truth_fast.find(k);
    if (fast_at != truth_fast.end() && (e.p_VinW - fast_at->second).norm() < 5.0) ++run.fast_rows_after;
    const auto it = truth_slow.find(k);
    if (it == truth_slow.end() || (e.p_VinW - it->second).norm() > 5.0) continue;
    sum_sq += (e.p_VinW - it->second).squaredNorm();
    ++run.rows_after;
  }
  run.slow_rms_after_m = run.rows_after > 0 ? std::sqrt(sum_sq / static_cast<double>(run.rows_after)) : 1e300;
  std::printf("ghost_field_s %g: fast track ended out of reach at %.1f s; slow vessel RMS %.4f m over %zu rows in the "
              "15 s after; %zu rows at the fast vessel after; %zu false rows\n",
              ghost_field_s, run.t_fast_end_s, run.slow_rms_after_m, run.rows_after, run.fast_rows_after,
              run.false_rows);
  return run;
}

TEST(MultiTracker, AnEndedTracksGhostFieldIsSubtractedFromAnotherTracksSamples) {
  const OvertakingRun off = RunOvertaking(0.0);
  const OvertakingRun on = RunOvertaking(30.0);
  ASSERT_GT(off.t_fast_end_s, 0.0);
  ASSERT_GT(on.t_fast_end_s, 0.0);
  EXPECT_EQ(on.t_fast_end_s, off.t_fast_end_s);  // the same track ends at the same epoch
  ASSERT_GT(on.rows_after, 100u);
  // Measured (2026-11-27): the fast track ends at 79.8 s in both runs; the slow vessel's RMS over the 15 s after
  // is 0.3605 m without the ghost, 0.0233 m with it (151 rows each).
  EXPECT_GE(off.slow_rms_after_m, 0.15);
  EXPECT_LE(on.slow_rms_after_m, 0.045);
  EXPECT_LE(on.slow_rms_after_m, 0.25 * off.slow_rms_after_m);
  // The ghost publishes nothing: no row at the fast vessel after its end, no false row added.
  EXPECT_EQ(on.fast_rows_after, 0u);
  EXPECT_LE(on.false_rows, off.false_rows);
  MultiTrackerOptions bad;
  std::string why;
  bad.management.ghost_field_s = -1.0;
  EXPECT_FALSE(bad.IsValid(&why));
  bad.management.ghost_field_s = 30.0;
  bad.management.ghost_b_snr = 0.0;
  EXPECT_FALSE(bad.IsValid(&why));
}

TEST(MultiTracker, OptionsAreChecked) {
  MultiTrackerOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.management.confirm_m = 11;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THROW(MultiTracker(Eigen::Vector3d::Zero(), o), InputError);
}

}  // namespace
}  // namespace magnav::tracker
