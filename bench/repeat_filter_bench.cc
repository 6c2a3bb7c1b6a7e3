// The repeat filter's cost per message on a service's hot path
// (dds/repeat_filter.h): RepeatFilter::First(message, SampleInfo) as the
// services call it for every message they take — the writer's GUID hashed,
// the whole message serialised to CDR and hashed (PayloadHash), then the
// (key, seq, stamp) map — beside the parts alone and the plain conversion of
// the same message (dds::FromMsg, the unit of the same-run ratio).
// Every message offered is a first one (new seq and stamp): the common case;
// the filter is in its steady state (each key's 2048 remembered messages full,
// the oldest evicted per message). Results: docs/BENCHMARKS.md.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "magnav/dds/convert.h"
#include "magnav/dds/repeat_filter.h"

namespace magnav::dds {
namespace {

constexpr std::uint32_t kSensors = 4;  // the 4-sensor AUV pass of the service benchmarks

msg::GradiometerSample Gradiometer(std::uint64_t i) {
  msg::GradiometerSample m;
  m.sensor_id(static_cast<std::uint32_t>(i % kSensors));
  m.stamp_ns(1'000'000'000ull + i * 10'000'000ull);
  m.seq(i / kSensors);
  const double x = static_cast<double>(i);
  m.sensor_position({x * 0.25, -x / 3.0, 5.0});
  m.B({2e-5 + 1e-12 * x, std::sin(x) * 1e-9, 4.5e-5});
  std::array<double, 9> T;
  for (int k = 0; k < 9; ++k) T[static_cast<std::size_t>(k)] = std::ldexp(std::sin(x + k), -30);
  m.T(T);
  m.sigma_B(1e-9);
  m.sigma_T(1.4e-9);
  return m;
}

msg::MagnetometerSample Magnetometer(std::uint64_t i) {
  return AnomalySampleMsg(static_cast<std::uint32_t>(i % kSensors), 1'000'000'000ull + i * 10'000'000ull,
                          i / kSensors, std::sin(static_cast<double>(i)), 48000.0);
}

// Messages made before timing (their construction is not the filter's cost).
template <class M>
const std::vector<M>& Messages(M (*make)(std::uint64_t)) {
  static const std::vector<M> v = [make] {
    std::vector<M> out;
    for (std::uint64_t i = 0; i < 4096; ++i) out.push_back(make(i));
    return out;
  }();
  return v;
}

// The plain conversion of the message (the unit).
void BM_ConvertGradiometer(benchmark::State& state) {
  const auto& msgs = Messages(&Gradiometer);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(FromMsg(msgs[i++ & 4095]));
  }
}
BENCHMARK(BM_ConvertGradiometer);

void BM_ConvertMagnetometer(benchmark::State& state) {
  const auto& msgs = Messages(&Magnetometer);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(RecordOf(msgs[i++ & 4095]));
  }
}
BENCHMARK(BM_ConvertMagnetometer);

// The payload hash alone (CDR serialisation + hash).
void BM_PayloadHashGradiometer(benchmark::State& state) {
  const auto& msgs = Messages(&Gradiometer);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(PayloadHash(msgs[i++ & 4095]));
  }
}
BENCHMARK(BM_PayloadHashGradiometer);

void BM_PayloadHashMagnetometer(benchmark::State& state) {
  const auto& msgs = Messages(&Magnetometer);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(PayloadHash(msgs[i++ & 4095]));
  }
}
BENCHMARK(BM_PayloadHashMagnetometer);

// The filter as the services call it: First(message, SampleInfo). Seq and
// stamp advance past the pattern's each lap, so every message is first.
template <class M>
void FilterHotPath(benchmark::State& state, M (*make)(std::uint64_t), bool with_payload_hash) {
  const auto& msgs = Messages(make);
  RepeatFilter filter;
  const eprosima::fastdds::dds::SampleInfo info{};
  std::uint64_t i = 0;
  for (auto _ : state) {
    const M& m = msgs[i & 4095];
    MessageId id = IdOf(m);
    const std::uint64_t lap = i >> 12;
    id.seq += lap * (4096 / kSensors);
    id.stamp_ns += lap * 4096 * 10'000'000ull;
    const MessageOrigin origin{WriterHash(info), with_payload_hash ? PayloadHash(m) : 0};
    benchmark::DoNotOptimize(filter.First(id, origin));
    ++i;
  }
  if (filter.repeats() + filter.conflicts() != 0) state.SkipWithError("a message was not first");
}

void BM_RepeatFilterGradiometer(benchmark::State& state) { FilterHotPath(state, &Gradiometer, true); }
BENCHMARK(BM_RepeatFilterGradiometer);
void BM_RepeatFilterGradiometerWithoutPayloadHash(benchmark::State& state) {
  FilterHotPath(state, &Gradiometer, false);
}
BENCHMARK(BM_RepeatFilterGradiometerWithoutPayloadHash);
void BM_RepeatFilterMagnetometer(benchmark::State& state) { FilterHotPath(state, &Magnetometer, true); }
BENCHMARK(BM_RepeatFilterMagnetometer);
void BM_RepeatFilterMagnetometerWithoutPayloadHash(benchmark::State& state) {
  FilterHotPath(state, &Magnetometer, false);
}
BENCHMARK(BM_RepeatFilterMagnetometerWithoutPayloadHash);

}  // namespace
}  // namespace magnav::dds

BENCHMARK_MAIN();
