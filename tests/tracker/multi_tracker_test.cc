// The multi-vessel tracker on a field built here (two_vessels.h: two
// AUV-sized vessels cross a 3x3 gradiometer grid at the same time, 50-60 m
// apart; held-out: the management defaults were chosen on the reference
// field, not on this one).
// Scored against the simulator's truth (not the tracker's helpers): one track
// per vessel, coverage near the sensors, RMS, no false rows.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

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
// second one starts once the ship is tracked, with the ship's model error in
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
  EXPECT_LE(w.ids[0], 2u);
  EXPECT_GE(w.coverage[0], 0.75);  // measured 0.820
  EXPECT_LE(w.rms[0], 0.44);       // measured 0.220 m (0.298 m with the far source off)
  // Measured 0 with the default end rule (out_of_reach_s 2 s, since
  // 2026-11-26); 172 (9.3 %) without it: the second AUV track drifted as the AUV left.
  EXPECT_LE(static_cast<double>(w.false_rows), 0.05 * static_cast<double>(w.rows));
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), sc.B0, opt);
  const testing::TrackRows rows = testing::BatchRows(tracks);
  const FieldScores s = ScoreField(sc, f, rows);
  testing::PrintFieldScores("ship arrives, batch", s);
  EXPECT_EQ(tracks.size(), 3u);  // the AUV twice, the ship once
  EXPECT_EQ(s.false_rows, 0u);
  EXPECT_LE(s.ids[0], 2u);
  EXPECT_GE(s.coverage[0], 0.90);  // measured 1.000 (0.970 before the default end rule)
  // m, measured 0.0484 with the defaults of 2026-11-26 evening: 0.0122 with
  // the end rule alone (0.331 before it), 0.0271 after the merges of the residual
  // start and the batch's turn-onset cost (not separated), 0.0484 with the far source on by default
  // too (the ship, once near enough to be a track, is also partly taken by
  // the far source; the window gains: 0.298 -> 0.220 m). Not diagnosed further.
  EXPECT_LE(s.rms[0], 1.5 * 0.0484);
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
