// Map-matching benchmarks: one bilinear map evaluation (the unit the others
// are compared with in the same run), fast MSD on a 200-point path, ICP on a
// 1-million-cell map, the coarse MSD search over ±0.15° on the crustal map,
// and a single-point query. Results: docs/BENCHMARKS.md.
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>

#include "magnav/mapmatch/match.h"

namespace magnav::mapmatch {
namespace {

const std::string kRef = MAGNAV_REFERENCE_DIR;

const GeoGrid& Crustal() {
  static const GeoGrid g = ReadGeoGridCsv(kRef + "/map_crustal_anomaly.csv", {"anomaly_nT"});
  return g;
}

const MatchPath& CrustalPath() {
  static const MatchPath p = ReadMatchPath(kRef + "/mappath_crustal_off0p01deg_noise0p5nT.csv", "meas_nT");
  return p;
}

// A gently turning path of n points from (lat, lon) with the given step (deg),
// measured on the map at the truth; the INS offset by (dlat, dlon).
MatchPath TurningPath(const GeoGrid& g, int n, double lat, double lon, double step, double turn, double dlat,
                      double dlon) {
  MatchPath p;
  double h = 0.4;
  for (int k = 0; k < n; ++k) {
    p.k.push_back(k);
    p.lat_deg.push_back(lat + dlat);
    p.lon_deg.push_back(lon + dlon);
    p.measured_nT.push_back(g.Sample(0, lat, lon)->value_nT);
    h += turn * std::sin(0.05 * k);
    lat += step * std::cos(h);
    lon += step * std::sin(h);
  }
  return p;
}

// 200 points on the crustal map (~90 m steps), INS off by (0.004°, -0.003°).
MatchPath SyntheticCrustalPath(int n) { return TurningPath(Crustal(), n, 44.94, 9.92, 0.0008, 0.02, 0.004, -0.003); }

void BM_BilinearSample(benchmark::State& state) {
  const GeoGrid& g = Crustal();
  double lat = 44.95, lon = 9.95, sum = 0.0;
  for (auto _ : state) {
    sum += g.Sample(0, lat, lon)->value_nT;
    lat += 1e-7;
    lon += 1.3e-7;
    if (lat > 45.05) lat = 44.95, lon = 9.95;
  }
  benchmark::DoNotOptimize(sum);
}
BENCHMARK(BM_BilinearSample);

// Defaults: each round solved directly (block-tridiagonal elimination).
void BM_FastMsd200(benchmark::State& state) {
  const MatchPath p = SyntheticCrustalPath(200);
  for (auto _ : state) {
    const MatchResult r = MatchFastMsd(Crustal(), 0, p);
    benchmark::DoNotOptimize(r.lat_deg.data());
  }
}
BENCHMARK(BM_FastMsd200)->Unit(benchmark::kMicrosecond);

// The same with the paper's Jacobi sweeps (the same fixed point).
void BM_FastMsd200Jacobi(benchmark::State& state) {
  const MatchPath p = SyntheticCrustalPath(200);
  FastMsdOptions o;
  o.solver = FastMsdSolver::kJacobi;
  int iterations = 0;
  for (auto _ : state) {
    const MatchResult r = MatchFastMsd(Crustal(), 0, p, o);
    iterations = r.iterations;
    benchmark::DoNotOptimize(r.lat_deg.data());
  }
  state.counters["jacobi_iterations"] = iterations;
}
BENCHMARK(BM_FastMsd200Jacobi)->Unit(benchmark::kMillisecond);

void BM_IcpMillionCells(benchmark::State& state) {
  // 1000 x 1000 nodes, 0.01° spacing, a smooth main-field-like layer.
  static const GeoGrid g = GeoGrid::FromFunction({10.0, 0.01, 1000}, {60.0, 0.01, 1000}, "F", [](double lat, double lon) {
    return 40000.0 + 450.0 * (lat - 10.0) - 60.0 * (lon - 60.0) + 40.0 * std::sin(0.9 * lat) * std::cos(1.1 * lon);
  });
  const MatchPath p = TurningPath(g, 60, 13.0, 63.0, 0.05, 0.05, 0.05, -0.04);
  int iterations = 0;
  for (auto _ : state) {
    const MatchResult r = MatchIcp(g, 0, p);
    iterations = r.iterations;
    benchmark::DoNotOptimize(r.lat_deg.data());
  }
  state.counters["icp_iterations"] = iterations;
}
BENCHMARK(BM_IcpMillionCells)->Unit(benchmark::kMillisecond);

void BM_CoarseSearch015(benchmark::State& state) {
  CorrelationOptions o;
  o.metric = CorrelationMetric::kMsd;
  o.search_window_deg = 0.15;
  for (auto _ : state) {
    const MatchResult r = MatchCorrelation(Crustal(), 0, CrustalPath(), o);
    benchmark::DoNotOptimize(r.score);
  }
  state.counters["shifts"] = 301 * 301;
}
BENCHMARK(BM_CoarseSearch015)->Unit(benchmark::kMillisecond);

void BM_PointQuery(benchmark::State& state) {
  static const PointIndex index(Crustal(), {0});
  double m = -150.0;
  std::size_t hits = 0, queries = 0;
  for (auto _ : state) {
    hits += index.Find({m}, 0.5).size();
    ++queries;
    m += 0.37;
    if (m > 250.0) m = -150.0;
  }
  state.counters["hits_per_query"] = static_cast<double>(hits) / static_cast<double>(queries);
}
BENCHMARK(BM_PointQuery)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace magnav::mapmatch

BENCHMARK_MAIN();
