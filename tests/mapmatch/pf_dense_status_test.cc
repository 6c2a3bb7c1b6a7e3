// The AFPF's status on dense readings (issue 25 item 3) (MatchParticleFilter): a run whose
// likelihood σ sat at its cap (afpf_max_sigma_nT) in at least half of its
// last 40 updates is "not converged" — the innovations exceed the largest
// noise the filter allows, which its NIS rules, dividing by that σ, do not
// see (the wrong-place AFPF runs of docs/ACCURACY.md, "Dense readings II",
// said "converged" with σ at 20 nT against a 3 nT sensor). Checked on a
// path read every 2 m generated here: with 12 nT noise (σ = 3 × ≈ 12 nT,
// capped) "not converged" and the reason names the cap; the same path
// with 3 nT noise "converged". Before, both said "converged".
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "crustal_path_run.h"
#include "magnav/mapmatch/fix_schedule.h"
#include "magnav/mapmatch/particle_filter.h"

namespace magnav::mapmatch {
namespace {

using testing_paths::CrustalMap;

// A path read every 2 m from near the crustal map's centre, INS = truth + 0.0098° / 0.0019° (the
// reference 0.01° offset), readings = the map's value + N(0, noise²).
MatchPath DensePath(double noise_nT, int steps) {
  const GeoGrid& g = CrustalMap();
  const std::size_t layer = g.layer("anomaly_nT");
  std::mt19937_64 rng(2612);
  std::normal_distribution<double> unit(0.0, 1.0);
  MatchPath p;
  double lat = 45.02, lon = 10.0, heading = 0.4;
  for (int k = 0; k < steps; ++k) {
    if (k > 0) {
      heading += 0.02 * unit(rng);
      lat += 2.0 * std::cos(heading) / MetresPerDegreeLat(lat);
      lon += 2.0 * std::sin(heading) / MetresPerDegreeLon(lat);
    }
    const auto v = g.Sample(layer, lat, lon);
    if (!v) ADD_FAILURE() << "the generated path leaves the map at step " << k;
    p.k.push_back(k);
    p.lat_deg.push_back(lat - 0.0098);
    p.lon_deg.push_back(lon + 0.0019);
    p.measured_nT.push_back((v ? v->value_nT : 0.0) + noise_nT * unit(rng));
  }
  return p;
}

TEST(DenseReadings, AfpfWithItsSigmaAtTheCapIsNotConvergedOnDenseReadings) {
  const GeoGrid& g = CrustalMap();
  const ParticleFilterOptions o;
  const MatchResult noisy = MatchParticleFilter(ParticleFilterKind::kAfpf, g, g.layer("anomaly_nT"),
                                                DensePath(12.0, 1200), o);
  EXPECT_FALSE(noisy.converged);
  EXPECT_NE(noisy.reason.find("cap"), std::string::npos) << noisy.reason;
  const MatchResult quiet = MatchParticleFilter(ParticleFilterKind::kAfpf, g, g.layer("anomaly_nT"),
                                                DensePath(3.0, 1200), o);
  EXPECT_TRUE(quiet.converged) << quiet.reason;
}

}  // namespace
}  // namespace magnav::mapmatch
