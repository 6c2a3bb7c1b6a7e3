// The multi-vessel tracker at scale (issue 13 item 4): an N x N gradiometer
// grid (40 m spacing) at 10 Hz crossed by V AUV-sized vessels at once, run
// through MultiTracker (window mode, as magnav-tracker) on one core.
// Reported per run: cpu_s_per_data_s (CPU seconds per second of data: the
// target is <= 0.1 for 100 sensors and 10 vessels), the cost per epoch, the
// tracks found, and `ratio_to_forward_model`: the tracker's time over the
// time of evaluating every vessel's field at every sensor for every epoch
// once (the host-independent figure).
// Layout 0: every two vessels >= 80 m apart (below); layout 1: pairs abreast
// (issue 24: V/2 pairs, each two vessels 24 m apart side by side, 12 m either
// side of a sensor column, so that the column between them sees both alike).
// Run: build/bin/bench_multi_tracker (scenarios built here with SimulateField).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <tuple>

#include "magnav/core/dipole.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"

namespace {

using magnav::FieldScenario;
using magnav::FieldVessel;
using magnav::SimulatedField;

// V vessels heading north along the grid columns, 2 m off the column, 5-6 m
// above the sensors: the first half on every other column (0, 2, 4, ...,
// 80 m apart) starting 10-20 m before the first row, the second half on the
// columns between (1, 3, ...) starting at the middle row, so that every two
// vessels are at least 80 m apart; each crosses two or three rows in 60 s.
// (Vessels side by side: layout 1 above.)
FieldScenario Scenario(int n, int vessels, double duration_s, int layout) {
  FieldScenario sc;
  sc.sensors = magnav::SensorGrid(n, n, 40.0);
  const double half = 20.0 * (n - 1);
  for (int v = 0; v < vessels && layout == 1; ++v) {
    // Pair p on column 2p (80 m between pairs), its two vessels at -12 m and
    // +12 m east of it, both starting 10 m before the first row.
    FieldVessel fv;
    fv.vessel_id = static_cast<std::uint32_t>(v + 1);
    fv.moment_body = {2000.0 + 100.0 * v, 300.0 - 60.0 * v, 800.0};
    const int pair = v / 2;
    const double column = -half + 40.0 * ((2 * pair) % n) + (v % 2 == 0 ? -12.0 : 12.0);
    fv.start_position = {-half - 10.0 - 2.0 * pair, column, -5.0 - 0.1 * v};
    fv.start_heading_rad = 0.0;
    fv.speed_mps = 1.5;
    fv.segments = {{duration_s, 0.0}};
    sc.vessels.push_back(fv);
  }
  for (int v = 0; v < vessels && layout == 0; ++v) {
    FieldVessel fv;
    fv.vessel_id = static_cast<std::uint32_t>(v + 1);
    fv.moment_body = {2000.0 + 100.0 * v, 300.0 - 60.0 * v, 800.0};
    const int k = v % n;
    const int c = 2 * k < n ? 2 * k : 2 * k - n + (n % 2 == 0 ? 1 : 0);
    const double column = -half + 40.0 * c + 2.0;
    const double x0 = 2 * k < n ? -half - 10.0 : -10.0;
    fv.start_position = {x0 - 10.0 * (v % 2), column, -5.0 - 0.1 * v};
    fv.start_heading_rad = 0.0;
    fv.speed_mps = 1.5;
    fv.segments = {{duration_s, 0.0}};
    sc.vessels.push_back(fv);
  }
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 7;
  return sc;
}

const SimulatedField& Field(int n, int vessels, double duration_s, int layout) {
  static std::map<std::tuple<int, int, double, int>, SimulatedField> cache;
  const auto key = std::make_tuple(n, vessels, duration_s, layout);
  auto it = cache.find(key);
  if (it == cache.end()) {
    it = cache.emplace(key, magnav::SimulateField(Scenario(n, vessels, duration_s, layout))).first;
  }
  return it->second;
}

// Seconds to evaluate every vessel's B and T at every sensor, every epoch.
double ForwardModelSeconds(const FieldScenario& sc, const SimulatedField& f) {
  const auto t0 = std::chrono::steady_clock::now();
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  for (const auto& vessel : f.truth) {
    for (std::size_t k = 0; k < vessel.size(); ++k) {
      for (const auto& p : sc.sensors) {
        Eigen::Vector3d B;
        Eigen::Matrix3d T;
        magnav::DipoleBT(p - vessel[k].p_VinW, vessel[k].m_W, &B, &T);
        acc += B + T.col(0);
      }
    }
  }
  benchmark::DoNotOptimize(acc);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Args: grid side N, vessels V, window solve interval (ms; 0 = every epoch;
// the multi-tracker's default is 500), layout (0 apart, 1 pairs abreast),
// background model: 0 the defaults (fixed B0 and the far source,
// far_source.h, on by default since 2026-11-26); 1 the cluster background
// (cluster_background.h, with the mean and largest number of tracks per
// cluster of its offset steps; the far source off, they are exclusive); 2 the
// fixed B0 alone (the far source off: its cost is the difference with 0).
// turn_onset: the window's turn-onset model on (TrackerOptions::
// window_turn_onset_model, its fast search; BM_MultiTrackerFieldTurnOnset),
// with the trigger's noise test at noise_sigmas (0 = off; TrackerOptions::
// window_turn_onset_trigger_noise_sigmas; BM_MultiTrackerFieldTurnOnsetNoise).
// With it on, the onset model's work is reported as counts (MultiSummary::
// turn_onset: they do not depend on the machine's load): window solves,
// tries, grid searches, candidate solves per window solve.
// drift_flags: the window's drift flags for a field known to drift
// (--window-offset-lines on --window-offset-score-test on
// --window-offset-rate-sigma 1e-10; docs/ACCURACY.md, "The drift flags as the
// window's defaults"), the score test latched after it has fired for
// persist_s (SensorOffsetOptions::window_score_persist_s; 0 = at its first
// firing).
void RunField(benchmark::State& state, bool turn_onset, double noise_sigmas = 0.0, bool drift_flags = false,
              double persist_s = 0.0) {
  const int n = static_cast<int>(state.range(0));
  const int vessels = static_cast<int>(state.range(1));
  const double solve_interval_s = static_cast<double>(state.range(2)) * 1e-3;
  const int layout = static_cast<int>(state.range(3));
  const double duration_s = layout == 1 ? 120.0 : 60.0;
  const FieldScenario sc = Scenario(n, vessels, duration_s, layout);
  const SimulatedField& f = Field(n, vessels, duration_s, layout);
  magnav::tracker::MultiTrackerOptions opt;
  opt.track.window_solve_interval_s = solve_interval_s;
  opt.cluster_background.enabled = state.range(4) == 1;
  opt.track.window_turn_onset_model = turn_onset;
  opt.track.window_turn_onset_trigger_noise_sigmas = noise_sigmas;
  if (state.range(4) != 0) opt.far_source.enabled = false;
  if (drift_flags) {
    opt.track.sensor_offset.window_lines = true;
    opt.track.sensor_offset.window_score_test = true;
    opt.track.sensor_offset.line_rate_sigma_T_per_s = 1e-10;
    opt.track.sensor_offset.window_score_persist_s = persist_s;
  }
  int tracks = 0;
  magnav::tracker::MultiSummary summary;
  double cpu_s = 0.0;
  std::vector<magnav::tracker::TrackOutput> rows;
  for (auto _ : state) {
    rows.clear();
    const std::clock_t c0 = std::clock();
    magnav::tracker::MultiTracker tracker(sc.B0, opt);
    for (const auto& s : f.samples) {
      for (auto& o : tracker.AddSample(s)) rows.push_back(std::move(o));
    }
    for (auto& o : tracker.Flush()) rows.push_back(std::move(o));
    cpu_s = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
    tracks = tracker.summary().num_confirmed;
    summary = tracker.summary();
  }
  if (opt.cluster_background.enabled) {
    state.counters["cluster_tracks_mean"] =
        summary.num_clusters > 0 ? static_cast<double>(summary.num_cluster_tracks) / summary.num_clusters : 0.0;
    state.counters["cluster_tracks_max"] = summary.max_cluster_tracks;
  }
  // Accuracy alongside (untimed): each row against the nearest vessel.
  double sum_sq = 0.0;
  int near = 0, false_rows = 0;
  for (const auto& o : rows) {
    double best = 1e300;
    const auto k = static_cast<std::size_t>(std::llround(o.estimate.t_s * sc.rate_hz));
    for (const auto& v : f.truth) {
      if (k < v.size()) best = std::min(best, (o.estimate.p_VinW - v[k].p_VinW).norm());
    }
    if (best > 5.0) {
      ++false_rows;
    } else {
      sum_sq += best * best;
      ++near;
    }
  }
  // Vessels with at least one row within 5 m (each row to its nearest).
  std::vector<int> rows_of(f.truth.size(), 0);
  for (const auto& o : rows) {
    const auto k = static_cast<std::size_t>(std::llround(o.estimate.t_s * sc.rate_hz));
    double best = 5.0;
    std::size_t who = f.truth.size();
    for (std::size_t v = 0; v < f.truth.size(); ++v) {
      if (k < f.truth[v].size() && (o.estimate.p_VinW - f.truth[v][k].p_VinW).norm() < best) {
        best = (o.estimate.p_VinW - f.truth[v][k].p_VinW).norm();
        who = v;
      }
    }
    if (who < f.truth.size()) ++rows_of[who];
  }
  state.counters["vessels_tracked"] =
      static_cast<double>(std::count_if(rows_of.begin(), rows_of.end(), [](int r) { return r > 0; }));
  state.counters["rms_m"] = near > 0 ? std::sqrt(sum_sq / near) : 0.0;
  state.counters["false_rows"] = false_rows;
  const double epochs = duration_s * 10.0 + 1.0;
  state.counters["sensors"] = n * n;
  state.counters["vessels"] = vessels;
  state.counters["tracks"] = tracks;
  state.counters["cpu_s_per_data_s"] = cpu_s / duration_s;
  state.counters["ms_per_epoch"] = 1e3 * cpu_s / epochs;
  state.counters["ratio_to_forward_model"] = cpu_s / ForwardModelSeconds(sc, f);
  if (turn_onset) {
    const magnav::tracker::TurnOnsetCounts& c = summary.turn_onset;
    state.counters["window_solves"] = c.window_solves;
    state.counters["onset_triggered"] = c.triggered;
    state.counters["onset_tries"] = c.tries;
    state.counters["onset_grid_searches"] = c.grid_searches;
    state.counters["onset_chosen"] = c.chosen;
    state.counters["onset_candidates_per_solve"] =
        c.window_solves > 0 ? static_cast<double>(c.candidate_solves) / c.window_solves : 0.0;
    state.counters["onset_iterations_per_solve"] =
        c.window_solves > 0 ? static_cast<double>(c.iterations) / c.window_solves : 0.0;
  }
}

void BM_MultiTrackerField(benchmark::State& state) { RunField(state, false); }
// The same with the window's turn-onset model on (docs/ACCURACY.md, "The
// window's turn onset: cheap and guarded"): the scale rows, apart and abreast.
void BM_MultiTrackerFieldTurnOnset(benchmark::State& state) { RunField(state, true); }
BENCHMARK(BM_MultiTrackerFieldTurnOnset)
    ->ArgNames({"grid", "vessels", "solve_ms", "abreast", "cluster_bg"})
    ->Args({10, 10, 500, 0, 0})
    ->Args({10, 10, 500, 1, 0})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
// The same with the trigger's noise test (docs/ACCURACY.md, "The window's
// turn onset at scale"); the last argument is its k × 10 (15: 1.5 σ).
void BM_MultiTrackerFieldTurnOnsetNoise(benchmark::State& state) {
  RunField(state, true, static_cast<double>(state.range(5)) / 10.0);
}
BENCHMARK(BM_MultiTrackerFieldTurnOnsetNoise)
    ->ArgNames({"grid", "vessels", "solve_ms", "abreast", "cluster_bg", "noise_x10"})
    ->Args({10, 10, 500, 0, 0, 15})
    ->Args({10, 10, 500, 1, 0, 15})
    ->Args({10, 10, 500, 0, 0, 20})
    ->Args({10, 10, 500, 1, 0, 20})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
// The window's drift flags at scale, apart and abreast (docs/BENCHMARKS.md:
// their cost and the pairs' RMS against the defaults' rows of
// BM_MultiTrackerField); the last argument is the score test's persistence, s.
void BM_MultiTrackerFieldDriftFlags(benchmark::State& state) {
  RunField(state, false, 0.0, true, static_cast<double>(state.range(5)));
}
BENCHMARK(BM_MultiTrackerFieldDriftFlags)
    ->ArgNames({"grid", "vessels", "solve_ms", "abreast", "cluster_bg", "persist_s"})
    ->Args({10, 10, 500, 0, 0, 0})
    ->Args({10, 10, 500, 1, 0, 0})
    ->Args({10, 10, 500, 0, 0, 3})
    ->Args({10, 10, 500, 1, 0, 3})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);
BENCHMARK(BM_MultiTrackerField)
    ->ArgNames({"grid", "vessels", "solve_ms", "abreast", "cluster_bg"})
    ->Args({3, 1, 0, 0, 0})
    ->Args({3, 3, 0, 0, 0})
    ->Args({5, 3, 0, 0, 0})
    ->Args({10, 1, 0, 0, 0})
    ->Args({10, 3, 0, 0, 0})
    ->Args({10, 10, 0, 0, 0})
    ->Args({10, 10, 500, 0, 0})
    ->Args({10, 10, 1000, 0, 0})
    ->Args({10, 10, 500, 1, 0})
    ->Args({10, 2, 500, 1, 0})
    ->Args({3, 2, 500, 1, 0})
    // Cost against cluster size (cluster background on; the same rows off above).
    ->Args({10, 1, 500, 0, 1})
    ->Args({10, 10, 500, 0, 1})
    ->Args({10, 2, 500, 1, 1})
    ->Args({10, 10, 500, 1, 1})
    ->Args({3, 2, 500, 1, 1})
    ->Args({10, 1, 500, 0, 0})
    // The far source's cost: the default rows above with it off.
    ->Args({10, 10, 500, 0, 2})
    ->Args({10, 10, 500, 1, 2})
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
