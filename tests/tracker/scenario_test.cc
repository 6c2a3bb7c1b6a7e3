// The multi-vessel tracker on a committed harbour-like scenario it was not
// tuned on (tests/data/generated/scenarios/heldout/crossing.toml: two AUVs
// on perpendicular paths over a 3x3 grid, closest approach to each other
// 8.5 m), held to the issue 24 targets (coverage >= 0.8 window / 0.9 batch,
// one id per vessel, <= 5 % false rows) and to 1.5x its measured RMS
// (docs/ACCURACY.md, "Harbour-like scenarios"); and the held-out abreast
// pair (below). The other kinds fail the targets today (that table); they
// are not asserted here.
#include <gtest/gtest.h>

#include <string>

#include "magnav/cli/scenario_file.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"
#include "test_data.h"
#include "two_vessels.h"

namespace magnav::tracker {
namespace {

FieldScenario HeldOut(const std::string& kind) {
  return cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/heldout/" + kind + ".toml");
}
FieldScenario HeldOutCrossing() { return HeldOut("crossing"); }

TEST(HarbourScenario, WindowTracksTheHeldOutCrossing) {
  const FieldScenario sc = HeldOutCrossing();
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, MultiTrackerOptions{});
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  const auto s = magnav::testing::ScoreField(sc, f, rows);
  magnav::testing::PrintFieldScores("held-out crossing, window", s);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0522);  // m, measured 0.0522 (coverage 0.933)
  EXPECT_LE(s.rms[1], 1.5 * 0.0456);  // m, measured 0.0456 (coverage 0.895)
}

TEST(HarbourScenario, BatchTracksTheHeldOutCrossing) {
  const FieldScenario sc = HeldOutCrossing();
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions opt;
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), sc.B0, opt);
  const auto s = magnav::testing::ScoreField(sc, f, magnav::testing::BatchRows(tracks));
  magnav::testing::PrintFieldScores("held-out crossing, batch", s);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.9) << "vessel " << v + 1;
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0179);  // m, measured 0.0179 (coverage 0.992)
  EXPECT_LE(s.rms[1], 1.5 * 0.0174);  // m, measured 0.0174 (coverage 0.952)
}


// Two AUVs abreast 24 m apart, symmetric about the middle sensor column
// (heldout/abreast.toml): only that column sees them, each of its samples is
// the sum of both. Before the dipole misfit gate and the two-dipole start
// (InitOptions::max_dipole_misfit, InitializePair) no vessel got a track and
// every row was false (docs/ACCURACY.md, "Harbour-like scenarios").
TEST(HarbourScenario, WindowStartsOneTrackPerVesselAbreast) {
  const FieldScenario sc = HeldOut("abreast");
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, MultiTrackerOptions{});
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  const auto s = magnav::testing::ScoreField(sc, f, rows);
  magnav::testing::PrintFieldScores("held-out abreast, window", s);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    // Below the 0.8: the pair starts once 20 s of mixed samples are
    // buffered. A 2x regression (0.39) fails.
    EXPECT_GE(s.coverage[v], 0.65) << "vessel " << v + 1;  // measured 0.784 / 0.784
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0557);  // m, measured 0.0557
  EXPECT_LE(s.rms[1], 1.5 * 0.0471);  // m, measured 0.0471
}

TEST(HarbourScenario, BatchStartsOneTrackPerVesselAbreast) {
  const FieldScenario sc = HeldOut("abreast");
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions opt;
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), sc.B0, opt);
  const auto s = magnav::testing::ScoreField(sc, f, magnav::testing::BatchRows(tracks));
  magnav::testing::PrintFieldScores("held-out abreast, batch", s);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    // Just below the 0.9 (measured 0.896 / 0.896); a 2x regression fails.
    EXPECT_GE(s.coverage[v], 0.75) << "vessel " << v + 1;
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0299);  // m, measured 0.0299
  EXPECT_LE(s.rms[1], 1.5 * 0.0370);  // m, measured 0.0370
}
}  // namespace
}  // namespace magnav::tracker
