// Single-vessel passes at closest approaches of 6-12 m (issue 24, "What it
// must show"; tests/data/generated/tracker_single_passes.csv, fixed before the
// batch change): the multi-vessel batch (SolveBatchMulti, as `magnav track`)
// refines a lone vessel over every sample where it is seen, so it is at least
// as accurate as the former single-target batch (SolveBatch over the whole
// pass). docs/ACCURACY.md, "Single-vessel passes at 6-12 m";
// scripts/heldout_single_pass runs every row through the CLI.
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"
#include "options_check.h"
#include "reference_truth.h"
#include "test_data.h"
#include "track_metrics.h"

namespace magnav::tracker {
namespace {

struct PassRow {
  std::string set, name;
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  double heading = 0.0, closest_3d = 0.0, side = 1.0, speed = 1.0, turn = 0.0;
  std::uint64_t seed = 0;
};

std::vector<PassRow> LoadPasses() {
  std::ifstream in(testing::TestDataDir() + "/generated/tracker_single_passes.csv");
  EXPECT_TRUE(in.good());
  std::vector<PassRow> rows;
  std::string line;
  bool header = true;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (header) {
      EXPECT_EQ(line, "set,name,mx,my,mz,heading_rad,closest_3d_m,side,speed_mps,turn_rps,seed");
      header = false;
      continue;
    }
    std::stringstream ss(line);
    std::vector<std::string> f;
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    EXPECT_EQ(f.size(), 11u) << line;
    if (f.size() != 11u) continue;
    PassRow r;
    r.set = f[0];
    r.name = f[1];
    r.moment = {std::stod(f[2]), std::stod(f[3]), std::stod(f[4])};
    r.heading = std::stod(f[5]);
    r.closest_3d = std::stod(f[6]);
    r.side = std::stod(f[7]);
    r.speed = std::stod(f[8]);
    r.turn = std::stod(f[9]);
    r.seed = std::stoull(f[10]);
    rows.push_back(r);
  }
  return rows;
}

const PassRow& Find(const std::vector<PassRow>& rows, const std::string& name) {
  for (const auto& r : rows) {
    if (r.name == name) return r;
  }
  ADD_FAILURE() << "no pass " << name;
  return rows.front();
}

// As scripts/heldout_single_pass: at t = 75 s the vessel is closest_3d from
// the sensor at the origin, 5 m above it.
PassScenario Scenario(const PassRow& r, bool fluxgate, std::uint64_t seed) {
  PassScenario sc;
  sc.moment_body = r.moment;
  sc.start_heading_rad = r.heading;
  sc.speed_mps = r.speed;
  const double horiz = std::sqrt(r.closest_3d * r.closest_3d - 25.0);
  const Eigen::Vector3d v(std::cos(r.heading), std::sin(r.heading), 0.0);
  const Eigen::Vector3d left(std::sin(r.heading), -std::cos(r.heading), 0.0);
  const Eigen::Vector3d closest = r.side * horiz * left + Eigen::Vector3d(0.0, 0.0, -5.0);
  sc.start_position = closest - 75.0 * r.speed * v;
  sc.segments = {{80.0, 0.0}, {60.0, r.turn}, {60.0, 0.0}};
  sc.sigma_B = fluxgate ? testing::kFluxgateSigmaB : testing::kSquidSigmaB;
  sc.sigma_T = fluxgate ? testing::kFluxgateSigmaT : testing::kSquidSigmaT;
  sc.seed = seed;
  return sc;
}

struct PassScores {
  testing::TrackMetrics batch, single, window;
  std::size_t batch_tracks = 0;
  // Truth epochs within 30 m (horizontally) of the sensor where the vessel
  // is within the sensor's reach: its true tensor SNR ‖T‖_F/σ_T ≥
  // reach_tensor_snr (the rows the batch reports with the end rule on).
  int within_reach = 0;
  int turn_restarts_kept = 0;  // of the batch's last solve of its (first) track
};

// Every estimate of the window (MultiTracker, every sample of the pass).
std::vector<EpochEstimate> WindowEstimates(const SimulatedPass& sim, const Eigen::Vector3d& B0,
                                           const MultiTrackerOptions& opt) {
  MultiTracker window(B0, opt);
  std::vector<EpochEstimate> w;
  const auto take = [&](const std::vector<TrackOutput>& out) {
    for (const auto& o : out) w.push_back(o.estimate);
  };
  for (const auto& smp : sim.samples) take(window.AddSample(smp));
  take(window.Flush());
  return w;
}

PassScores RunPass(const PassRow& r, bool fluxgate, bool with_single, bool with_window = true,
                   int turn_change_points = TrackerOptions{}.batch_turn_change_points,
                   const MultiTrackerOptions& base = {}) {
  const PassScenario sc = Scenario(r, fluxgate, r.seed);
  const SimulatedPass sim = SimulatePass(sc);
  const testing::TruthTrack truth = testing::TruthOf(sim);
  MultiTrackerOptions opt = base;
  opt.track.batch_turn_change_points = turn_change_points;
  const auto epochs = GroupEpochs(sim.samples, opt.track.epoch_tolerance_s);
  PassScores s;
  for (std::size_t k = 0; k < truth.t.size(); ++k) {
    if (truth.p[k].head<2>().norm() > testing::kEvalRangeM) continue;  // the sensor at the origin
    const CtState<double> x{truth.p[k].x(), truth.p[k].y(), truth.p[k].z(), sc.speed_mps, truth.heading[k], 0.0};
    Eigen::Vector3d B;
    Eigen::Matrix3d T;
    PredictedField(x, sc.moment_body, Eigen::Vector3d::Zero(), &B, &T);
    if (T.norm() / sc.sigma_T >= opt.management.reach_tensor_snr) ++s.within_reach;
  }
  const auto tracks = SolveBatchMulti(epochs, sc.B0, opt);
  s.batch_tracks = tracks.size();
  if (!tracks.empty()) s.turn_restarts_kept = tracks.front().track.summary.num_turn_restarts_kept;
  std::vector<EpochEstimate> rows;
  for (const auto& t : tracks) rows.insert(rows.end(), t.track.epochs.begin(), t.track.epochs.end());
  s.batch = testing::ScoreTrack(rows, sim.samples, truth);
  if (with_single) {
    const TrackEstimate single = SolveBatch(epochs, sc.B0, opt.track);
    s.single = testing::ScoreTrack(single.epochs, sim.samples, truth);
  }
  if (!with_window) return s;
  s.window = testing::ScoreTrack(WindowEstimates(sim, sc.B0, opt), sim.samples, truth);
  return s;
}

void Print(const PassRow& r, bool fluxgate, const PassScores& s) {
  const auto row = [&](const char* mode, const testing::TrackMetrics& m) {
    if (m.n == 0) return;  // not run
    std::cout << "| " << r.name << " | " << r.closest_3d << " | " << (fluxgate ? "fluxgate" : "squid") << " | "
              << mode << " | " << m.rms << " | " << m.max << " | " << m.nees << " | " << m.n << " |\n";
  };
  row("batch", s.batch);
  row("former single-target batch", s.single);
  row("window", s.window);
}

struct Figures {
  double rms, max, nees;
  int n;
};
struct Documented {
  const char* pass;
  bool fluxgate;
  Figures batch, window;
};

void ExpectFigures(const testing::TrackMetrics& m, const Figures& d, const std::string& what) {
  testing::ExpectErrorFigure(m.rms, d.rms, what + " RMS");
  testing::ExpectErrorFigure(m.max, d.max, what + " max");
  testing::ExpectCountFigure(m.n, d.n, what + " epochs", 1.1);
  testing::ExpectHonestNees(m, d.nees, what);
}

// A few held-out passes of the file (docs/ACCURACY.md, "Single-vessel passes
// at 6-12 m"; every figure with the margins of reference_truth.h): the batch
// uses (nearly) every epoch within 30 m, as the former single-target batch
// over the whole pass did (before this change fewer: the approach side before
// the window track started was not used), and reports those within the
// sensor's reach (the default end rule since 2026-11-26, "The end rule
// beyond the reach by default": fluxgate h6 477 of 608, h9 322 of 387; the
// figures below are over those), meets the targets (fluxgate batch ≤ 0.2 m, window
// ≤ 0.3 m; SQUID 0.01 m) and an honest NEES. ~10 s.
TEST(SinglePass, BatchUsesEveryEpochWhereTheVesselIsSeen) {
  const std::vector<Documented> doc = {
      {"h6", true, {0.0320, 0.120, 0.728, 477}, {0.0227, 0.0566, 1.13, 345}},
      {"h9", true, {0.0763, 0.174, 3.90, 322}, {0.194, 0.455, 4.31, 210}},
      {"h10", false, {0.000649, 0.00376, 2.60, 559}, {0.000727, 0.00378, 3.50, 559}},
  };
  const auto rows = LoadPasses();
  for (const auto& d : doc) {
    const PassRow& r = Find(rows, d.pass);
    const std::string what = std::string(d.pass) + (d.fluxgate ? " fluxgate" : " SQUID");
    const PassScores s = RunPass(r, d.fluxgate, true);
    Print(r, d.fluxgate, s);
    EXPECT_EQ(s.batch_tracks, 1u) << what;
    // (Nearly) every epoch within 30 m where the vessel is within the
    // sensor's reach: with the end rule (TrackManagementOptions::
    // out_of_reach_s, on by default since 2026-11-26) the batch's rows beyond
    // it are not reported (their samples are still used). Before the rule
    // every epoch the single-target batch scored (h6 604 of 608).
    std::cout << what << ": epochs within reach " << s.within_reach << ", batch rows " << s.batch.n << "\n";
    EXPECT_GE(s.batch.n, 0.98 * s.within_reach) << what;
    EXPECT_LE(s.batch.n, s.single.n) << what;
    EXPECT_LE(s.batch.rms, d.fluxgate ? 0.2 : 0.01) << what << " batch";
    EXPECT_LE(s.window.rms, d.fluxgate ? 0.3 : 0.01) << what << " window";
    ExpectFigures(s.batch, d.batch, what + " batch");
    ExpectFigures(s.window, d.window, what + " window");
  }
}

// The batch keeps a turn that starts near the closest approach once the
// data grow weak (docs/ACCURACY.md, "The batch keeps the turn"): without the
// piecewise-constant turn-rate restarts (batch_turn_change_points = 0) the
// solve stops at a slow drift of too small a turn (t3 0.864 m, h7 0.976 m,
// mean NEES 38 / 85), a local minimum of higher cost. t3 is a tuning row, h7
// held out. Batch only (the window does not use the restarts). ~3 s.
// Run with the turn-rate Cauchy scale these restarts were built and measured
// with (2 σ, batch_turn_loss_scale_sigma = 0): at the default 1.5 σ the batch's
// own solve may already find these turns (docs/ACCURACY.md, "The batch's turn
// onset cost"), and then no restart is needed.
TEST(SinglePass, BatchKeepsTheTurnOnceTheDataGrowWeak) {
  MultiTrackerOptions scale2;
  scale2.batch_turn_loss_scale_sigma = 0.0;
  const std::vector<std::pair<const char*, Figures>> doc = {
      {"t3", {0.0935, 0.250, 1.69, 304}},
      {"h7", {0.121, 0.307, 2.38, 410}},
  };
  const auto rows = LoadPasses();
  for (const auto& [name, d] : doc) {
    const PassRow& r = Find(rows, name);
    const std::string what = std::string(name) + " fluxgate batch";
    const PassScores s = RunPass(r, true, false, false, TrackerOptions{}.batch_turn_change_points, scale2);
    Print(r, true, s);
    EXPECT_EQ(s.batch_tracks, 1u) << what;
    EXPECT_GE(s.turn_restarts_kept, 1) << what << ": the estimate came from a restart";
    EXPECT_LE(s.batch.rms, 0.2) << what;
    ExpectFigures(s.batch, d, what);
  }
}

// The batch restarted from the window track that found the vessel
// (MultiTrackerOptions::batch_restart_from_window; docs/ACCURACY.md, "The
// batch restarted from the window track"): h12 (held out, 12 m, a 0.01 rad/s
// turn) and two noise draws of h6 (seeds 3103 and 3109 of
// scripts/tracker_calibration's 20) where the turn-rate restarts alone stop
// at too small a turn (0.401, 0.534, 0.601 m; mean NEES 4.4-12). With the
// window start: ≤ 0.2 m and an honest NEES. Fails without it. Batch only, ~3 s.
// With the turn-rate Cauchy scale it was built and measured with (2 σ,
// batch_turn_loss_scale_sigma = 0): at 1 σ the batch's own solve found these
// turns (h12 0.116 m, 3103 0.125 m, 3109 0.151 m), no restart kept.
TEST(SinglePass, BatchRestartedFromTheWindowTrackFindsTheTurn) {
  MultiTrackerOptions scale2;
  scale2.batch_turn_loss_scale_sigma = 0.0;
  struct Case {
    const char* pass;
    std::uint64_t seed;  // 0: the row's own
    Figures d;
  };
  const std::vector<Case> doc = {
      {"h12", 0, {0.0771, 0.247, 0.547, 364}},
      {"h6", 3103, {0.0841, 0.266, 2.17, 476}},
      {"h6", 3109, {0.110, 0.319, 2.64, 476}},
  };
  const auto rows = LoadPasses();
  for (const auto& c : doc) {
    PassRow r = Find(rows, c.pass);
    if (c.seed != 0) r.seed = c.seed;
    const std::string what = std::string(c.pass) + " seed " + std::to_string(r.seed) + " fluxgate batch";
    const PassScores s = RunPass(r, true, false, false, TrackerOptions{}.batch_turn_change_points, scale2);
    Print(r, true, s);
    EXPECT_EQ(s.batch_tracks, 1u) << what;
    EXPECT_GE(s.turn_restarts_kept, 1) << what << ": the estimate came from a restart";
    EXPECT_LE(s.batch.rms, 0.2) << what;
    if (c.seed != 0) {
      ExpectFigures(s.batch, c.d, what);
    } else {
      // h12's per-epoch NEES is correlated over 166 epochs (> the 150 of
      // ExpectHonestNees): the figures and the χ² bound, not the τ limit.
      testing::ExpectErrorFigure(s.batch.rms, c.d.rms, what + " RMS");
      testing::ExpectErrorFigure(s.batch.max, c.d.max, what + " max");
      testing::ExpectCountFigure(s.batch.n, c.d.n, what + " epochs", 1.1);
      EXPECT_LE(s.batch.nees, testing::NeesUpperBound(s.batch)) << what;
      testing::ExpectErrorFigure(s.batch.nees, c.d.nees, what + " NEES");
    }
  }
}

// Σ e_z² / Σ σ_z² over the window's coasting rows of a pass (the depth's
// share of the NEES there; 1 if its σ is honest).
double CoastingDepthRatio(const PassRow& r, const MultiTrackerOptions& opt, int* rows) {
  const PassScenario sc = Scenario(r, true, r.seed);
  const SimulatedPass sim = SimulatePass(sc);
  const testing::TruthTrack truth = testing::TruthOf(sim);
  std::map<long, std::size_t> at;
  for (std::size_t i = 0; i < truth.t.size(); ++i) at[std::lround(truth.t[i] * 10.0)] = i;
  MultiTracker window(sc.B0, opt);
  double e2 = 0.0, s2 = 0.0;
  *rows = 0;
  const auto take = [&](const std::vector<TrackOutput>& out) {
    for (const auto& o : out) {
      const auto it = at.find(std::lround(o.estimate.t_s * 10.0));
      if (o.state != TrackState::kCoasting || !o.estimate.has_covariance || it == at.end()) continue;
      const double ez = o.estimate.p_VinW.z() - truth.p[it->second].z();
      e2 += ez * ez;
      s2 += o.estimate.cov_state(2, 2);
      ++*rows;
    }
  };
  for (const auto& smp : sim.samples) take(window.AddSample(smp));
  take(window.Flush());
  return *rows > 0 ? e2 / s2 : 0.0;
}

// The depth walk where the depth is not observed
// (ProcessNoise::depth_weak_m_per_sqrt_s; docs/ACCURACY.md, "The depth walk
// where the depth is not observed"): with one walk everywhere (0.01 m/√s,
// main's) the window's depth σ while coasting grew as √t while the depth
// error of a depth-keeping vessel did not (8 runs of h9: e_z²/σ_z² 0.039).
// With the stiff walk (3e-4; the multi-vessel tracker's default since branch
// tsigma2, MultiTrackerOptions::kFieldDepthWeakMPerSqrtS) from epochs whose every
// measured tensor is < 10 σ_T the ratio on h6 and h9 (held out, fluxgate,
// the rows' own draws) is 0.547 and 0.270: asserted above its figure / 1.5
// (the margin of reference_truth.h) and ≤ 3. With the walk off (main's
// default before, printed) it is 0.137 and 0.074: the same assertion fails. Window only, ~1 s.
// The coasting rows are those of the track after it left the sensor's reach:
// with the default end rule (TrackManagementOptions::out_of_reach_s 2 s,
// since 2026-11-26) the window track ends 2 s out of reach and has none, so
// this test of the σ in those rows turns the rule off (out_of_reach_s 0).
TEST(SinglePass, WindowDepthSigmaWhileCoastingFollowsItsError) {
  const auto rows = LoadPasses();
  for (const auto& [name, documented] : {std::pair<const char*, double>{"h6", 0.547}, {"h9", 0.270}}) {
    const PassRow& r = Find(rows, name);
    int n = 0;
    MultiTrackerOptions on;
    on.track.process.depth_weak_m_per_sqrt_s = 3e-4;  // MultiTrackerOptions' default; set here as measured
    on.management.out_of_reach_s = 0.0;               // the rows beyond the reach (see above)
    const double ratio = CoastingDepthRatio(r, on, &n);
    MultiTrackerOptions off;
    off.track.process.depth_weak_m_per_sqrt_s = 0.0;
    off.management.out_of_reach_s = 0.0;
    int n_off = 0;
    const double ratio_off = CoastingDepthRatio(r, off, &n_off);
    std::cout << name << " fluxgate window coasting: e_z^2/sigma_z^2 " << ratio << " (" << n << " rows); one walk "
              << ratio_off << " (" << n_off << " rows)\n";
    EXPECT_GE(n, 100) << name;
    EXPECT_GE(ratio, documented / testing::kFigureMargin) << name;
    EXPECT_LE(ratio, 3.0) << name;
  }
}

// The batch's coasting rows of a pass (SolveBatchMulti, as `magnav track`):
// Σ e_z² / Σ σ_z² (the depth's share of the NEES there; 1 if its σ is
// honest) and the mean 3-dof position NEES (full 3 × 3 P).
struct BatchCoasting {
  double depth_ratio = 0.0, anees = 0.0;
  int rows = 0;
};
BatchCoasting BatchCoastingOf(const PassRow& r, const MultiTrackerOptions& opt) {
  const PassScenario sc = Scenario(r, true, r.seed);
  const SimulatedPass sim = SimulatePass(sc);
  const testing::TruthTrack truth = testing::TruthOf(sim);
  std::map<long, std::size_t> at;
  for (std::size_t i = 0; i < truth.t.size(); ++i) at[std::lround(truth.t[i] * 10.0)] = i;
  const auto tracks = SolveBatchMulti(GroupEpochs(sim.samples, opt.track.epoch_tolerance_s), sc.B0, opt);
  double e2 = 0.0, s2 = 0.0, nees = 0.0;
  BatchCoasting out;
  for (const auto& t : tracks) {
    for (std::size_t k = 0; k < t.track.epochs.size() && k < t.states.size(); ++k) {
      const EpochEstimate& e = t.track.epochs[k];
      const auto it = at.find(std::lround(e.t_s * 10.0));
      if (t.states[k] != TrackState::kCoasting || !e.usable || !e.has_covariance || it == at.end()) continue;
      const Eigen::Vector3d err = e.p_VinW - truth.p[it->second];
      if (err.norm() > 5.0) continue;  // as scripts/tracker_calibration
      e2 += err.z() * err.z();
      s2 += e.cov_state(2, 2);
      nees += err.dot(e.cov_p_W().ldlt().solve(err));
      ++out.rows;
    }
  }
  if (out.rows > 0) {
    out.depth_ratio = e2 / s2;
    out.anees = nees / out.rows;
  }
  return out;
}

// The multi-vessel tracker's default (MultiTrackerOptions::
// kFieldDepthWeakMPerSqrtS, 3e-4 from epochs whose every tensor is < 10 σ_T)
// makes the batch's coasting σ follow its error in depth (docs/ACCURACY.md,
// "Tracker σ over 20 draws, and the depth walk on by default"). h6 and h9
// fluxgate, the rows' own draws, default options: the batch's Σ e_z² / Σ σ_z²
// over its coasting rows is 0.578 and 0.268, asserted above its figure / 1.5
// and ≤ 3; main's default (one walk, 0.01 m/√s) gives 0.124 and 0.050 (fails). The
// coasting rows' ANEES (printed, not asserted on one draw: the 20-draw figures
// are in docs/ACCURACY.md). 4–7 s on the loaded shared machine.
// The coasting rows are those beyond the sensor's reach: with the default end
// rule (out_of_reach_s 2 s, since 2026-11-26) the batch does not report them
// (0 rows), so this test of their σ turns the rule off ("by default" is the
// depth walk's default).
TEST(SinglePass, BatchDepthSigmaWhileCoastingFollowsItsErrorByDefault) {
  const auto rows = LoadPasses();
  for (const auto& [name, documented] : {std::pair<const char*, double>{"h6", 0.578}, {"h9", 0.268}}) {
    const PassRow& r = Find(rows, name);
    MultiTrackerOptions opt;
    opt.management.out_of_reach_s = 0.0;  // the rows beyond the reach (see above)
    const BatchCoasting c = BatchCoastingOf(r, opt);
    std::cout << name << " fluxgate batch coasting (default options): e_z^2/sigma_z^2 " << c.depth_ratio
              << ", ANEES " << c.anees << " (" << c.rows << " rows)\n";
    EXPECT_GE(c.rows, 50) << name;
    EXPECT_GE(c.depth_ratio, documented / testing::kFigureMargin) << name;
    EXPECT_LE(c.depth_ratio, 3.0) << name;
  }
}

// The batch's turn onset cost (MultiTrackerOptions::batch_turn_loss_scale_sigma;
// docs/ACCURACY.md, "The batch's turn onset cost"): on f20 and f22 (set
// fresh2, blind for the work before this; a 0.015 rad/s turn starting 5 s
// after the closest approach at 7.2 / 9.6 m) the batch with the Cauchy scale
// of the single-target batch (2 σ; 0 = inherit it) kept a straight path that
// drifts sideways once the data grow weak (0.678 / 0.498 m within 30 m, mean
// NEES 8 / 14 by `magnav evaluate`): at 2 σ a 160 σ onset costs ≈ 17.5, more
// than the far B samples gain from the turn (from the truth, f22's problem
// ended 0.38 higher). At the default 1.5 σ (≈ 10.5): ≤ 0.2 m and an honest NEES. Asserted:
// RMS ≤ 0.2 m, RMS, max and n within the margins of reference_truth.h, NEES
// honest; the old scale > 0.3 m on f20 (the test can tell). Batch only, ~3 s.
TEST(SinglePass, BatchTurnOnsetCostLetsTheFarTurnBeFound) {
  MultiTrackerOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  EXPECT_EQ(o.batch_turn_loss_scale_sigma, 1.5);
  o.batch_turn_loss_scale_sigma = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("batch_turn_loss_scale_sigma"), std::string::npos);
  const std::vector<std::pair<const char*, Figures>> doc = {
      // Measured on main after the merges of 2026-11-26 evening (the batch's
      // rows within the reach only, since the end rule's default: 395 and 381
      // epochs before, RMS 0.107 / 0.0714 m over them).
      {"f20", {0.0651, 0.152, 2.50, 302}},
      {"f22", {0.0545, 0.134, 2.36, 305}},
  };
  const auto rows = LoadPasses();
  for (const auto& [name, d] : doc) {
    const PassRow& r = Find(rows, name);
    const std::string what = std::string(name) + " fluxgate batch";
    const PassScores s = RunPass(r, true, false, false);
    Print(r, true, s);
    EXPECT_EQ(s.batch_tracks, 1u) << what;
    EXPECT_LE(s.batch.rms, 0.2) << what;
    ExpectFigures(s.batch, d, what);
  }
  MultiTrackerOptions old;
  old.batch_turn_loss_scale_sigma = 0.0;  // track.process's 2 σ, as before
  const PassScores s =
      RunPass(Find(rows, "f20"), true, false, false, TrackerOptions{}.batch_turn_change_points, old);
  std::cout << "f20 fluxgate batch, turn loss scale 2 sigma: RMS " << s.batch.rms << " m\n";
  // Measured 0.322 m over the rows within reach (0.678 m over every row,
  // before the end rule's default): the 2 σ scale misses the 0.2 m target.
  EXPECT_GT(s.batch.rms, 0.2);
}

// The window alone on one pass (MultiTracker, every sample), scored within
// 30 m of the sensor.
testing::TrackMetrics RunWindowOnly(const PassRow& r, const MultiTrackerOptions& opt) {
  const PassScenario sc = Scenario(r, true, r.seed);
  const SimulatedPass sim = SimulatePass(sc);
  const testing::TruthTrack truth = testing::TruthOf(sim);
  return testing::ScoreTrack(WindowEstimates(sim, sc.B0, opt), sim.samples, truth);
}

// The window's turn onset as a model choice (TrackerOptions::
// window_turn_onset_model, off by default; docs/ACCURACY.md, "The window's
// turn onset as a model choice"): on f16 (fluxgate, CA 9.5 m, a −0.02 rad/s
// turn from 80 s) the default window's loose turn-rate walk spreads the
// onset as a ramp and its newest heading lags the turn (0.482 m within 30 m
// by `magnav evaluate`); with the onset model (the batch's stiff walk and one
// free jump, chosen by data cost + BIC and, since session 17, a significant
// jump, found by the fast search: "The window's turn onset: cheap and
// guarded") the onset is found at 80 s and the window meets ≤ 0.3 m with an
// honest NEES (0.251 m; session 16's full search without the guard 0.236 m).
// Asserted: ≤ 0.3 m, RMS, max and n within the margins of reference_truth.h,
// NEES honest; without the option > 0.3 m (the test can tell). Window only,
// ~0.5 s.
TEST(SinglePass, WindowTurnOnsetModelKeepsTheTurn) {
  TrackerOptions o;
  std::string why;
  EXPECT_FALSE(o.window_turn_onset_model);
  EXPECT_TRUE(o.IsValid(&why)) << why;
  using testing::ExpectRefused;
  ExpectRefused<TrackerOptions>([](auto& x) { x.window_turn_onset_bic_params = -1.0; }, "window_turn_onset_bic_params");
  ExpectRefused<TrackerOptions>([](auto& x) { x.window_turn_onset_grid_s = 0.0; }, "window_turn_onset_grid_s");
  ExpectRefused<TrackerOptions>([](auto& x) { x.window_turn_onset_iterations = 0; }, "window_turn_onset_iterations");
  ExpectRefused<TrackerOptions>([](auto& x) { x.window_turn_onset_jump_sigmas = -1.0; },
                                "window_turn_onset_jump_sigmas");
  ExpectRefused<TrackerOptions>([](auto& x) { x.window_turn_onset_trigger_sigmas = std::nan(""); },
                                "window_turn_onset_trigger_sigmas");
  ExpectRefused<TrackerOptions>([](auto& x) { x.window_turn_onset_coarse_grid_s = 0.0; },
                                "window_turn_onset_coarse_grid_s");
  EXPECT_EQ(TrackerOptions{}.window_turn_onset_search, TrackerOptions::OnsetSearch::kFast);
  EXPECT_EQ(TrackerOptions{}.window_turn_onset_jump_sigmas, 3.0);

  const auto rows = LoadPasses();
  const PassRow& r = Find(rows, "f16");
  MultiTrackerOptions on;
  on.track.window_turn_onset_model = true;
  const testing::TrackMetrics m = RunWindowOnly(r, on);
  std::cout << "f16 fluxgate window, turn onset model: RMS " << m.rms << " m, max " << m.max << " m, NEES "
            << m.nees << ", n " << m.n << "\n";
  EXPECT_LE(m.rms, 0.3);
  ExpectFigures(m, {0.251, 0.489, 2.55, 275}, "f16 fluxgate window, turn onset model");
  const testing::TrackMetrics off = RunWindowOnly(r, MultiTrackerOptions{});
  std::cout << "f16 fluxgate window, default: RMS " << off.rms << " m\n";
  EXPECT_GT(off.rms, 0.3);
}

// The onset model's cost and its guard (TrackerOptions::window_turn_onset_*;
// docs/ACCURACY.md, "The window's turn onset: cheap and guarded"): a
// WindowTracker alone with the option on, solved every 0.5 s as in
// MultiTracker. `counts` = the summary's candidate solves per window solve.
Summary RunOnsetWindow(const PassRow& r, const TrackerOptions& base, int* solves) {
  const PassScenario sc = Scenario(r, true, r.seed);
  const SimulatedPass sim = SimulatePass(sc);
  TrackerOptions o = base;
  o.window_turn_onset_model = true;
  o.window_solve_interval_s = 0.5;
  WindowTracker w(sc.B0, o);
  *solves = 0;
  const auto count = [&](const std::vector<EpochEstimate>& out) { *solves += out.empty() ? 0 : 1; };
  for (const auto& smp : sim.samples) count(w.AddSample(smp));
  count(w.Flush());
  return w.last_summary();
}

// On f16 (fluxgate) the fast search (near the previous try's onset, else
// only when the default's turn rate spans more than 3 σ of the stiff walk).
// Asserted: its candidate solves per window solve within 1.5× of its figure
// (a 2× regression fails), and at most a fifth of the full search's (every
// 1 s onset of a 20 s window and "no onset": 19-20 per solve, not run here:
// ~10 s). ~0.3 s.
TEST(SinglePass, WindowTurnOnsetFastSearchIsCheap) {
  constexpr double kFastPerFigure = 1.67;
  const auto rows = LoadPasses();
  const PassRow& r = Find(rows, "f16");
  int solves = 0;
  const Summary fast = RunOnsetWindow(r, TrackerOptions{}, &solves);
  ASSERT_GT(solves, 0);
  const double fast_per = static_cast<double>(fast.num_turn_onset_candidate_solves) / solves;
  std::cout << "f16 window, candidate solves per window solve (" << solves << " solves): fast " << fast_per
            << " (tries " << fast.num_turn_onset_tries << ", chosen " << fast.num_turn_onset_chosen
            << ", refused by the jump " << fast.num_turn_onset_refused_jump << ", iterations per candidate "
            << static_cast<double>(fast.num_turn_onset_iterations) / std::max(fast.num_turn_onset_candidate_solves, 1)
            << ")\n";
  EXPECT_LE(fast_per, kFastPerFigure * testing::kFigureMargin);
  EXPECT_LE(fast_per, 19.0 / 5.0);
  EXPECT_GT(fast.num_turn_onset_chosen, 0);
}

// The guard on the onset's jump (window_turn_onset_jump_sigmas, 3 σ): on h9
// (fluxgate, CA 9 m, no turn) few onsets are emitted with the guard; without it
// (0) the onset model's best onset is emitted where the BIC lets it: 109
// of 109 tries; with it 5 of 60 (tries: the fast search's trigger). Asserted:
// chosen with the guard within 1.5× of 5, without it ≥ 50. ~1 s.
TEST(SinglePass, WindowTurnOnsetGuardRefusesInsignificantJumps) {
  const auto rows = LoadPasses();
  const PassRow& r = Find(rows, "h9");
  TrackerOptions guarded, unguarded;
  unguarded.window_turn_onset_jump_sigmas = 0.0;
  int solves = 0;
  const Summary g = RunOnsetWindow(r, guarded, &solves);
  const Summary u = RunOnsetWindow(r, unguarded, &solves);
  std::cout << "h9 window (no turn): guarded tries " << g.num_turn_onset_tries << ", chosen "
            << g.num_turn_onset_chosen << ", refused by the jump " << g.num_turn_onset_refused_jump
            << "; unguarded tries " << u.num_turn_onset_tries << ", chosen " << u.num_turn_onset_chosen << "\n";
  EXPECT_LE(g.num_turn_onset_chosen, 5 * testing::kFigureMargin);
  EXPECT_GE(u.num_turn_onset_chosen, 50);
}

// A try that does not choose the onset model emits the default's rows as
// they are (docs/ACCURACY.md, "The window's turn onset at scale"): the
// default solution's factorisation is kept across the candidates and put
// back, and the covariance the trigger's noise test computed is emitted,
// instead of factorising again. On f16 (fluxgate, a turn from 80 s: many
// tries), a WindowTracker alone with the option on and every try refused by
// the jump's guard (1e9 σ), with and without the noise test (1.5), emits
// exactly the default's states and covariances. ~0.6 s.
TEST(SinglePass, WindowTurnOnsetRefusedTryEmitsTheDefault) {
  const auto rows = LoadPasses();
  const PassRow& r = Find(rows, "f16");
  const PassScenario sc = Scenario(r, true, r.seed);
  const SimulatedPass sim = SimulatePass(sc);
  const auto run = [&](bool onset, double noise, Summary* summary) {
    TrackerOptions o;
    o.window_solve_interval_s = 0.5;
    o.window_turn_onset_model = onset;
    o.window_turn_onset_jump_sigmas = 1e9;
    o.window_turn_onset_trigger_noise_sigmas = noise;
    WindowTracker w(sc.B0, o);
    std::vector<EpochEstimate> out;
    for (const auto& smp : sim.samples) {
      for (auto& e : w.AddSample(smp)) out.push_back(e);
    }
    for (auto& e : w.Flush()) out.push_back(e);
    *summary = w.last_summary();
    return out;
  };
  Summary s_off, s_on, s_noise;
  const std::vector<EpochEstimate> off = run(false, 0.0, &s_off);
  for (const double noise : {0.0, 1.5}) {
    Summary& s = noise > 0.0 ? s_noise : s_on;
    const std::vector<EpochEstimate> on = run(true, noise, &s);
    const std::string what = noise > 0.0 ? "with the noise test" : "without the noise test";
    std::cout << "f16 window, every try refused (" << what << "): tries " << s.num_turn_onset_tries << ", refused by the jump "
              << s.num_turn_onset_refused_jump << ", noise vetoes " << s.num_turn_onset_noise_vetoes << "\n";
    EXPECT_GE(s.num_turn_onset_tries, 10) << what;
    EXPECT_EQ(s.num_turn_onset_chosen, 0) << what;
    ASSERT_EQ(on.size(), off.size()) << what;
    int differ = 0;
    for (std::size_t k = 0; k < on.size(); ++k) {
      const bool same = on[k].t_s == off[k].t_s && on[k].p_VinW == off[k].p_VinW &&
                        on[k].heading_rad == off[k].heading_rad && on[k].has_covariance == off[k].has_covariance &&
                        on[k].cov_state == off[k].cov_state;
      differ += same ? 0 : 1;
    }
    EXPECT_EQ(differ, 0) << what << ": rows not the default's";
  }
  EXPECT_GT(s_noise.num_turn_onset_noise_vetoes, 0);
}

// The tries' sources and the trigger's noise test (TrackerOptions::
// window_turn_onset_trigger_noise_sigmas, off by default; docs/ACCURACY.md,
// "The window's turn onset at scale"): on h9 (fluxgate, CA 9 m, no turn) the
// default's turn rate spans more than 3 σ of the stiff walk on 60 of 252
// solves (its own σ of ω is larger than the stiff walk's over the window),
// so the session-17 trigger fires where nothing turns: 60 tries; with the
// noise test at 1.5 σ all 60 triggers are turned down: 0 tries. A
// WindowTracker alone every 0.5 s (RunOnsetWindow). Asserted: the counters
// add up; without the test the trigger fires on at least kTriggered / the
// margin solves; with it at most 5 tries (the session-17 trigger's 60 fail
// it). And on f16 (a turn) the test keeps the turn (≤ 0.3 m). ~1.5 s.
TEST(SinglePass, WindowTurnOnsetNoiseTestSkipsQuietTriggers) {
  constexpr int kTriggered = 60;
  const auto rows = LoadPasses();
  const PassRow& h9 = Find(rows, "h9");
  TrackerOptions plain, noise;
  noise.window_turn_onset_trigger_noise_sigmas = 1.5;
  int solves = 0, solves_noise = 0;
  const Summary p = RunOnsetWindow(h9, plain, &solves);
  const Summary q = RunOnsetWindow(h9, noise, &solves_noise);
  std::cout << "h9 window (no turn), " << p.num_window_solves << " window solves: triggered " << p.num_turn_onset_triggered
            << ", tries " << p.num_turn_onset_tries << " (grid " << p.num_turn_onset_grid_searches << "), candidates "
            << p.num_turn_onset_candidate_solves << "; with the noise test: vetoes " << q.num_turn_onset_noise_vetoes
            << ", tries " << q.num_turn_onset_tries << ", candidates " << q.num_turn_onset_candidate_solves << "\n";
  for (const Summary* s : {&p, &q}) {
    EXPECT_GT(s->num_window_solves, 0);
    EXPECT_LE(s->num_turn_onset_tries, s->num_window_solves);
    EXPECT_LE(s->num_turn_onset_grid_searches, s->num_turn_onset_tries);
    EXPECT_LE(s->num_turn_onset_triggered, s->num_window_solves);
    EXPECT_GE(s->num_turn_onset_candidate_solves, s->num_turn_onset_tries);
  }
  EXPECT_EQ(q.num_turn_onset_triggered, p.num_turn_onset_triggered);  // the test comes after the trigger
  EXPECT_EQ(p.num_turn_onset_noise_vetoes, 0);
  EXPECT_GE(p.num_turn_onset_triggered, kTriggered / testing::kFigureMargin);
  EXPECT_LE(q.num_turn_onset_tries, 5);
  EXPECT_GE(q.num_turn_onset_noise_vetoes, q.num_turn_onset_triggered - q.num_turn_onset_tries);

  const PassRow& f16 = Find(rows, "f16");
  MultiTrackerOptions on;
  on.track.window_turn_onset_model = true;
  on.track.window_turn_onset_trigger_noise_sigmas = 1.5;
  const testing::TrackMetrics m = RunWindowOnly(f16, on);
  std::cout << "f16 fluxgate window, turn onset model with the noise test: RMS " << m.rms << " m, n " << m.n << "\n";
  EXPECT_LE(m.rms, 0.3);
  using testing::ExpectRefused;
  ExpectRefused<TrackerOptions>([](auto& x) { x.window_turn_onset_trigger_noise_sigmas = -1.0; },
                                "window_turn_onset_trigger_noise_sigmas");
  ExpectRefused<TrackerOptions>([](auto& x) { x.window_turn_onset_trigger_noise_sigmas = std::nan(""); },
                                "window_turn_onset_trigger_noise_sigmas");
  EXPECT_EQ(TrackerOptions{}.window_turn_onset_trigger_noise_sigmas, 0.0);
}

}  // namespace
}  // namespace magnav::tracker
