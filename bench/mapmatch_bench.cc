// Map-matching benchmarks: one bilinear map evaluation (the unit the others
// are compared with in the same run), fast MSD on a 200-point path and its
// covariance step alone on 200 to 20 000 points, ICP on a
// 1-million-cell map, the coarse MSD search over ±0.15° on the crustal map,
// a single-point query, and the particle filters (a PF step with 3000
// particles, an AFPF step at its adaptive count, the AFPF's first step, whole
// paths). Results: docs/BENCHMARKS.md.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "fast_msd_covariance.h"
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

// The same without the map's interpolation error bound in the covariance
// (FastMsdOptions::map_error_in_covariance off): the cost of that term, in the same run.
void BM_FastMsd200NoMapError(benchmark::State& state) {
  const MatchPath p = SyntheticCrustalPath(200);
  FastMsdOptions o;
  o.map_error_in_covariance = false;
  for (auto _ : state) {
    const MatchResult r = MatchFastMsd(Crustal(), 0, p, o);
    benchmark::DoNotOptimize(r.lat_deg.data());
  }
}
BENCHMARK(BM_FastMsd200NoMapError)->Unit(benchmark::kMicrosecond);

// The same without the other basins in the covariance (FastMsdOptions::basin_half_width_deg 0: the
// linearised basin only, as before 2026-11-26 12:00): the cost of the basins' forward-backward, in the same run.
void BM_FastMsd200NoBasins(benchmark::State& state) {
  const MatchPath p = SyntheticCrustalPath(200);
  FastMsdOptions o;
  o.basin_half_width_deg = 0.0;
  for (auto _ : state) {
    const MatchResult r = MatchFastMsd(Crustal(), 0, p, o);
    benchmark::DoNotOptimize(r.lat_deg.data());
  }
}
BENCHMARK(BM_FastMsd200NoBasins)->Unit(benchmark::kMicrosecond);

// BM_FastMsd200's path with N(0, σ²) reading noise (σ = range(0) / 10 nT, seed 1): the basins'
// posterior spreads wider with the noise than on the noise-free path, so their cost grows; with and
// without them (range(1) = 1 / 0).
void BM_FastMsd200Noisy(benchmark::State& state) {
  MatchPath p = SyntheticCrustalPath(200);
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, static_cast<double>(state.range(0)) / 10.0);
  for (double& m : p.measured_nT) m += noise(rng);
  FastMsdOptions o;
  if (state.range(1) == 0) o.basin_half_width_deg = 0.0;
  for (auto _ : state) {
    const MatchResult r = MatchFastMsd(Crustal(), 0, p, o);
    benchmark::DoNotOptimize(r.lat_deg.data());
  }
}
BENCHMARK(BM_FastMsd200Noisy)->ArgsProduct({{5, 30}, {1, 0}})->Unit(benchmark::kMicrosecond);

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

// Fast MSD's covariance step alone (mapmatch/src/fast_msd_covariance.h), as MatchFastMsd runs it after
// the rounds: the EM for σ², τ² (at most 100 iterations, O(N) each) and the smoother's error covariance
// with its 6 curvature passes (O(N) each). Input: an n-point linearisation with the crustal map's
// gradients along BM_FastMsd200's path (repeated past 200 points), 0.5 nT residuals, corrections a random
// walk of 3e-4° per point, every 10th point without data, the map's Hessian zero (the cost does not
// depend on it). Time per point constant in n = O(N).
void BM_FastMsdErrorCovariance(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  static const MatchPath p = SyntheticCrustalPath(200);
  std::vector<double> gl(n), gn(n), r(n), el(n), en(n), zero(n, 0.0);
  std::vector<char> data(n, 1);
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.5), step(0.0, 3e-4);
  for (std::size_t i = 0; i < n; ++i) {
    const auto s = Crustal().Sample(0, p.lat_deg[i % 200], p.lon_deg[i % 200]);
    gl[i] = s->dvalue_dlat_nT_per_deg;
    gn[i] = s->dvalue_dlon_nT_per_deg;
    r[i] = noise(rng);
    el[i] = (i > 0 ? el[i - 1] : 0.0) + step(rng);
    en[i] = (i > 0 ? en[i - 1] : 0.0) + step(rng);
    data[i] = i % 10 == 9 ? 0 : 1;
  }
  for (auto _ : state) {
    const internal::ErrorCovariance c =
        internal::FastMsdErrorCovariance(gl, gn, r, data, el, en, zero, zero, zero, 1e7);
    benchmark::DoNotOptimize(c.lat_lat.data());
  }
  state.counters["points"] =
      benchmark::Counter(static_cast<double>(n), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_FastMsdErrorCovariance)->Arg(200)->Arg(2000)->Arg(20000)->Unit(benchmark::kMicrosecond);

// One curvature pass of it: the diagonal blocks of the sandwich M⁻¹ A M⁻¹ (SandwichDiagonalBlocks,
// the part that was O(N²) before 2026-11-26 06:00) for the smoother's M and A on the same gradients
// (λ = 1e7, σ² = 0.25 nT², τ² = 8e-8 deg²).
void BM_FastMsdSandwich(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  static const MatchPath p = SyntheticCrustalPath(200);
  const double h = 0.5e7, kt2 = h * h * 8e-8;
  internal::BlockTridiagonal m, a;
  for (std::size_t i = 0; i < n; ++i) {
    const auto s = Crustal().Sample(0, p.lat_deg[i % 200], p.lon_deg[i % 200]);
    const Eigen::Vector2d g(s->dvalue_dlat_nT_per_deg, s->dvalue_dlon_nT_per_deg);
    const double d = (i == 0 || i + 1 == n) ? 1.0 : 2.0, w = (i == 0 || i + 1 == n) ? 0.5 : 1.0;
    m.diag.push_back(h * d * Eigen::Matrix2d::Identity() + w * g * g.transpose());
    a.diag.push_back(kt2 * d * Eigen::Matrix2d::Identity() + w * w * 0.25 * g * g.transpose());
    if (i + 1 < n) {
      m.upper.push_back(-h * Eigen::Matrix2d::Identity());
      a.upper.push_back(-kt2 * Eigen::Matrix2d::Identity());
    }
  }
  for (auto _ : state) {
    const std::vector<Eigen::Matrix2d> x = internal::SandwichDiagonalBlocks(m, a);
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["points"] =
      benchmark::Counter(static_cast<double>(n), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_FastMsdSandwich)->Arg(200)->Arg(20000)->Unit(benchmark::kMicrosecond);

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

// One filter step (predict, weigh, resample or fission, estimate, diversity)
// in steady state: the filter first runs the reference path's first 75 points
// (converged), then the timed steps cycle over points 75..149 (the wrap is one
// INS jump per 75 steps). PF: 3000 particles (Arg); AFPF: at its adaptive
// count (3000 once converged, the `particles` counter). TimeSteps is that
// timed part, shared by the filter benchmarks below.
void TimeSteps(benchmark::State& state, ParticleFilterKind kind, const ParticleFilterOptions& o) {
  const MatchPath& p = CrustalPath();
  auto f = MakeParticleFilter(kind, Crustal(), 0, o);
  std::size_t k = 0;
  for (; k < 75; ++k) f->Step(p.lat_deg[k], p.lon_deg[k], p.measured_nT[k]);
  double particles = 0.0, steps = 0.0;
  for (auto _ : state) {
    const StepDiagnostics& d = f->Step(p.lat_deg[k], p.lon_deg[k], p.measured_nT[k]);
    particles += d.particles;
    steps += 1.0;
    if (++k == p.size()) k = 75;
  }
  state.counters["particles"] = particles / steps;
}
void FilterStep(benchmark::State& state, ParticleFilterKind kind) {
  ParticleFilterOptions o;
  o.num_particles = static_cast<int>(state.range(0));
  o.max_particles = std::max(o.max_particles, o.num_particles);
  TimeSteps(state, kind, o);
}
void BM_PfStep(benchmark::State& state) { FilterStep(state, ParticleFilterKind::kPf); }
BENCHMARK(BM_PfStep)->Arg(3000)->Unit(benchmark::kMicrosecond);
void BM_AfpfStep(benchmark::State& state) { FilterStep(state, ParticleFilterKind::kAfpf); }
BENCHMARK(BM_AfpfStep)->Arg(3000)->Unit(benchmark::kMicrosecond);

// The same step with K independent sub-clouds (ParticleFilterOptions::subclouds, each 3000 particles,
// re-seeding on): Arg = K; K = 1 is BM_PfStep's filter. The cost ratio to BM_PfStep is K by design.
void SubCloudStep(benchmark::State& state, ParticleFilterKind kind) {
  ParticleFilterOptions o;
  o.subclouds = static_cast<int>(state.range(0));
  o.subcloud_reseed_nats = 10.0;
  TimeSteps(state, kind, o);
}
void BM_PfStepSubClouds(benchmark::State& state) { SubCloudStep(state, ParticleFilterKind::kPf); }
BENCHMARK(BM_PfStepSubClouds)->Arg(1)->Arg(3)->Unit(benchmark::kMicrosecond);
void BM_AfpfStepSubClouds(benchmark::State& state) { SubCloudStep(state, ParticleFilterKind::kAfpf); }
BENCHMARK(BM_AfpfStepSubClouds)->Arg(1)->Arg(3)->Unit(benchmark::kMicrosecond);

// The AFPF's first step at the default cap (30000 particles over the ±0.15°
// prior, fission of all of them): the most expensive step of a run.
void BM_AfpfFirstStep(benchmark::State& state) {
  const MatchPath& p = CrustalPath();
  double particles = 0.0;
  for (auto _ : state) {
    auto f = MakeParticleFilter(ParticleFilterKind::kAfpf, Crustal(), 0, ParticleFilterOptions{});
    particles = f->Step(p.lat_deg[0], p.lon_deg[0], p.measured_nT[0]).particles;
  }
  state.counters["particles_after"] = particles;
}
BENCHMARK(BM_AfpfFirstStep)->Unit(benchmark::kMillisecond);

// A whole 150-point reference path, default settings.
void BM_PfPath150(benchmark::State& state) {
  for (auto _ : state) {
    const MatchResult r = MatchParticleFilter(ParticleFilterKind::kPf, Crustal(), 0, CrustalPath(), {});
    benchmark::DoNotOptimize(r.lat_deg.data());
  }
}
BENCHMARK(BM_PfPath150)->Unit(benchmark::kMillisecond);
void BM_AfpfPath150(benchmark::State& state) {
  for (auto _ : state) {
    const MatchResult r = MatchParticleFilter(ParticleFilterKind::kAfpf, Crustal(), 0, CrustalPath(), {});
    benchmark::DoNotOptimize(r.lat_deg.data());
  }
}
BENCHMARK(BM_AfpfPath150)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace magnav::mapmatch

BENCHMARK_MAIN();
