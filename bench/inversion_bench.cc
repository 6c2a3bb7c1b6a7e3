// Inversion throughput: single-sample solvers and the gated Inverter per
// sample, and one Monte-Carlo update (predict + weigh + resample when due)
// for 600 particles. Targets: TED+EGT ≥ 2e6 inversions/s on one core, MC
// update ≤ 100 µs.
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "magnav/core/dipole.h"
#include "magnav/core/frames.h"
#include "magnav/inversion/analytic.h"
#include "magnav/inversion/inverter.h"
#include "magnav/inversion/particle_filter.h"

namespace magnav::inversion {
namespace {

const Vec3 kMomentBody(2000.0, 300.0, 800.0);  // A·m² (the reference AUV)

// 1024 random fluxgate-level samples at 3–15 m range.
const std::vector<GradiometerSample>& Samples() {
  static const std::vector<GradiometerSample> samples = [] {
    std::mt19937_64 rng(1);
    std::normal_distribution<double> n01;
    std::uniform_real_distribution<double> range(3.0, 15.0);
    std::vector<GradiometerSample> out;
    for (int k = 0; k < 1024; ++k) {
      GradiometerSample s;
      const Vec3 dir = Vec3(n01(rng), n01(rng), n01(rng)).normalized();
      const Vec3 m = WorldMoment(kMomentBody, 6.28 * k / 1024.0);
      DipoleBT(range(rng) * dir, m, &s.B, &s.T);
      for (int i = 0; i < 3; ++i) s.B[i] += 1e-9 * n01(rng);
      for (int i = 0; i < 3; ++i) {
        for (int j = i; j < 3; ++j) {
          const double e = 1.4e-9 * n01(rng);
          s.T(i, j) += e;
          if (i != j) s.T(j, i) += e;
        }
      }
      s.T(2, 2) = -s.T(0, 0) - s.T(1, 1);
      s.sigma_B = 1e-9;
      s.sigma_T = 1.4e-9;
      s.t_s = 0.1 * k;
      out.push_back(s);
    }
    return out;
  }();
  return samples;
}

void BM_SolveTed(benchmark::State& state) {
  const auto& samples = Samples();
  std::size_t k = 0;
  AnalyticSolution sol;
  for (auto _ : state) {
    const auto& s = samples[k++ & 1023];
    benchmark::DoNotOptimize(SolveTed(s.T, s.B, {}, &sol));
    benchmark::DoNotOptimize(sol);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SolveTed);

void BM_SolveTedEgt(benchmark::State& state) {
  const auto& samples = Samples();
  std::size_t k = 0;
  AnalyticSolution sol;
  for (auto _ : state) {
    const auto& s = samples[k++ & 1023];
    benchmark::DoNotOptimize(SolveTedEgt(s.T, s.B, 0.5, {}, &sol));
    benchmark::DoNotOptimize(sol);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SolveTedEgt);

void BM_SolveEgt(benchmark::State& state) {
  const auto& samples = Samples();
  std::size_t k = 0;
  AnalyticSolution sol;
  for (auto _ : state) {
    const auto& s = samples[k++ & 1023];
    benchmark::DoNotOptimize(SolveEgt(s.T, s.B, {}, &sol));
    benchmark::DoNotOptimize(sol);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SolveEgt);

// Everything a service does per sample: gates, TED+EGT, σ, moment fit,
// speed gate (each sample from another geometry, so the speed gate mostly
// rejects — it is evaluated all the same).
void BM_InverterProcess(benchmark::State& state) {
  const auto& samples = Samples();
  InverterOptions options;
  options.estimate_moment = state.range(0) != 0;
  Inverter inverter(options);
  std::size_t k = 0, solved = 0;
  double t = 0.0;
  for (auto _ : state) {
    GradiometerSample s = samples[k++ & 1023];
    s.t_s = (t += 0.1);
    const DipoleFix fix = inverter.Process(s);
    solved += std::isfinite(fix.cond);  // got past the input and signal gates
    benchmark::DoNotOptimize(fix);
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["solved_fraction"] = static_cast<double>(solved) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_InverterProcess)->Arg(0)->Arg(1)->ArgName("moment");

// One filter step at 10 Hz on a dipole passing the sensor at 1 m/s.
void BM_McStep(benchmark::State& state) {
  ParticleFilterOptions options;
  options.moment_body_Am2 = kMomentBody;
  options.num_particles = static_cast<int>(state.range(0));
  DipoleParticleFilter filter(options);
  const double heading = 0.7;
  const Vec3 v(std::cos(heading), std::sin(heading), 0.0);
  const Vec3 p0(-5.0, -4.0, -5.0);
  filter.InitializeAround(p0, 0.5, Eigen::Vector2d(v.x(), v.y()), 0.3, 0.0);
  const Vec3 m_W = WorldMoment(kMomentBody, heading);
  GradiometerSample s;
  s.sigma_T = 1.4e-9;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  double t = 0.0;
  for (auto _ : state) {
    t += 0.1;
    const Vec3 p = p0 + std::fmod(t, 10.0) * v;  // stays within ~10 m of the sensor
    s.t_s = t;
    s.T = DipoleT(-p, m_W);
    s.T(0, 1) += 1.4e-9 * n01(rng);
    benchmark::DoNotOptimize(filter.Step(s));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_McStep)->Arg(600)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace magnav::inversion

BENCHMARK_MAIN();
