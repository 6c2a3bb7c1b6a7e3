// The multi-vessel tracker on a committed harbour-like scenario it was not
// tuned on (tests/data/generated/scenarios/heldout/crossing.toml: two AUVs
// on perpendicular paths over a 3x3 grid, closest approach to each other
// 8.5 m), held to the issue 24 targets (coverage >= 0.8 window / 0.9 batch,
// one id per vessel, <= 5 % false rows) and to 1.5x its measured RMS
// (docs/ACCURACY.md, "Harbour-like scenarios"); and the held-out abreast
// pair (below), held to the same targets; and the held-out far-ship and
// drift scenarios' false rows (below).
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "magnav/cli/scenario_file.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"
#include "test_data.h"
#include "short_overtaking.h"
#include "two_vessels.h"

namespace magnav::tracker {
namespace {

FieldScenario HeldOut(const std::string& kind) {
  return cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/heldout/" + kind + ".toml");
}
FieldScenario HeldOutCrossing() { return HeldOut("crossing"); }

// The field scores (track_metrics.h) of the window tracker (as magnav-tracker)
// and of the batch (as `magnav track`) on a scenario, printed under `name`.
// The mean position NEES (eᵀP⁻¹e, 3 dof, the rows' full 3 × 3 covariance)
// per vessel over each track's rows from `from_s` to `to_s` after its first
// row — e.g. 0–5 s: a pair start's rows before its refit (pair_refit_s =
// 5 s). Each row goes to the vessel nearest it (within 5 m); NaN for a
// vessel without rows.
std::vector<double> NeesOver(const SimulatedField& f, double rate_hz, const magnav::testing::TrackRows& rows,
                             double from_s, double to_s) {
  std::map<std::uint32_t, double> first;
  for (const auto& [id, e] : rows) {
    if (e.usable && e.has_covariance && !first.count(id)) first[id] = e.t_s;
  }
  const auto truth_at = [&](std::size_t v, double t) -> const VesselTruth* {
    const long long k = std::llround(t * rate_hz);
    for (const auto& q : f.truth[v]) {
      if (std::llround(q.t_s * rate_hz) == k) return &q;
    }
    return nullptr;
  };
  std::vector<double> sum(f.truth.size(), 0.0), n(f.truth.size(), 0.0);
  for (const auto& [id, e] : rows) {
    if (!e.usable || !e.has_covariance || e.t_s < first[id] + from_s || e.t_s > first[id] + to_s) continue;
    std::size_t best_v = f.truth.size();
    double best = 5.0;
    for (std::size_t v = 0; v < f.truth.size(); ++v) {
      const VesselTruth* q = truth_at(v, e.t_s);
      if (q != nullptr && (e.p_VinW - q->p_VinW).norm() <= best) {
        best = (e.p_VinW - q->p_VinW).norm();
        best_v = v;
      }
    }
    if (best_v == f.truth.size()) continue;
    const Eigen::Vector3d err = e.p_VinW - truth_at(best_v, e.t_s)->p_VinW;
    const Eigen::Matrix3d P = e.cov_state.topLeftCorner<3, 3>();
    sum[best_v] += err.dot(P.ldlt().solve(err));
    n[best_v] += 1.0;
  }
  std::vector<double> out;
  for (std::size_t v = 0; v < sum.size(); ++v) out.push_back(n[v] > 0 ? sum[v] / n[v] : std::nan(""));
  return out;
}

// χ²(3) 0.99 quantile.
constexpr double kChi2Dof3P99 = 11.345;

magnav::testing::FieldScores ScoreWindow(const FieldScenario& sc, const std::string& name,
                                         std::vector<double>* early_nees = nullptr,
                                         const MultiTrackerOptions& options = MultiTrackerOptions{}) {
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, options);
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  const auto s = magnav::testing::ScoreField(sc, f, rows);
  magnav::testing::PrintFieldScores((name + ", window").c_str(), s);
  if (early_nees != nullptr) {
    *early_nees = NeesOver(f, sc.rate_hz, rows, 0.0, 5.0);
    std::printf("%s, window: mean position NEES over each track's first 5 s:", name.c_str());
    for (double x : *early_nees) std::printf(" %.2f", x);
    std::printf("\n");
  }
  return s;
}
magnav::testing::FieldScores ScoreBatch(const FieldScenario& sc, const std::string& name) {
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions opt;
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), sc.B0, opt);
  const auto s = magnav::testing::ScoreField(sc, f, magnav::testing::BatchRows(tracks));
  magnav::testing::PrintFieldScores((name + ", batch").c_str(), s);
  return s;
}

TEST(HarbourScenario, WindowTracksTheHeldOutCrossing) {
  const auto s = ScoreWindow(HeldOutCrossing(), "held-out crossing");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0522);  // m, measured 0.0522 (coverage 0.933)
  EXPECT_LE(s.rms[1], 1.5 * 0.0456);  // m, measured 0.0456 (coverage 0.895)
}

TEST(HarbourScenario, BatchTracksTheHeldOutCrossing) {
  const auto s = ScoreBatch(HeldOutCrossing(), "held-out crossing");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.9) << "vessel " << v + 1;
  }
  // m; measured 0.0179 / 0.0174 (coverage 0.99 / 0.95) before the batch over all the evidence,
  // 0.0245 / 0.0155 (coverage 1.00 / 1.00) after it (docs/ACCURACY.md, "Single-vessel passes").
  EXPECT_LE(s.rms[0], 1.5 * 0.0179);
  EXPECT_LE(s.rms[1], 1.5 * 0.0174);
}


// Two AUVs abreast 24 m apart, symmetric about the middle sensor column
// (heldout/abreast.toml): only that column sees them, each of its samples is
// the sum of both. Before the dipole misfit gate and the two-dipole start
// (InitOptions::max_dipole_misfit, InitializePair) no vessel got a track and
// every row was false (docs/ACCURACY.md, "Harbour-like scenarios"); with them
// the pair started at 55 s, 9 s after the vessels came within reach
// (coverage 0.784 window and batch, below the 0.8 / 0.9). With the
// approach starts and the pair refit (TrackManagementOptions::pair_refit_s)
// it starts at 51 s and meets the targets (docs/ACCURACY.md,
// "Abreast from when they come within reach"). This file was looked at for
// that change (no longer blind); heldout_abreast/ is the fresh check.
TEST(HarbourScenario, WindowStartsOneTrackPerVesselAbreast) {
  std::vector<double> early;
  const auto s = ScoreWindow(HeldOut("abreast"), "held-out abreast", &early);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // the target; measured 0.873 / 0.873
    // The pair start's rows before its refit: their σ covers their error
    // (the joint fit's marginal: InitialTrack::cov_state). Mean position
    // NEES measured 2.03 / 0.55 (70.1 / 19.8 with the σ given the partner's
    // start, before 2026-11-26's pair-sigma change).
    EXPECT_LE(early[v], kChi2Dof3P99) << "vessel " << v + 1;
  }
  // m, measured 0.107 / 0.0761 (0.0557 / 0.0471 with the later start, 0.238 /
  // 0.224 with the approach starts but no refit); the target is 0.3.
  EXPECT_LE(s.rms[0], 1.5 * 0.107);
  EXPECT_LE(s.rms[1], 1.5 * 0.0761);
}

// The pair refit's coupling in the window's σ
// (TrackManagementOptions::pair_refit_excess; docs/ACCURACY.md, "Two young
// tracks abreast: the pair refit's coupling in the window's σ"). After the
// refit (5 s after the start) each refitted engine takes its partner's field
// as known, so its σ is the one given the partner while their errors are
// the joint fit's. Over the next window_s (rows 5–25 s after each track's
// first) on held-out abreast, noise draws 1–3 of scripts/tracker_calibration
// (seed 1101 × 100 + k), the rows' mean position NEES (3 dof) over both
// vessels and the three draws (the field cut at 80 s): measured 13.19
// without the refit's excess, 3.20 with it (ANEES over 20 draws: the
// calibration table of that section).
TEST(HarbourScenario, WindowCarriesThePairRefitsCouplingInItsSigma) {
  double sum[2] = {0.0, 0.0};
  int n = 0;
  for (int draw = 1; draw <= 3; ++draw) {
    FieldScenario sc = HeldOut("abreast");
    sc.seed = sc.seed * 100 + static_cast<std::uint64_t>(draw);
    // Up to 80 s (the pair starts at 46 s): the rows measured end at 71 s.
    for (FieldVessel& v : sc.vessels) {
      ASSERT_EQ(v.segments.size(), 1u);
      v.segments[0].duration_s = 80.0 - v.t_start_s;
    }
    const SimulatedField f = SimulateField(sc);
    for (const bool on : {false, true}) {
      MultiTrackerOptions o;
      o.management.pair_refit_excess = on;
      MultiTracker tracker(sc.B0, o);
      const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
      const std::vector<double> nees = NeesOver(f, sc.rate_hz, rows, 5.0, 25.0);
      ASSERT_EQ(nees.size(), 2u);
      std::printf("held-out abreast draw %d, window, pair_refit_excess %d: mean position NEES 5-25 s after the "
                  "start %.2f / %.2f\n",
                  draw, on ? 1 : 0, nees[0], nees[1]);
      for (double x : nees) {
        ASSERT_TRUE(std::isfinite(x)) << "draw " << draw;
        sum[on ? 1 : 0] += x;
      }
    }
    n += 2;
  }
  const double without = sum[0] / n, with = sum[1] / n;
  std::printf("mean over draws and vessels: without %.2f, with %.2f\n", without, with);
  EXPECT_LE(with, 1.5 * 3.0);  // 3 = an honest 3-dof mean; measured 3.20
  EXPECT_GE(without, 8.0);     // measured 13.19: the σ given the partner is overconfident
}

// The back-filled start (TrackManagementOptions::backfill_start) of a pair
// start (held-out abreast: both vessels started together at ≈ 51 s): each
// track's rows from its start's first evidence, marked TrackState::kStart,
// all before its confirmation and its first live row, without a gap, as
// close to the truth as the live rows (no false row), beginning ≥ 2 s
// before the confirmation (a two-dipole start's evidence: min_span_s).
TEST(HarbourScenario, WindowBackFillsAPairStartsRows) {
  const FieldScenario sc = HeldOut("abreast");
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, MultiTrackerOptions{});
  std::vector<TrackOutput> out;
  for (const auto& smp : f.samples) {
    for (const auto& x : tracker.AddSample(smp)) out.push_back(x);
  }
  for (const auto& x : tracker.Flush()) out.push_back(x);
  std::map<std::uint32_t, double> confirmed_at;
  for (const TrackEvent& ev : tracker.TakeEvents()) {
    if (ev.kind == TrackEvent::Kind::kStarted) confirmed_at[ev.track_id] = ev.t_s;
  }
  ASSERT_EQ(confirmed_at.size(), 2u);
  std::map<std::uint32_t, double> first_start, last_start, first_live;
  std::map<std::uint32_t, int> start_rows;
  magnav::testing::TrackRows start_only;
  for (const TrackOutput& x : out) {
    const double t = x.estimate.t_s;
    if (x.state != TrackState::kStart) {
      if (!first_live.count(x.track_id)) first_live[x.track_id] = t;
      continue;
    }
    EXPECT_TRUE(x.estimate.usable && x.estimate.has_covariance) << "t = " << t;
    if (!first_start.count(x.track_id)) first_start[x.track_id] = t;
    last_start[x.track_id] = t;
    ++start_rows[x.track_id];
    start_only.emplace_back(x.track_id, x.estimate);
  }
  ASSERT_EQ(start_rows.size(), 2u);
  EXPECT_EQ(magnav::testing::ScoreField(sc, f, start_only).false_rows, 0u);
  for (const auto& [id, n] : start_rows) {
    std::printf("track %u: start rows %.1f-%.1f s, confirmed %.1f s, first live row %.1f s\n", id, first_start[id],
                last_start[id], confirmed_at[id], first_live[id]);
    EXPECT_LT(last_start[id], first_live[id]) << "track " << id;
    EXPECT_LT(last_start[id], confirmed_at[id]) << "track " << id;
    EXPECT_LE(first_start[id], confirmed_at[id] - 2.0) << "track " << id;
    EXPECT_EQ(n, std::lround((first_live[id] - first_start[id]) * sc.rate_hz)) << "track " << id;  // no gap
  }
}

TEST(HarbourScenario, BatchStartsOneTrackPerVesselAbreast) {
  const auto s = ScoreBatch(HeldOut("abreast"), "held-out abreast");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.9) << "vessel " << v + 1;  // the target; measured 1.00 / 1.00
  }
  // m; measured 0.0386 / 0.0522 (0.0324 / 0.0396 with the later start and coverage 0.784).
  EXPECT_LE(s.rms[0], 1.5 * 0.0386);
  EXPECT_LE(s.rms[1], 1.5 * 0.0522);
}

// The fresh held-out abreast pair (heldout_abreast/abreast_20.toml: 20 m
// apart, 9 m and 11 m either side of the middle sensor row; committed
// before it was run), held to the targets. Its window figures were
// measured blind; the batch's partner rule (TrackRecord::partner_id) was
// made after its batch had been seen failing there (coverage 0.89 / 0.94,
// RMS 1.02 m, 10 % false rows), so the batch figure is not blind.
FieldScenario FreshAbreast(const std::string& name) {
  return cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/heldout_abreast/" + name +
                               ".toml");
}

TEST(HarbourScenario, WindowTracksTheFreshAbreastPair) {
  std::vector<double> early;
  const auto s = ScoreWindow(FreshAbreast("abreast_20"), "fresh abreast 20 m", &early);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // measured 0.889 / 0.899
    EXPECT_LE(s.rms[v], 0.3) << "vessel " << v + 1;       // m, measured 0.203 / 0.177
  }
  // As above: measured 16.4 / 8.41 (240 / 269 with the σ given the
  // partner's start). Vessel 1 is still above χ²(3)'s 0.99 quantile (11.3):
  // its start is 0.5 m off, more than the fit's noise explains (not fixed;
  // docs/ACCURACY.md). Held to its figure with the usual margin.
  EXPECT_LE(early[0], 1.5 * 16.4);
  EXPECT_LE(early[1], kChi2Dof3P99);
}

// heldout_abreast/abreast_36.toml: 36 m apart, each 12 m from its own
// sensor row and 24 m from the middle one, whose sensors see the nearer
// vessel strongly and the other's B at ~10 % of it. No sample is mixed
// enough for the two-dipole start: the vessels are started one by one
// (48 s, 49 s), each with the other's field unexplained, and on main each
// track carried its start's error (moment 5–20 % off) to the end of the
// pass: RMS 0.715 / 0.472 m, mean NEES inside the reach 289. With the joint
// start (TrackManagementOptions::joint_start_s) the second start is fitted
// jointly with the first and both are started again from that fit. This
// file was looked at for that change (not blind; fresh_abreast/ is). Vessel
// 1's coverage was 0.73, below the 0.8: its own sensor sees it at
// tensor SNR ≥ 20 (the field initiator's threshold) only from ≈ 43 s and a
// start needs 5 s of fixes and a confirmation, so no live row came before
// ≈ 47.6 s while 0.8 needs them from 46.8 s. With the back-filled start
// (TrackManagementOptions::backfill_start) vessel 1's track, started
// jointly with vessel 2's, also gets the window's smoothed rows from its
// first strong epoch: coverage 0.896 / 0.853 (vessel 2's single start was
// confirmed before the joint start: not back-filled) (docs/ACCURACY.md,
// "The start's rows back-filled"). Main's 0.733 fails the vessel-1 check
// (the 0.8, 11 % under the measured 0.896).
TEST(HarbourScenario, WindowTracksTheAbreastPairStartedOneByOne) {
  std::vector<double> early;
  const auto s = ScoreWindow(FreshAbreast("abreast_36"), "abreast 36 m", &early);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // measured 0.896 / 0.853 (main: 0.733 / 0.853)
  }
  // m; measured 0.0587 / 0.108 (before the back-fill 0.0613 / 0.108; main before
  // the joint start: 0.715 / 0.472); the target is 0.3.
  EXPECT_LE(s.rms[0], 1.5 * 0.0613);
  EXPECT_LE(s.rms[1], 1.5 * 0.108);
}

// fresh_abreast/abreast_28.toml: 28 m apart, one vessel 3 m from the middle
// sensor row, the other 11 m from its own; started one by one 6 s apart.
// Committed before it was run; run blind with joint_start_s = 5 s (failing:
// RMS 1.27 m, 5.8 % false rows, as on main), then joint_start_s was set to
// 20 s, so it is no longer blind (docs/ACCURACY.md, "Two vessels started
// one by one: the joint start").
TEST(HarbourScenario, WindowTracksTheAbreastPairStartedSixSecondsApart) {
  const auto s = ScoreWindow(
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/fresh_abreast/abreast_28.toml"),
      "abreast 28 m");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 (main: 5.8 %)
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // measured 0.829 / 0.878
  }
  // m. Vessel 1: 0.0425 before the start in the residual
  // (TrackManagementOptions::residual_start), 0.113 with it: it starts 5 s
  // earlier, at tensor SNR 10 beside vessel 2, and its first 4 s of live rows
  // are 0.2–0.5 m off until the pair refit (docs/ACCURACY.md, "Starts beside
  // a tracked neighbour"); main: 1.27. Vessel 2: 0.0437 (main: 0.206), 0.0279
  // with its start's rows back-filled at the joint start.
  EXPECT_LE(s.rms[0], 1.5 * 0.113);
  EXPECT_LE(s.rms[1], 1.5 * 0.0437);
}

// fresh_abreast2/abreast_40.toml: 39.5 m apart, vessel 1 9.5 m from the
// sensor column x = -36 (tensor SNR ≈ 50 there), vessel 2 13 m from the
// column x = 0 (tensor SNR ≤ 17: below the initiator's 20, no start fix).
// Blind, it got no track at all: vessel 1 was started 83 times, each
// tentative track missed by the poor-fit test at the sensor (0, -36) that
// its B alone reaches (predicted B 11 nT, tensor SNR 1.2) and where vessel
// 2's unexplained B (71 nT, tensor SNR 12) dominates. Without such samples
// in the poor-fit test (TrackManagementOptions::poor_fit_tensor_snr = 6;
// off by default: it costs some abreast RMS elsewhere) vessel 1 is tracked,
// and vessel 2 is then started beside it by the two-dipole fit (TryBeside).
// No longer blind (docs/ACCURACY.md, "Two blind abreast files that got no
// track: the cause"). Vessel 2's coverage (0.67) and vessel 1's RMS
// (0.39 m) do not meet the 0.8 and 0.3 m: held to their figures.
TEST(HarbourScenario, WindowTracksTheNearVesselBesideOneTooWeakToStart) {
  MultiTrackerOptions options;
  options.management.poor_fit_tensor_snr = 6.0;  // off by default
  const auto s = ScoreWindow(
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/fresh_abreast2/abreast_40.toml"),
      "abreast 40 m", nullptr, options);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
  EXPECT_GE(s.coverage[0], 0.8);           // measured 0.891 (main: 0, no track)
  EXPECT_GE(s.coverage[1], 0.9 * 0.667);  // measured 0.667 (main: 0)
  EXPECT_LE(s.rms[0], 1.5 * 0.3925);      // m, measured 0.3925
  EXPECT_LE(s.rms[1], 1.5 * 0.0434);      // m, measured 0.0434
}

// The same file with the defaults: the start in the residual beside a live
// track (TrackManagementOptions::residual_start, residual_start.h). Vessel
// 1's single start takes its field out of the initiator's buffer; vessel 2
// shows there at tensor SNR ≥ 10 (its peak 17 < the field's 20) and is
// fitted jointly with vessel 1's track (the joint fit at SNR 10), which is
// restarted from it: no more poor fit at the sensor both reach. Main: no
// track at all. This file is not blind (looked at before this change).
TEST(HarbourScenario, WindowStartsTheWeakVesselInTheResidualBesideItsNeighbour) {
  const auto s = ScoreWindow(
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/fresh_abreast2/abreast_40.toml"),
      "abreast 40 m, defaults");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // measured 0.980 / 0.917 (main: 0 / 0)
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0367);  // m, measured 0.0367
  EXPECT_LE(s.rms[1], 1.5 * 0.0482);  // m, measured 0.0482
}

// A vessel started in the residual gets its start's rows (issue 24, branch
// winstart): fresh_abreast4/abreast_31's vessel 2 (peak tensor SNR 14, below
// the field's start SNR 20) is started in the residual at SNR 10 at 76.6 s,
// 30 s after it came within 15 m of a sensor. Its start was back-filled
// from the first epoch its window predicts the field's SNR 20, which it
// never reaches, so it was not back-filled at all (window coverage 0.668);
// from the residual start's SNR 10 (the lowest any start rule accepts), not
// before its first fix: 56.8 s on, coverage 0.842. Not blind any more
// (looked at for this change; blind for the residual start's batch).
TEST(HarbourScenario, WindowBackFillsTheVesselStartedInTheResidual) {
  const auto s = ScoreWindow(
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/fresh_abreast4/abreast_31.toml"),
      "abreast_31, defaults");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // the issue's; measured 0.969 / 0.842 (0.969 / 0.668 before)
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0268);  // m, measured 0.0268
  EXPECT_LE(s.rms[1], 1.5 * 0.0823);  // m, measured 0.0823 (0.089 before)
}

// The lone start (issue 24; ResidualStartOptions::lone_min_fixes):
// fresh_farsrc/far_ship_110's AUV passes its first sensor 14–15 m off, in
// reach from 54.8 s at tensor SNR 11–13 (noise-free), below the field's
// start SNR 20 until 85 s, with no live track for the start in the
// residual to act beside: its single start came at 90.6 s (window coverage
// 0.663). The lone start (≥ 40 fixes over ≥ 10 s at the residual start's
// SNR 10, no live track; on by default) starts it at 62.6 s and its start's rows are
// back-filled from its first fix. Not blind (looked at for this change);
// the far ship 110 m off is in the file, so is its far-source fit.
TEST(HarbourScenario, WindowStartsTheLoneWeakVessel) {
  const auto s = ScoreWindow(
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/fresh_farsrc/far_ship_110.toml"),
      "far_ship_110, defaults (the lone start on)");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_GE(s.coverage[0], 0.8);  // the issue's; measured 1.000 (0.663 without the lone start)
  EXPECT_LE(s.rms[0], 1.5 * 0.0943);  // m, measured 0.0943
}

// Two weak vessels abreast with no live track (issue 24, branch pairstart):
// fresh_drift2/drift_3_abreast without its drift (two AUVs southward 26 m
// apart, 13 m either side of the middle column; each one's own tensor peaks
// at 17.8 / 13.4 sigma_T, their sum at 28 at the column's sensors), cut to
// 80 s from 24 m before the first sensor. No track without the lone pair
// start: every single-sample fix is spoiled by the other vessel's field
// (the lone start finds at most 28 of its 40 fixes) and the field's pair
// start fits the two within 0.5 m but refuses them, each dipole's own tensor
// below 20. With it (ResidualStartOptions::lone_pair, on by default; the
// pair start at the lone start's SNR 10, fixes 40 and span 10 s) both are
// tracked. Not blind:
// drift_3_abreast was run once blind (no track) and diagnosed here.
TEST(HarbourScenario, WindowStartsTwoWeakVesselsAbreastWithNoLiveTrack) {
  FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                           "/generated/scenarios/fresh_drift2/drift_3_abreast.toml");
  sc.background_drift_Tps.clear();
  for (FieldVessel& v : sc.vessels) {
    v.start_position.x() = 60.0;
    v.segments = {{80.0, 0.0}};
  }
  const auto s = ScoreWindow(sc, "drift_3_abreast without drift, 80 s, defaults (the lone pair start on)");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // the issue's; measured 0.953 / 0.953 (no track when off)
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.1030);  // m, measured 0.1030
  EXPECT_LE(s.rms[1], 1.5 * 0.1029);  // m, measured 0.1029
}

// The batch over all the evidence for a vessel started in the residual
// (issue 24 items 2 and 5; MultiTrackerOptions::batch_weak_init):
// fresh_sigma/abreast_s's vessel 1 (peak tensor SNR 12, below the field's
// start SNR 20) is started in the residual beside vessel 2. Its batch solve
// found no fix at SNR 20 to initialise from, so its batch rows were its
// window rows (coverage 0.854, RMS 0.0474 m: both fail below); initialised
// at the residual start's SNR 10 and refined over its own samples, the
// neighbour's field removed: 1.00, 0.0204 m. Not blind (looked at for the
// residual start and for this change).
TEST(HarbourScenario, BatchRefinesTheVesselStartedInTheResidual) {
  const auto s = ScoreBatch(
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/fresh_sigma/abreast_s.toml"),
      "abreast_s, defaults");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.9) << "vessel " << v + 1;  // the issue's; measured 1.000 / 1.000 (0.854 / 1.000 before)
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0204);  // m, measured 0.0204 (0.0474 before: its window rows)
  EXPECT_LE(s.rms[1], 1.5 * 0.0119);  // m, measured 0.0119 (0.0164 before)
}

TEST(HarbourScenario, BatchTracksTheFreshAbreastPair) {
  const auto s = ScoreBatch(FreshAbreast("abreast_20"), "fresh abreast 20 m");
  // Measured 0 false rows (220, 7.8 %, on main; 274, 10 %, without the partner rule).
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.9) << "vessel " << v + 1;  // measured 1.00 / 1.00
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0359);  // m, measured 0.0359 (0.758 on main)
  EXPECT_LE(s.rms[1], 1.5 * 0.0586);  // m, measured 0.0586
}
}  // namespace
}  // namespace magnav::tracker

namespace magnav::tracker {
namespace {

// One vessel overtaking another (issue 24): the held-out overtaking
// geometry (heldout/overtaking.toml: a slow AUV at 0.8 m/s and a fast one at
// 1.8 m/s, 8 m apart either side of the middle sensor row), shortened to
// 100 s with both vessels started nearer the grid (slow at x = −40 m, fast at
// −65 m; the fast one passes at 25 s, 20 m before the middle column). Before
// the pair start beside a track (pair_beside.h) the slow vessel's track
// ended "missed" as soon as the fast one's field spoiled its fit, and the
// fast one got a track between the two (main's library: window coverage
// 0.35 / 0.13, 2 ids each, RMS 0.32 / 3.27 m, 22 % false rows; batch
// coverage 0.70 / 0.93, 2 ids each, RMS 0.24 / 1.66 m; docs/ACCURACY.md,
// "One vessel overtaking another"). This geometry was looked at for that
// change (not blind); fresh_overtaking/ is the blind check.
using testing::ShortOvertaking;

TEST(HarbourScenario, WindowKeepsBothVesselsOfAnOvertaking) {
  const auto s = ScoreWindow(ShortOvertaking(), "short overtaking");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // the issue's; measured 0.932 / 0.990
  }
  // m, measured 0.111; 0.0632 with the end rule beyond the reach off (the
  // default before 2026-11-26): the fast vessel's track now ends 2 s out of
  // reach, and its B, still seen at the slow vessel's sensors, is no longer
  // removed from them (docs/ACCURACY.md, "The end rule beyond the reach by
  // default"; not fixed).
  EXPECT_LE(s.rms[0], 1.5 * 0.111);
  EXPECT_LE(s.rms[1], 1.5 * 0.0412);  // m, measured 0.0412 (0.0405 before)
}

TEST(HarbourScenario, BatchKeepsBothVesselsOfAnOvertaking) {
  const auto s = ScoreBatch(ShortOvertaking(), "short overtaking");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.9) << "vessel " << v + 1;  // the issue's; measured 1.00 / 1.00
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.0115);  // m, measured 0.0115
  EXPECT_LE(s.rms[1], 1.5 * 0.0093);  // m, measured 0.0093
}

// A slow vessel's track kept while a fast one, still weak, closes on it
// (issue 24, branch overtake2): fresh_sigma2/overtaking_s2 (1.5 m/s past
// 0.6 m/s, 11 m apart, southward) cut to its first 90 s (the window is
// causal: the same rows up to then). The fast vessel's B spoils the slow
// one's fit from 37.8 s, 25 m behind it; the beside fit finds it there
// (misfit 0.004, 1.5 m from its true line) but its tensor is 7.6 and 9.9 σ_T,
// below the beside start's 10, and the slow vessel's track ended "missed"
// at 39.5 s, 0.5 s before the fast one could be started beside it: a second
// id (purity 0.80). With those misses excused while the fit beside explains
// them (TrackManagementOptions::excuse_beside, on by default) the fast one is
// started beside it at 40 s and each keeps one id. The counter-run with the
// excuse off is asserted to give the slow vessel two ids, so the check
// cannot pass without it. Not blind: this file was looked at for the change
// (fresh_overtaking2/ is the blind check; docs/ACCURACY.md, "The slow
// vessel of overtaking_s2").
FieldScenario ShortOvertakingS2() {
  FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                           "/generated/scenarios/fresh_sigma2/overtaking_s2.toml");
  sc.vessels[0].segments = {{90.0, 0.0}};
  sc.vessels[1].segments = {{90.0, 0.0}};
  return sc;
}

TEST(HarbourScenario, WindowKeepsTheSlowVesselWhileAWeakOvertakerCloses) {
  const auto s = ScoreWindow(ShortOvertakingS2(), "short overtaking_s2");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // the issue's; measured 0.917 / 1.000 (0.812 / 0.969 without)
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.202);  // m, measured 0.202 (0.195 over its two ids without the excuse)
  EXPECT_LE(s.rms[1], 1.5 * 0.0616);  // m, measured 0.0616 (0.0478)
  MultiTrackerOptions off;
  off.management.excuse_beside = false;
  // Re-acquisition (on by default since 2026-11-27) alone gives the slow
  // vessel one id here too (its second track continues its first): off, so
  // that the counter-run tests the excuse.
  off.management.reacquire_s = 0.0;
  const auto g = ScoreWindow(ShortOvertakingS2(), "short overtaking_s2, misses not excused", nullptr, off);
  EXPECT_GE(g.ids[0], 2u);  // measured 2
}

// The same when the newcomer is seen by its B alone (issue 24, branch n14):
// fresh_overtaking2/overtaking_n14 (1.6 m/s past 1.0 m/s, 14 m apart,
// northward) cut to its first 75 s. The fast vessel's B spoils the slow
// one's fit from 43.6 s, 31 m behind it, while its own tensor is 1.1–1.5
// σ_T: with the excuse needing the newcomer's tensor at 3 σ_T, the slow
// vessel's track ended "missed" at 45.5 s (2 ids). With its field seen
// (B and tensor, as a track's gate) the track coasts until the fast one is
// started beside it at 49 s; the pair's refit then uses the beside fit's
// init SNR (at the field's 20 the fast one's samples barely entered it and
// its line was put 16 m off at 64 s, a second id for it). The counter-run
// with the excuse off is asserted to give the slow vessel two ids. The
// newcomer's field is "seen" only with its tensor evidence (its predicted
// tensor ≥ 3 σ_T at some sample, reducing the tensor χ² there: 3.2–7.9 σ_T
// at 44–48 s, 2.4 at 45 s): without it a far ship's B, or a track's own
// model error, fitted as a far second dipole excused misses too
// (FieldReference.*, MultiTracker.FarShipArrivingWhileAnAuvIsTracked failed;
// branch n14b). Not blind: the file was looked at for this change
// (docs/ACCURACY.md, "overtaking_n14", "overtaking_n14, second try").
FieldScenario ShortOvertakingN14() {
  FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                           "/generated/scenarios/fresh_overtaking2/overtaking_n14.toml");
  sc.vessels[0].segments = {{75.0, 0.0}};
  sc.vessels[1].segments = {{75.0, 0.0}};
  return sc;
}

TEST(HarbourScenario, WindowKeepsTheSlowVesselWhileAnOvertakersBSpoilsItsFit) {
  const auto s = ScoreWindow(ShortOvertakingN14(), "short overtaking_n14");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;  // the issue's; measured 0.840 / 1.000 (0.808 / 0.145 without)
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.511);  // m, measured 0.511 (0.672 over its two ids without)
  EXPECT_LE(s.rms[1], 1.5 * 0.214);  // m, measured 0.214 (0.309)
  MultiTrackerOptions off;
  off.management.excuse_beside = false;
  // Re-acquisition (on by default since 2026-11-27) alone gives the slow
  // vessel one id here too (its second track continues its first): off, so
  // that the counter-run tests the excuse.
  off.management.reacquire_s = 0.0;
  const auto g = ScoreWindow(ShortOvertakingN14(), "short overtaking_n14, misses not excused", nullptr, off);
  EXPECT_GE(g.ids[0], 2u);  // measured 2
}

// A coasting track re-acquired under its id (issue 24, branch overtake5;
// reacquire.h): fresh_overtaking4/overtaking_ne15 (2.1 m/s past 0.9 m/s,
// 15 m apart, heading 0.6 rad; blind once, looked at since) cut to its
// first 80 s. The slow vessel crosses a grid cell on the diagonal, 21-27 m
// from every sensor from 55 s to 66 s; its track coasts and ends "missed" at
// 62 s as the overtaker's B arrives, 31 m behind, and a new track is
// confirmed on it at 71.8 s (its rows from 66 s). Re-acquisition (on by
// default, 30 s) gives that track the ended one's id (χ² 0.26 of 13.28);
// the counter-run with it off gives the slow vessel two ids, as on main.
FieldScenario ShortOvertakingNe15() {
  FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                           "/generated/scenarios/fresh_overtaking4/overtaking_ne15.toml");
  sc.vessels[0].segments = {{80.0, 0.0}};
  sc.vessels[1].segments = {{80.0, 0.0}};
  return sc;
}

TEST(HarbourScenario, WindowReacquiresTheSlowVesselsTrackAfterItsGap) {
  const auto s = ScoreWindow(ShortOvertakingNe15(), "short overtaking_ne15");
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  EXPECT_EQ(s.ids[0], 1u);        // measured 1 (2 with it off)
  EXPECT_EQ(s.ids[1], 1u);        // the overtaker's own: measured 1
  EXPECT_GE(s.coverage[0], 0.8);  // the issue's; measured 0.821
  EXPECT_LE(s.rms[0], 1.5 * 0.0807);  // m, measured 0.0807
  MultiTrackerOptions off;
  off.management.reacquire_s = 0.0;
  const auto g = ScoreWindow(ShortOvertakingNe15(), "short overtaking_ne15, no re-acquisition", nullptr, off);
  EXPECT_GE(g.ids[0], 2u);  // measured 2
}

// With the window's offset lines (SensorOffsetOptions::window_lines, off)
// the same short ne15: the lines are marginalised out of the window's
// covariance (tracker/src/offset_marginal.h) and the variance factor reads
// each sensor's residual means per quarter of the window, so the slow
// track's σ before its gap says what the fit knows and re-acquisition
// continues it (docs/ACCURACY.md, "The window offsets' uncertainty in the
// window's σ"). Before (the chain's covariance given the lines, residual
// means over the whole window): 2 ids, and its rows 57–62 s (35.4–40.4 s
// after its first) had mean 2-dof NEES 185 (`magnav track`, the full file).
TEST(HarbourScenario, WindowOffsetLinesMarginalisedKeepTheSlowVesselsId) {
  MultiTrackerOptions on;
  on.track.sensor_offset.window_lines = true;
  const FieldScenario sc = ShortOvertakingNe15();
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, on);
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  const auto s = magnav::testing::ScoreField(sc, f, rows);
  magnav::testing::PrintFieldScores("short overtaking_ne15, offset lines, window", s);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  EXPECT_EQ(s.ids[0], 1u);  // measured 1 (2 before)
  EXPECT_EQ(s.ids[1], 1u);
  EXPECT_GE(s.coverage[0], 0.8);
  const std::vector<double> nees = NeesOver(f, sc.rate_hz, rows, 35.4, 40.4);
  std::printf("short overtaking_ne15, offset lines: the slow track's NEES (3 dof) 5 s before its gap: %.2f\n", nees[0]);
  EXPECT_LE(nees[0], 1.5 * 5.93);  // measured 5.93 (8.03 before the window's prior left the offset sensors' B out)
}

// No ghost track from a far ship or a drifting background (issue 24 items 1
// and 3): the held-out far-ship and drift scenarios (heldout/far_ship.toml:
// a 4.2e5 A·m² ship 114 m off the grid; heldout/drift.toml: 4 nT/min), window
// mode, with the defaults: the "out_of_reach" end rule (out_of_reach_s 2 s,
// the default since 2026-11-26) beside the tensor evidence for confirmation
// (confirm_tensor_snr 3). Before both a departing AUV's track walked off on
// the ship's or the drift's B: 57 % and 24 % false rows (docs/ACCURACY.md,
// "No ghost track from a far ship or a drift"); with the rules 0.0 % and
// 2.9 %. Held to the 5 % (the 10x without the rules does not pass).
// The AUV's figures as measured (these files were not tuned on; the tuning
// was on tuning/).
TEST(HarbourScenario, WindowStartsNoGhostFromAFarShip) {
  const auto s = ScoreWindow(HeldOut("far_ship"), "held-out far ship", nullptr);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
  EXPECT_GE(s.coverage[0], 0.9 * 0.609);  // measured 0.609 (2 ids: broken while the ship is closest)
  EXPECT_LE(s.ids[0], 2u);
}

// The same held-out far ship with the defaults alone: the tensor evidence
// for confirmation (confirm_tensor_snr 3) is what stops the ghost started at
// 133.8 s, whose detections were B alone (main: 660 of 1155 rows false, 57 %;
// with the default 0 %). With the confirmation off and the end rule on (the
// default since 2026-11-26) the ghost is confirmed and ended "out_of_reach"
// after 15 false rows (2.9 %); with both off (main's rules before) it comes
// back: that run is asserted to fail the 5 %, so the check cannot pass
// without the rules. The far source (on by default since 2026-11-26) removes
// the ship's B, which alone also keeps the ghost away (0 false rows with both
// rules off): the counter-run turns it off too, so that it tests the rules.
TEST(HarbourScenario, WindowConfirmsNoGhostFromAFarShipByDefault) {
  const auto s = ScoreWindow(HeldOut("far_ship"), "held-out far ship, defaults", nullptr);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
  MultiTrackerOptions without;
  without.management.confirm_tensor_snr = 0.0;
  without.management.out_of_reach_s = 0.0;
  without.far_source.enabled = false;
  const auto g = ScoreWindow(HeldOut("far_ship"), "held-out far ship, no tensor evidence nor end rule nor far source",
                             nullptr, without);
  EXPECT_GT(static_cast<double>(g.false_rows), 0.2 * static_cast<double>(g.rows));  // measured 57 % on main
}

// The drift with the defaults, and the same run with the end rule off
// (out_of_reach_s 0, the default before 2026-11-26): asserted to fail the
// 5 % (measured 23.5 %), so the check cannot pass without the rule.
TEST(HarbourScenario, WindowStartsNoGhostFromADrift) {
  const auto s = ScoreWindow(HeldOut("drift"), "held-out drift", nullptr);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 2.9 %
  EXPECT_GE(s.coverage[0], 0.8);  // the issue's; measured 0.889
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_LE(s.rms[0], 1.5 * 0.44);  // m, measured 0.44 (0.44 with the rule off)
  MultiTrackerOptions off;
  off.management.out_of_reach_s = 0.0;
  const auto g = ScoreWindow(HeldOut("drift"), "held-out drift, end rule off", nullptr, off);
  EXPECT_GT(static_cast<double>(g.false_rows), 0.1 * static_cast<double>(g.rows));  // measured 23.5 %
}

}  // namespace
}  // namespace magnav::tracker

namespace magnav::tracker {
namespace {

// The per-sensor B offset in each track's solve (TrackerOptions::sensor_offset,
// an option, off; docs/ACCURACY.md "A per-sensor B offset in each track's
// solve"): on the held-out drift (5 nT/min) the window meets the issue's
// targets, RMS 0.093 m measured (0.436 m with the option off, main's row;
// 0.073 m before the window's prior left the offset sensors' B out).
TEST(HarbourScenario, WindowWithTheSensorOffsetMeetsTheTargetsOnTheHeldOutDrift) {
  MultiTrackerOptions on;
  on.track.sensor_offset.window = true;
  const auto s = ScoreWindow(HeldOut("drift"), "held-out drift, sensor offset", nullptr, on);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
  EXPECT_GE(s.coverage[0], 0.8);  // measured 0.889
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_LE(s.rms[0], 1.5 * 0.093);  // m, measured 0.093
}

// The window's offsets behind the batch's score test (SensorOffsetOptions::
// window_score_test, `--window-offset-score-test`, an option, off;
// docs/ACCURACY.md "The window's offsets behind the batch's score test"), with
// the offsets as lines whose rate's prior is 0.1 nT/s (a drift's, not a
// vessel's): on the held-out drift the test fires at the first solve after
// the start and the window meets the targets (RMS 0.0555 m measured,
// 0.436 m with the defaults), its σ near the truth's (mean position NEES 1.97,
// 3 dof; 4.36 while the window's prior kept the B levels of the samples that
// had left it, window.cc MarginalizeFront); the same vessel without the drift
// never fires it, and its rows are the defaults' bit for bit.
MultiTrackerOptions OffsetsBehindTheScoreTest() {
  MultiTrackerOptions o;
  o.track.sensor_offset.window_lines = true;
  o.track.sensor_offset.window_score_test = true;
  o.track.sensor_offset.line_rate_sigma_T_per_s = 1e-10;
  return o;
}

TEST(HarbourScenario, WindowOffsetsBehindTheScoreTestTakeTheHeldOutDriftAndLeaveACleanPassAlone) {
  FieldScenario sc = HeldOut("drift");
  {
    const SimulatedField f = SimulateField(sc);
    MultiTracker tracker(sc.B0, OffsetsBehindTheScoreTest());
    const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
    const auto s = magnav::testing::ScoreField(sc, f, rows);
    magnav::testing::PrintFieldScores("held-out drift, offsets behind the score test, window", s);
    EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
    EXPECT_GE(s.coverage[0], 0.8);  // measured 0.889
    EXPECT_EQ(s.ids[0], 1u);
    EXPECT_LE(s.rms[0], 2.0 * 0.0555);  // m, measured 0.0555 (0.067 before)
    const std::vector<double> nees = NeesOver(f, sc.rate_hz, rows, 0.0, 1e9);
    std::printf("held-out drift, offsets behind the score test: mean position NEES (3 dof) %.2f\n", nees[0]);
    EXPECT_LE(nees[0], 1.5 * 1.97);  // measured 1.97; 4.36 before
    EXPECT_GE(nees[0], 0.5 * 1.97);
    const auto tracks = tracker.Tracks();
    ASSERT_FALSE(tracks.empty());
    for (const TrackRecord& t : tracks) {
      std::printf("track %u: %.1f-%.1f s, window offsets from %.1f s\n", t.track_id, t.t_start_s, t.t_end_s,
                  t.t_window_offsets_s);
    }
    EXPECT_TRUE(std::isfinite(tracks[0].t_window_offsets_s));
    EXPECT_LE(tracks[0].t_window_offsets_s, tracks[0].t_start_s + 2.0);  // measured 0.2 s after its first row
    const auto d = ScoreWindow(sc, "held-out drift, defaults");
    EXPECT_GE(d.rms[0], 3.0 * s.rms[0]);  // measured 0.436 m (6.5x)
  }
  sc.background_drift_Tps.clear();  // the same vessel and noise, no drift
  const SimulatedField f = SimulateField(sc);
  MultiTracker with(sc.B0, OffsetsBehindTheScoreTest()), without(sc.B0, MultiTrackerOptions{});
  const auto a = magnav::testing::WindowRows(&with, f.samples), b = magnav::testing::WindowRows(&without, f.samples);
  ASSERT_GT(a.size(), 500u);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].first, b[i].first);
    EXPECT_EQ(a[i].second.p_VinW, b[i].second.p_VinW);
    EXPECT_EQ(a[i].second.cov_state, b[i].second.cov_state);
  }
  for (const TrackRecord& t : with.Tracks()) EXPECT_TRUE(std::isnan(t.t_window_offsets_s)) << t.track_id;
  // The test needs the window's offsets (constant or lines) to call for.
  SensorOffsetOptions so;
  so.window_score_test = true;
  std::string error;
  EXPECT_FALSE(so.IsValid(&error));
  EXPECT_NE(error.find("window_score_test"), std::string::npos) << error;
  so.window = true;
  EXPECT_TRUE(so.IsValid(&error)) << error;
}

// The window's prior keeps only the tensor of a sample whose sensor has the
// track's own offset (window.cc MarginalizeFront; docs/ACCURACY.md "The
// window's prior without the offset sensors' B"): beside a far ship
// (fresh_farsrc2/far_ship_105.toml: a 4.1e5 A·m² ship 105 m off the grid, the
// far source's fit not explaining all of its B, so the offsets fire and move)
// the leaving samples' B levels under the offsets of their time held the
// AUV's moment 7 % high at 55 σ and the track 0.2 m off at σ 0.02 m (window
// RMS 0.324 m, mean NEES 159). Now: the moment within 1.5 % (measured −1.4 %
// in magnitude), RMS 0.211 m, mean NEES 4.8.
TEST(HarbourScenario, WindowOffsetsBesideAFarShipLeaveTheMomentToTheTensor) {
  const FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                                 "/generated/scenarios/fresh_farsrc2/far_ship_105.toml");
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, OffsetsBehindTheScoreTest());
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  const auto s = magnav::testing::ScoreField(sc, f, rows);
  magnav::testing::PrintFieldScores("far_ship_105, offsets behind the score test, window", s);
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_GE(s.coverage[0], 0.8);  // measured 1.00
  EXPECT_LE(s.rms[0], 1.5 * 0.211);  // m, measured 0.211 (0.324 before)
  const std::vector<double> nees = NeesOver(f, sc.rate_hz, rows, 0.0, 1e9);
  std::printf("far_ship_105, offsets behind the score test: mean position NEES (3 dof) %.2f\n", nees[0]);
  EXPECT_LE(nees[0], 2.0 * 4.79);  // measured 4.79 (159 before)
  const auto tracks = tracker.Tracks();
  ASSERT_FALSE(tracks.empty());
  const double truth = sc.vessels[0].moment_body.norm();
  const double rel = tracks[0].m_B_Am2.norm() / truth - 1.0;
  std::printf("far_ship_105: the AUV's moment %.1f A·m² (truth %.1f, %+.2f %%), window offsets from %.1f s\n",
              tracks[0].m_B_Am2.norm(), truth, 100.0 * rel, tracks[0].t_window_offsets_s);
  EXPECT_TRUE(std::isfinite(tracks[0].t_window_offsets_s));  // the test fired (measured at 52 s)
  EXPECT_LE(std::abs(rel), 0.03);  // measured −1.44 %; +7.47 % before
}

// The score test latched only after it persists (SensorOffsetOptions::
// window_score_persist_s, 3 s here; an option, 0 by default; docs/ACCURACY.md
// "The drift flags as the window's defaults: measured, not merged"). On
// heldout_abreast/abreast_20 (two tracked AUVs abreast 20 m apart, no drift)
// the test fires from 55 s, 6 s after the pair's start: latched there, the
// lines and the B-laden prior took the rows to RMS 0.495 / 0.352 m (0.193 /
// 0.168 without the lines); latched 3 s later with the tensor-only prior,
// 0.299 / 0.202 m (with 5 s it does not latch there). On the held-out drift
// it latches 3 s after the start, the window's prior then the one folded
// from the leaving samples' tensors alone; with the latch delayed but the
// B-laden prior kept (tried) the mean NEES was 27.
MultiTrackerOptions OffsetsBehindAPersistentScoreTest() {
  MultiTrackerOptions o = OffsetsBehindTheScoreTest();
  o.track.sensor_offset.window_score_persist_s = 3.0;
  return o;
}

TEST(HarbourScenario, WindowScoreTestLatchedAfterItPersistsKeepsAbreastAndTakesTheDrift) {
  {
    const auto s = ScoreWindow(FreshAbreast("abreast_20"), "abreast_20, persistent score test", nullptr,
                               OffsetsBehindAPersistentScoreTest());
    const auto g = ScoreWindow(FreshAbreast("abreast_20"), "abreast_20, score test latched at once", nullptr,
                               OffsetsBehindTheScoreTest());
    EXPECT_EQ(s.false_rows, 0u);
    for (std::size_t v = 0; v < 2; ++v) {
      EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
      EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v + 1;
    }
    EXPECT_LE(s.rms[0], 1.2 * 0.299);  // m, measured 0.299 (0.495 latched at once, 0.193 without the lines)
    EXPECT_LE(s.rms[1], 1.2 * 0.202);  // m, measured 0.202 (0.352, 0.168)
    EXPECT_GE(g.rms[0], 1.4 * s.rms[0]);  // the check can fail: measured 1.66x
  }
  const FieldScenario sc = HeldOut("drift");
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, OffsetsBehindAPersistentScoreTest());
  const auto rows = magnav::testing::WindowRows(&tracker, f.samples);
  const auto s = magnav::testing::ScoreField(sc, f, rows);
  magnav::testing::PrintFieldScores("held-out drift, offsets behind a persistent score test, window", s);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  EXPECT_GE(s.coverage[0], 0.8);
  EXPECT_EQ(s.ids[0], 1u);
  const std::vector<double> nees = NeesOver(f, sc.rate_hz, rows, 0.0, 1e9);
  const auto tracks = tracker.Tracks();
  ASSERT_FALSE(tracks.empty());
  std::printf("held-out drift, persistent score test: RMS %.4g m, mean position NEES (3 dof) %.3g, latched %.1f s "
              "after the track's start\n",
              s.rms[0], nees[0], tracks[0].t_window_offsets_s - tracks[0].t_start_s);
  EXPECT_LE(s.rms[0], 1.5 * 0.1236);  // m, measured 0.1236 (0.436 without the lines, 0.0555 latched at once)
  EXPECT_LE(nees[0], 2.0 * 3.69);  // measured 3.69 (1.97 latched at once; 27 with the B-laden prior kept)
  // Measured 2.7 s after the track's first row (0.2 s latched at once).
  EXPECT_GE(tracks[0].t_window_offsets_s - tracks[0].t_start_s, 2.0);
}

// The window's per-sensor offsets as lines in time (SensorOffsetOptions::
// window_lines, `--window-offset-lines`, an option, off; docs/ACCURACY.md "The
// slow vessel's window RMS while an untracked overtaker closes"):
// fresh_overtaking3/overtaking_s13 (looked at since its blind run) cut to its
// first 50 s. The slow vessel's first track (from 25 s) is held by its tensor
// at one sensor and by its B alone at three; the fast vessel, 26-37 m behind
// and untracked (beyond the tensor reach), leaves 5-30 nT of its B at those
// three, and the window's rows are 1.3-1.5 m off (0.03 m with the fast vessel
// taken out of the file). With the offsets as lines its B is taken out.
// Measured RMS values are in the comments; the counter-run without the option
// is asserted to be at least 3x worse, so the check cannot pass without it.
FieldScenario ShortOvertakingS13() {
  FieldScenario sc = cli::ReadScenarioFile(magnav::testing::TestDataDir() +
                                           "/generated/scenarios/fresh_overtaking3/overtaking_s13.toml");
  sc.vessels[0].segments = {{50.0, 0.0}};
  sc.vessels[1].segments = {{50.0, 0.0}};
  return sc;
}

TEST(HarbourScenario, WindowOffsetLinesTakeAnUntrackedOvertakersBOut) {
  MultiTrackerOptions on;
  on.track.sensor_offset.window_lines = true;
  const auto s = ScoreWindow(ShortOvertakingS13(), "short overtaking_s13, offset lines", nullptr, on);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_LE(s.rms[0], 1.5 * 0.2985);  // m, measured 0.2985 (coverage 0.948; 0.378 before the window's prior left the offset sensors' B out)
  const auto g = ScoreWindow(ShortOvertakingS13(), "short overtaking_s13, defaults", nullptr);
  EXPECT_GE(g.rms[0], 3.0 * s.rms[0]);  // measured 1.429 m (4.8x; coverage 0.948)
  // The options' checks: not with carry nor with the quiet offset (the lines
  // would leave it unused); the rate's prior σ > 0.
  SensorOffsetOptions so;
  so.window_lines = true;
  std::string error;
  EXPECT_TRUE(so.IsValid(&error)) << error;
  EXPECT_TRUE(so.WindowOffsets());
  so.window = true;
  so.carry = true;
  EXPECT_FALSE(so.IsValid(&error));
  so.carry = false;
  so.quiet = true;
  EXPECT_FALSE(so.IsValid(&error));
  EXPECT_NE(error.find("quiet"), std::string::npos) << error;
  so.quiet = false;
  so.line_rate_sigma_T_per_s = 0.0;
  EXPECT_FALSE(so.IsValid(&error));
}

// The window's offset carried between windows and only where the track's
// predicted tensor SNR reaches 20 (SensorOffsetOptions carry and
// min_tensor_snr, options, off; docs/ACCURACY.md "The window's sensor offset
// carried between windows, and gated by the tensor"): on heldout_abreast/abreast_20, whose window the
// free offset cost (vessel 1 RMS 0.193 → 0.394 m, `magnav track`), vessel 1
// stays within the targets (1 id each, RMS ≈ main's); and the held-out drift
// meets the targets (less of the free offset's gain).
MultiTrackerOptions CarriedGatedOffset() {
  MultiTrackerOptions o;
  o.track.sensor_offset.window = true;
  o.track.sensor_offset.carry = true;
  o.track.sensor_offset.min_tensor_snr = 20.0;
  return o;
}

TEST(HarbourScenario, WindowWithTheCarriedGatedOffsetKeepsAbreast20) {
  const FieldScenario sc =
      cli::ReadScenarioFile(magnav::testing::TestDataDir() + "/generated/scenarios/heldout_abreast/abreast_20.toml");
  const auto s = ScoreWindow(sc, "abreast_20, carried gated sensor offset", nullptr, CarriedGatedOffset());
  EXPECT_EQ(s.false_rows, 0u);  // measured 0
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_GE(s.coverage[v], 0.9);  // measured 0.974, 1.000
    EXPECT_EQ(s.ids[v], 1u);
  }
  EXPECT_LE(s.rms[0], 1.5 * 0.1935);  // m, measured 0.1935 (main 0.193); the free offset's 0.394 fails it
  EXPECT_LE(s.rms[1], 2.0 * 0.1585);  // m, measured 0.1585 (main 0.168)
}

TEST(HarbourScenario, WindowWithTheCarriedGatedOffsetMeetsTheTargetsOnTheHeldOutDrift) {
  const auto s = ScoreWindow(HeldOut("drift"), "held-out drift, carried gated sensor offset", nullptr,
                             CarriedGatedOffset());
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));  // measured 0 %
  EXPECT_GE(s.coverage[0], 0.8);  // measured 0.889
  EXPECT_EQ(s.ids[0], 1u);
  // m, the 0.3 (measured 0.185, the free offset's 0.093): main's 0.436
  // and a 2× regression (0.41) fail it.
  EXPECT_LE(s.rms[0], 0.3);
}

// The sensor's own offset from its quiet data (SensorOffsetOptions::quiet)
// with the carried, gated offset, window on heldout/drift: no false row (main
// 2.43 %), coverage and one id kept. Its RMS is not the target: the quiet
// offset, a stale median walked without the drift's trend, gives back the
// gated offset's gain (0.185 m; docs/ACCURACY.md, "One B offset per sensor,
// owned by the sensor"): bounded here against a 2x regression only.
TEST(HarbourScenario, WindowWithTheQuietSensorOffsetKeepsTheHeldOutDriftClean) {
  MultiTrackerOptions o = CarriedGatedOffset();
  o.track.sensor_offset.quiet = true;
  const auto s = ScoreWindow(HeldOut("drift"), "held-out drift, quiet sensor offset", nullptr, o);
  EXPECT_EQ(s.false_rows, 0u);    // measured 0 (main 2.43 %)
  EXPECT_GE(s.coverage[0], 0.8);  // measured 0.889
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_LE(s.rms[0], 2.0 * 0.3726);  // m, measured 0.3726 (main 0.436, the gate alone 0.185)
}

// The quiet offset as a line with the new track's approach taken out of the
// store (SensorOffsetOptions::quiet_rate and quiet_approach), window on
// heldout/drift: the offset follows the drift's ramp while the vessel holds
// the sensors, so the RMS the stale median gave back (0.3726 m) returns
// (docs/ACCURACY.md, "A drift rate in the sensor-owned offset").
TEST(HarbourScenario, WindowWithTheQuietOffsetRateAndApproachMeetsTheHeldOutDrift) {
  MultiTrackerOptions o = CarriedGatedOffset();
  o.track.sensor_offset.quiet = true;
  o.track.sensor_offset.quiet_rate = true;
  o.track.sensor_offset.quiet_approach = true;
  const auto s = ScoreWindow(HeldOut("drift"), "held-out drift, quiet offset rate and approach", nullptr, o);
  EXPECT_EQ(s.false_rows, 0u);    // measured 0 (main 2.43 %)
  EXPECT_GE(s.coverage[0], 0.8);  // measured 0.889
  EXPECT_EQ(s.ids[0], 1u);
  // m, measured 0.1794: the stale median's 0.3726, main's 0.436 and a 2×
  // regression fail it.
  EXPECT_LE(s.rms[0], 1.5 * 0.1794);
}

// The single-track batch (SolveBatch) with the offset on the held-out drift's
// samples while the AUV is within 30 m of a sensor (the drift, since t = 0,
// is in them): RMS against the truth at the epochs. (The multi-vessel batch
// on the whole file, 4.8 s, is too long for CI: its row is in the doc.)
TEST(HarbourScenario, BatchWithTheSensorOffsetOnTheHeldOutDriftsPass) {
  const FieldScenario sc = HeldOut("drift");
  const SimulatedField f = SimulateField(sc);
  const auto near = [&](const Eigen::Vector3d& p) {
    for (const auto& s : sc.sensors) {
      if ((p - s).norm() <= 30.0) return true;
    }
    return false;
  };
  std::map<long long, Eigen::Vector3d> truth;
  for (const auto& q : f.truth[0]) {
    if (near(q.p_VinW)) truth[std::llround(q.t_s * sc.rate_hz)] = q.p_VinW;
  }
  ASSERT_FALSE(truth.empty());
  std::vector<GradiometerSample> kept;
  for (const auto& s : f.samples) {
    if (truth.count(std::llround(s.t_s * sc.rate_hz))) kept.push_back(s);
  }
  TrackerOptions opt;
  opt.sensor_offset.batch = true;
  opt.compute_covariance = false;
  const TrackEstimate est = SolveBatch(GroupEpochs(kept, opt.epoch_tolerance_s), sc.B0, opt);
  ASSERT_TRUE(est.summary.usable) << est.summary.message;
  double sum = 0.0;
  int n = 0;
  for (const auto& e : est.epochs) {
    const auto it = truth.find(std::llround(e.t_s * sc.rate_hz));
    if (it == truth.end() || !e.usable) continue;
    sum += (e.p_VinW - it->second).squaredNorm();
    ++n;
  }
  ASSERT_GT(n, 0);
  const double rms = std::sqrt(sum / n);
  std::printf("held-out drift, single-track batch with the sensor offset: RMS %.4f m over %d epochs\n", rms, n);
  EXPECT_GE(n, static_cast<int>(0.9 * static_cast<double>(truth.size())));
  // m, measured 1.061 (2.860 with the option off: this single-track batch of
  // the default TrackerOptions is far from the multi-vessel batch's 0.199 m
  // either way; it checks the offset's rounds in SolveBatch alone).
  EXPECT_LE(rms, 2.0 * 1.061);
}

}  // namespace
}  // namespace magnav::tracker
