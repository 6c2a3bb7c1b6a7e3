// Forward model throughput: dipole tensor (and B) evaluations per second on one
// core. Target (issue 2): >= 20 million tensor evaluations per second.
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "magnav/core/dipole.h"

namespace {

struct Inputs {
  std::vector<magnav::Vec3> r, m;
  explicit Inputs(std::size_t n) {
    std::mt19937 rng(1);
    std::normal_distribution<double> g;
    for (std::size_t i = 0; i < n; ++i) {
      r.emplace_back(10 * g(rng), 10 * g(rng), 3 + std::abs(g(rng)));
      m.emplace_back(1e3 * g(rng), 1e3 * g(rng), 1e3 * g(rng));
    }
  }
};

void BM_DipoleTensor(benchmark::State& state) {
  const Inputs in(1024);
  std::size_t i = 0;
  for (auto _ : state) {
    magnav::Mat3 T = magnav::DipoleT(in.r[i], in.m[i]);
    benchmark::DoNotOptimize(T);
    i = (i + 1) & 1023;
  }
  state.counters["evals_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DipoleTensor);

void BM_DipoleFieldAndTensor(benchmark::State& state) {
  const Inputs in(1024);
  std::size_t i = 0;
  for (auto _ : state) {
    magnav::Vec3 B;
    magnav::Mat3 T;
    magnav::DipoleBT(in.r[i], in.m[i], &B, &T);
    benchmark::DoNotOptimize(B);
    benchmark::DoNotOptimize(T);
    i = (i + 1) & 1023;
  }
  state.counters["evals_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DipoleFieldAndTensor);

void BM_MeasurementWithJacobians(benchmark::State& state) {
  const Inputs in(1024);
  std::size_t i = 0;
  for (auto _ : state) {
    magnav::Jacobian8x3 Jr, Jm;
    magnav::Measurement8 z = magnav::DipoleMeasurement(in.r[i], in.m[i], &Jr, &Jm);
    benchmark::DoNotOptimize(z);
    benchmark::DoNotOptimize(Jr);
    benchmark::DoNotOptimize(Jm);
    i = (i + 1) & 1023;
  }
  state.counters["evals_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_MeasurementWithJacobians);

}  // namespace

BENCHMARK_MAIN();
