// Tracker timing: sliding-window update per new epoch (20 s window at 10 Hz)
// and batch solve of a whole 200 s pass, with 1 and 4 gradiometers.
// Run: build/bin/bench_tracker (reference files from tests/data/reference).
#include <benchmark/benchmark.h>

#include <map>
#include <string>

#include "magnav/core/gradiometer.h"
#include "magnav/tracker/tracker.h"

namespace {

using magnav::tracker::Epoch;

struct Pass {
  std::vector<Epoch> epochs;
  Eigen::Vector3d B0;
};

const Pass& LoadPass(const std::string& name) {
  static std::map<std::string, Pass> cache;
  auto it = cache.find(name);
  if (it == cache.end()) {
    const magnav::GradiometerFile f =
        magnav::ReadGradiometerFile(std::string(MAGNAV_REFERENCE_DIR) + "/track_pass_" + name + ".csv");
    Pass p;
    p.B0 = *f.B0;
    p.epochs = magnav::tracker::GroupEpochs(f.samples, magnav::tracker::TrackerOptions{}.epoch_tolerance_s);
    it = cache.emplace(name, std::move(p)).first;
  }
  return it->second;
}

std::string PassName(int64_t sensors, const std::string& vessel = "ship") {
  return vessel + (sensors == 1 ? "_1sensor_fluxgate" : "_4sensor_fluxgate");
}

// One window update (marginalisation + chain Gauss-Newton + newest covariance) per
// iteration, in steady state: the tracker is warmed up over 60 s first and
// restarted (untimed) when the pass runs out.
void BM_WindowUpdatePerEpoch(benchmark::State& state) {
  const Pass& pass = LoadPass(PassName(state.range(0)));
  magnav::tracker::TrackerOptions opt;
  opt.window_s = 20.0;
  const std::size_t warm = 600;
  std::unique_ptr<magnav::tracker::WindowTracker> tr;
  std::size_t next = pass.epochs.size();
  double iterations = 0.0;
  for (auto _ : state) {
    if (next >= pass.epochs.size()) {
      state.PauseTiming();
      tr = std::make_unique<magnav::tracker::WindowTracker>(pass.B0, opt);
      for (next = 0; next < warm; ++next) tr->AddEpoch(pass.epochs[next]);
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(tr->AddEpoch(pass.epochs[next++]));
    iterations += tr->last_summary().iterations;
  }
  state.counters["gn_iterations"] = benchmark::Counter(iterations, benchmark::Counter::kAvgIterations);
  state.counters["sensors"] = static_cast<double>(state.range(0));
  state.counters["window_epochs"] = tr->last_summary().num_epochs;
}
BENCHMARK(BM_WindowUpdatePerEpoch)->Arg(1)->Arg(4)->Unit(benchmark::kMicrosecond);

// Batch solve (initialisation + growing solve + chain covariance) of a 200 s
// pass (2001 epochs). Args: vessel (0 = ship, 1 = AUV: its turn is found
// later, more iterations), sensors, solver (0 = the default chain
// Levenberg-Marquardt, 1 = Ceres SPARSE_NORMAL_CHOLESKY on the same
// problems), threads, no_restarts (1 = batch_turn_change_points 0: the
// solve without its piecewise-constant turn-rate restarts, for their cost).
void BM_BatchSolve200s(benchmark::State& state) {
  const std::string vessel = state.range(0) == 0 ? "ship" : "auv";
  const Pass& pass = LoadPass(PassName(state.range(1), vessel));
  magnav::tracker::TrackerOptions opt;
  opt.batch_solver = state.range(2) == 0 ? magnav::tracker::TrackerOptions::BatchSolver::kChainLevenbergMarquardt
                                         : magnav::tracker::TrackerOptions::BatchSolver::kCeres;
  opt.num_threads = static_cast<int>(state.range(3));
  if (state.range(4) != 0) opt.batch_turn_change_points = 0;
  int iterations = 0;
  for (auto _ : state) {
    const auto est = magnav::tracker::SolveBatch(pass.epochs, pass.B0, opt);
    iterations = est.summary.iterations;
    benchmark::DoNotOptimize(est.m_B_Am2);
  }
  state.SetLabel(vessel + (state.range(2) == 0 ? " chain LM" : " ceres"));
  state.counters["sensors"] = static_cast<double>(state.range(1));
  state.counters["epochs"] = static_cast<double>(pass.epochs.size());
  state.counters["iterations"] = iterations;
  state.counters["threads"] = static_cast<double>(opt.num_threads);
  state.counters["change_points"] = opt.batch_turn_change_points;
}
BENCHMARK(BM_BatchSolve200s)
    ->ArgNames({"auv", "sensors", "ceres", "threads", "no_restarts"})
    ->ArgsProduct({{0, 1}, {1, 4}, {0}, {1, 2}, {0}})
    ->Args({0, 1, 1, 1, 0})
    ->Args({0, 4, 1, 1, 0})
    ->Args({1, 1, 1, 1, 0})
    ->Args({1, 4, 1, 1, 0})
    ->Args({0, 1, 0, 1, 1})
    ->Args({1, 1, 0, 1, 1})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2.0)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
