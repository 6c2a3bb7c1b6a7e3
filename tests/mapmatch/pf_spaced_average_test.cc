// Readings left out by the update spacing averaged, not dropped — an option,
// off by default (ParticleFilterOptions::average_spaced_readings; issue 25;
// docs/ACCURACY.md, "Dense readings II": measured no better than dropping on
// the dense tuning paths). A filter fed a reading every few metres uses one
// in ~12 (min_update_spacing_m, 25 m) and drops the others. With the option
// each particle keeps the residuals z_j − m(x_i,j) of
// the readings spaced out since the last update, the map taken where that
// particle was at each of them, and the update weighs it by their mean with
// its own. Checked on one particle (no randomness that matters: drift
// 1e-12°), against the residuals worked out from the map: the update weighs
// the particle by their mean (its NIS r̄²/σ²; before, by the last reading's
// residual alone), its innovation stays the reading's own, and
// a spaced reading the cloud's prediction does not explain (+1000 nT) is
// left out of the mean and counted as an outlier.
//
// The AFPF's status on dense readings (MatchParticleFilter): a run whose
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

// One particle, INS steps of 2 m north; the reading at step k is the map's value where the particle
// will be plus offset[k] (offset[0] at the first step, an update; then spaced readings until the INS
// has moved 25 m, the 13th step updates). Returns the diagnostics of every step.
std::vector<StepDiagnostics> RunOneParticle(ParticleFilterKind kind, const std::vector<double>& offset,
                                            bool average) {
  const GeoGrid& g = CrustalMap();
  const std::size_t layer = g.layer("anomaly_nT");
  ParticleFilterOptions o;
  o.num_particles = o.max_particles = 1;
  o.drift_sigma_deg = 1e-12;
  o.prior_half_width_deg = 0.001;
  o.average_spaced_readings = average;
  o.fission_lambda = 1e-12;  // AFPF offspring on their parent (the test is of the reading, not of fission)
  auto f = MakeParticleFilter(kind, g, layer, o);
  std::vector<StepDiagnostics> out;
  const double lat0 = 45.02, lon0 = 10.02, step_deg = 2.0 / MetresPerDegreeLat(lat0);
  double plat = 0.0, plon = 0.0;  // the particle, after the previous step
  int outliers0 = 0;              // the first reading (0 nT, not checked) may be gated
  for (std::size_t k = 0; k < offset.size(); ++k) {
    const double ins_lat = lat0 + static_cast<double>(k) * step_deg;
    double z = 0.0;
    if (k == 0) {
      z = 0.0;  // the prior is drawn inside Step: a reading of 0 nT, not checked
    } else {
      plat += step_deg;  // where the particle will be (the INS increment; drift 1e-12°)
      z = g.Sample(layer, plat, plon)->value_nT + offset[k];
    }
    out.push_back(f->Step(ins_lat, lon0, z));
    plat = f->particles().front().lat_deg, plon = f->particles().front().lon_deg;
    if (k == 0) outliers0 = f->counters().outliers;
  }
  EXPECT_EQ(f->counters().outliers - outliers0, average ? 1 : 0);
  return out;
}

TEST(SpacedReadings, TheUpdateWeighsTheMeanOfTheSpacedResidualsAndItsOwn) {
  // Steps 1..12 are 2..24 m from step 0 (spaced out), step 13 is 26 m away (an update).
  std::vector<double> offset = {0.0, 2.0, -1.0, 4.0, 1000.0, 3.0, -2.0, 0.5, 1.5, -0.5, 2.5, 6.0, -3.0, 7.0};
  double sum = 0.0;
  int n = 0;
  for (std::size_t k = 1; k < offset.size(); ++k) {
    if (offset[k] < 100.0) sum += offset[k], ++n;
  }
  const double mean = sum / n;  // 19 / 12: the spike is left out
  for (ParticleFilterKind kind : {ParticleFilterKind::kPf, ParticleFilterKind::kAfpf}) {
    SCOPED_TRACE(ParticleFilterKindName(kind));
    const auto avg = RunOneParticle(kind, offset, true);
    for (std::size_t k = 1; k + 1 < offset.size(); ++k) {
      EXPECT_EQ(avg[k].update, k == 4 ? StepUpdate::kOutlier : StepUpdate::kSpaced) << k;
    }
    // One particle of weight 1: NIS = −2 log p(z|x) = r̄² / σ², r̄ the residual that weighed it.
    const StepDiagnostics& u = avg.back();
    ASSERT_EQ(u.update, StepUpdate::kUpdated);
    EXPECT_NEAR(u.nis, mean * mean / (u.sigma_nT * u.sigma_nT), 1e-9);
    // The innovation (σ, gate, lost-track rules) is this reading's own, as before.
    EXPECT_NEAR(u.innovation_nT, 7.0, 1e-6);
    // Dropped (as before): the particle is weighed by its own reading's residual, 7 nT.
    const auto dropped = RunOneParticle(kind, offset, false);
    const StepDiagnostics& v = dropped.back();
    ASSERT_EQ(v.update, StepUpdate::kUpdated);
    EXPECT_NEAR(v.nis, 49.0 / (v.sigma_nT * v.sigma_nT), 1e-9);
    EXPECT_NEAR(v.innovation_nT, 7.0, 1e-6);
  }
}


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

TEST(SpacedReadings, AfpfWithItsSigmaAtTheCapIsNotConvergedOnDenseReadings) {
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
