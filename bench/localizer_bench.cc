// Localizer benchmarks: one EKF step (prediction + one magnetometer update)
// for M = 8, 100, 1000 sensors (the step is O(M²): the update touches every
// covariance entry), the batch solve and the bounds on the reference pass
// (tests/data/reference/localize_*.csv). Results: docs/BENCHMARKS.md.
#include <benchmark/benchmark.h>

#include <cmath>

#include "magnav/localizer/batch.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/ekf.h"
#include "magnav/localizer/input.h"

namespace magnav::localizer {
namespace {

const std::string kRef = MAGNAV_REFERENCE_DIR;

const PassFile& Reference() {
  static const PassFile f = ReadPassFiles(kRef + "/localize_measurements.csv", kRef + "/localize_deployment.csv",
                                          kRef + "/localize_gnss_full.csv", std::nullopt);
  return f;
}

// One step = predict 0.2 s + update with one sensor's sample, M sensors on a
// 10 m grid at 30 m depth; the sensor measured cycles through all M.
void BM_EkfStep(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  std::vector<SensorPrior> sensors;
  const int side = static_cast<int>(std::ceil(std::sqrt(m)));
  for (int j = 0; j < m; ++j) {
    sensors.push_back({static_cast<std::uint32_t>(j), {10.0 * (j % side), 10.0 * (j / side), 30.0}, 15.0});
  }
  const Vessel vessel{{30000.0, 2000.0, 10000.0}, 0.0};
  VesselVector x0;
  x0 << -50.0, -50.0, 2.0, 0.5, 0.0;
  LocalizerEkf ekf(vessel, sensors, 0.0, x0, VesselCovariance::Identity(), LocalizerOptions{});
  double t = 0.0;
  int j = 0;
  for (auto _ : state) {
    t += 0.2;
    MagSample s{t, static_cast<std::uint32_t>(j), Eigen::Vector3d(1e-9, -2e-9, 3e-9)};
    benchmark::DoNotOptimize(ekf.Update(s));
    j = (j + 1) % m;
  }
  state.counters["sensors"] = m;
}
BENCHMARK(BM_EkfStep)->Arg(8)->Arg(100)->Arg(1000)->Unit(benchmark::kMicrosecond);

// The whole reference pass through the EKF (5554 epochs × 8 samples, 1111 fixes; bound included).
void BM_EkfReferencePass(benchmark::State& state) {
  const Pass& pass = Reference().pass;
  for (auto _ : state) benchmark::DoNotOptimize(RunEkf(pass, LocalizerOptions{}));
}
BENCHMARK(BM_EkfReferencePass)->Unit(benchmark::kMillisecond);

// Batch solve of the reference pass from the EKF's estimate (solve + covariance + bound).
void BM_BatchReferencePass(benchmark::State& state) {
  const Pass& pass = Reference().pass;
  const Localization start = RunEkf(pass, LocalizerOptions{});
  for (auto _ : state) benchmark::DoNotOptimize(SolveBatch(pass, LocalizerOptions{}, &start));
}
BENCHMARK(BM_BatchReferencePass)->Unit(benchmark::kMillisecond);

// The joint and known-trajectory bounds on the reference pass at the EKF's estimate.
void BM_CrlbReferencePass(benchmark::State& state) {
  const Pass& pass = Reference().pass;
  const Localization est = RunEkf(pass, LocalizerOptions{});
  std::vector<Eigen::Vector2d> s;
  for (const auto& e : est.sensors) s.push_back(e.p_SinW_m.head<2>());
  for (auto _ : state) benchmark::DoNotOptimize(ComputeCrlb(pass, LocalizerOptions{}, est.trajectory, s));
}
BENCHMARK(BM_CrlbReferencePass)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace magnav::localizer

BENCHMARK_MAIN();
