// Localizer benchmarks: one EKF step (prediction + one magnetometer update)
// for M = 8, 100, 1000 sensors (the step is O(M²): the update touches every
// covariance entry), the batch solve and the bounds on the reference pass
// (tests/data/reference/localize_*.csv). Results: docs/BENCHMARKS.md.
#include <benchmark/benchmark.h>

#include <time.h>

#include <cmath>

#include "magnav/localizer/batch.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/ekf.h"
#include "magnav/localizer/input.h"
#include "magnav/localizer/stream.h"
#include "racetrack.h"  // tests/localizer: the 6-sensor racetrack survey

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

// The streaming localizer at an age: a stream fed `age` s of the racetrack
// survey (tests/localizer/racetrack.h: 6 sensors at 2 Hz + GNSS at 1 Hz = 13
// items/s), then timed on the next `chunk` s of data with a publish
// (Estimates(true), what magnav-localizer's Publish computes) every 5 s of
// data, as the service at a 5 s period under a 1x replay. Counters (this
// thread's CPU time): us_item = CPU per item (the EKF update plus, bounded, the bound's recursion),
// ms_publish = per publish, retained = items kept (StreamingLocalizer::
// retained_items), state_MB = those items at sizeof(MagSample) (40 B) each plus, bounded, the
// (5 + 2M)² information: the memory that grows with uptime, or not.
// Args: {age s, bounded 0/1}. Bounded: a 500 s chunk; unbounded: 25 s (its
// publish costs about a second at 16000 s).
void BM_StreamAtAge(benchmark::State& state) {
  const double age_s = static_cast<double>(state.range(0));
  const bool bounded = state.range(1) != 0;
  const double chunk_s = bounded ? 500.0 : 25.0, publish_every_s = 5.0;
  static const test::Racetrack d = test::SimulateRacetrack(16000.0 + 510.0);
  StreamOptions so;
  so.reorder_delay_s = 0.0;
  so.bounded = bounded;
  StreamingLocalizer s(d.pass.vessel, d.pass.sensors, LocalizerOptions{}, so);
  std::size_t i = 0, g = 0;
  const auto feed_until = [&](double t_end) {
    for (; i < d.pass.samples.size() && d.pass.samples[i].t_s <= t_end; ++i) {
      while (g < d.pass.gnss.size() && d.pass.gnss[g].t_s <= d.pass.samples[i].t_s) s.Add(d.pass.gnss[g++]);
      s.Add(d.pass.samples[i]);
    }
  };
  feed_until(age_s);
  const auto cpu_s = [] {  // this thread's CPU time: the machine is shared
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  };
  double item_s = 0.0, publish_s = 0.0;
  std::size_t items = 0, publishes = 0;
  double t = age_s;
  for (auto _ : state) {
    for (double end = t + chunk_s; t < end; t += publish_every_s) {
      const std::size_t before = i + g;
      const double t0 = cpu_s();
      feed_until(t + publish_every_s);
      const double t1 = cpu_s();
      benchmark::DoNotOptimize(s.Estimates(/*bounds=*/true));
      const double t2 = cpu_s();
      item_s += t1 - t0;
      publish_s += t2 - t1;
      items += i + g - before;
      ++publishes;
    }
  }
  const double m = static_cast<double>(d.pass.sensors.size());
  state.counters["us_item"] = 1e6 * item_s / static_cast<double>(items);
  state.counters["ms_publish"] = 1e3 * publish_s / static_cast<double>(publishes);
  state.counters["retained"] = static_cast<double>(s.retained_items());
  state.counters["state_MB"] =
      (static_cast<double>(sizeof(MagSample) * s.retained_items()) + (bounded ? 8.0 * (5 + 2 * m) * (5 + 2 * m) : 0.0)) / 1e6;
}
BENCHMARK(BM_StreamAtAge)
    ->ArgsProduct({{500, 8000, 16000}, {1, 0}})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace magnav::localizer

BENCHMARK_MAIN();
