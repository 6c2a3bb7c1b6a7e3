// The converging status (ParticleFilterOptions::settle_updates, StepDiagnostics::converging,
// StatusOf; issue 25 items 3, 4; docs/ACCURACY.md, "A converging status for PF/AFPF"): a filter
// says "converging" from its first step until its cloud's 1-σ spread has stayed below
// settled_sigma_deg for settle_updates updates, "ok" after; a run whose last step is converging is
// never "converged". Status only: the estimates are those of the filter without it.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "crustal_path_run.h"
#include "magnav/mapmatch/particle_filter.h"

namespace magnav::mapmatch {
namespace {

using testing_paths::CrustalMap;
using testing_paths::LoadPathRun;
using testing_paths::PathRun;

double Spread(const StepDiagnostics& d) { return std::sqrt(d.cloud_cov_lat_lat + d.cloud_cov_lon_lon); }

// The reference 0.1°-offset path at 3 nT (150 steps, the path of the interop test's map_fix_status
// case), both filters with their defaults: converging from the first step (the prior square, 1-σ
// 0.08°), then ok once the cloud has settled — every one of the settle_updates updates before the
// first ok step had a spread below settled_sigma_deg — and ok at the end, "converged". Measured
// (seed 1): the first ok at step 43 (PF) and 42 (AFPF); asserted within the first 75 steps (half the
// path: a settle twice as slow, or a filter converging for good, fails). With settle_updates = 0: no
// step converging and the estimates bit for bit the same.
TEST(PfConverging, ARunIsConvergingUntilItsCloudHasSettledThenOk) {
  const GeoGrid& g = CrustalMap();
  const std::size_t layer = g.layer("anomaly_nT");
  const PathRun run = LoadPathRun(magnav::testing::ReferencePath("mappath_crustal_off0p1deg_noise3nT.csv"));
  for (ParticleFilterKind kind : {ParticleFilterKind::kPf, ParticleFilterKind::kAfpf}) {
    SCOPED_TRACE(ParticleFilterKindName(kind));
    const ParticleFilterOptions o;
    std::vector<StepDiagnostics> steps;
    const MatchResult r = MatchParticleFilter(kind, g, layer, run.path, o, &steps);
    ASSERT_EQ(steps.size(), run.path.size());
    EXPECT_EQ(StatusOf(steps.front()), StepStatus::kConverging);
    EXPECT_GT(Spread(steps.front()), 10.0 * o.settled_sigma_deg);
    std::size_t first_ok = steps.size();
    for (std::size_t k = 0; k < steps.size(); ++k) {
      if (StatusOf(steps[k]) == StepStatus::kOk) {
        first_ok = k;
        break;
      }
      EXPECT_TRUE(steps[k].converging || steps[k].lost) << k;
    }
    ASSERT_LT(first_ok, 75u) << "the filter must settle within half the path";
    // The settle criterion held: the last settle_updates updates up to the first ok step were all from a
    // settled cloud.
    int settled_updates = 0;
    for (std::size_t k = first_ok + 1; k-- > 0 && settled_updates < o.settle_updates;) {
      if (steps[k].update != StepUpdate::kUpdated) continue;
      EXPECT_LT(Spread(steps[k]), o.settled_sigma_deg) << k;
      ++settled_updates;
    }
    EXPECT_EQ(settled_updates, o.settle_updates);
    EXPECT_EQ(StatusOf(steps.back()), StepStatus::kOk);
    EXPECT_TRUE(r.converged) << r.reason;
    EXPECT_NE(r.notes.find("converging steps"), std::string::npos) << r.notes;
    std::printf("%s: first ok at step %zu\n", ParticleFilterKindName(kind), first_ok);

    ParticleFilterOptions off = o;
    off.settle_updates = 0;
    std::vector<StepDiagnostics> off_steps;
    const MatchResult ro = MatchParticleFilter(kind, g, layer, run.path, off, &off_steps);
    EXPECT_EQ(ro.lat_deg, r.lat_deg);
    EXPECT_EQ(ro.lon_deg, r.lon_deg);
    for (const StepDiagnostics& d : off_steps) EXPECT_FALSE(d.converging);
    EXPECT_EQ(StatusOf(off_steps.front()), StepStatus::kOk);
  }
}

// A run that ends while its cloud is still wide — the reference path cut after its first 8 steps,
// the PF's cloud then 1-σ ≥ 0.01° (≈ 1 km; fresh dense path 9103's PF said "converged" 2.3 km off
// with a cloud 4 km wide) — is not "converged", and says why; with settle_updates = 0 (before the
// status) the same run said "converged".
TEST(PfConverging, AWideCloudAtTheEndIsNotConverged) {
  const GeoGrid& g = CrustalMap();
  const std::size_t layer = g.layer("anomaly_nT");
  PathRun run = LoadPathRun(magnav::testing::ReferencePath("mappath_crustal_off0p1deg_noise3nT.csv"));
  MatchPath cut;
  for (std::size_t k = 0; k < 8; ++k) {
    cut.k.push_back(run.path.k[k]);
    cut.lat_deg.push_back(run.path.lat_deg[k]);
    cut.lon_deg.push_back(run.path.lon_deg[k]);
    cut.measured_nT.push_back(run.path.measured_nT[k]);
  }
  ParticleFilterOptions o;
  std::vector<StepDiagnostics> steps;
  const MatchResult r = MatchParticleFilter(ParticleFilterKind::kPf, g, layer, cut, o, &steps);
  ASSERT_GT(Spread(steps.back()), 0.01) << "the cloud this test is about must still be wide";
  EXPECT_FALSE(steps.back().lost);
  EXPECT_EQ(StatusOf(steps.back()), StepStatus::kConverging);
  EXPECT_FALSE(r.converged);
  EXPECT_NE(r.reason.find("converging at the end"), std::string::npos) << r.reason;
  o.settle_updates = 0;
  const MatchResult before = MatchParticleFilter(ParticleFilterKind::kPf, g, layer, cut, o);
  EXPECT_TRUE(before.converged) << before.reason;
}

// The converging regime's covariance (ParticleFilterOptions::converging_covariance_mixture, issue 25
// item 4; docs/ACCURACY.md, "The converging regime's covariance"). Calibration harness paths of
// off0p1_noise5 (scripts/calibration_scenarios; filter seed = path number, as the harness runs them), PF
// with its defaults: 3101 (a cloud re-initialised at step 15 and settling on the truth by step 45; with
// the cloud's own covariance a converging step's mean NEES was 8,445, the run that made the harness's
// converging ANEES 500) and 3113 (a cloud that collapsed 0.15° off at steps 13–14 between two lost
// steps: 65). Measured with the mixture: 2.9 and 11.8 (2-D NEES, dof 2); asserted below 5 and 20
// (a 2× regression fails), and above 1,000 and 40 with the option off (the covariance before). The
// estimates, lost flags, statuses and the cloud's own covariance are the same with and without it; a
// converging step's published covariance is at least as wide (trace) as its cloud's, and every other
// step publishes what it did before.
double MeanConvergingNees(const PathRun& run, const std::vector<StepDiagnostics>& steps) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const StepDiagnostics& d = steps[k];
    if (StatusOf(d) != StepStatus::kConverging) continue;
    const double e0 = d.lat_deg - run.true_lat[k], e1 = d.lon_deg - run.true_lon[k];
    const double a = d.cov_lat_lat, b = d.cov_lat_lon, c = d.cov_lon_lon, det = a * c - b * b;
    sum += det > 0.0 ? (c * e0 * e0 - 2.0 * b * e0 * e1 + a * e1 * e1) / det : INFINITY;
    ++n;
  }
  return n > 0 ? sum / n : NAN;
}

TEST(PfConverging, AConvergingStepPublishesTheMixtureOfItsEpisodesClouds) {
  const GeoGrid& g = CrustalMap();
  const std::size_t layer = g.layer("anomaly_nT");
  struct Case {
    int number;
    double below, above_without;
  };
  for (const Case& c : {Case{3101, 5.0, 1000.0}, Case{3113, 20.0, 40.0}}) {
    SCOPED_TRACE("harness path " + std::to_string(c.number));
    const PathRun run = testing_paths::GeneratedPathRun(c.number, "5", "5", "0.1");
    ParticleFilterOptions o;
    o.seed = static_cast<std::uint64_t>(c.number);
    ASSERT_TRUE(o.converging_covariance_mixture) << "the default";
    std::vector<StepDiagnostics> on, off;
    MatchParticleFilter(ParticleFilterKind::kPf, g, layer, run.path, o, &on);
    o.converging_covariance_mixture = false;
    MatchParticleFilter(ParticleFilterKind::kPf, g, layer, run.path, o, &off);
    ASSERT_EQ(on.size(), off.size());
    int widened = 0;
    for (std::size_t k = 0; k < on.size(); ++k) {
      ASSERT_EQ(on[k].lat_deg, off[k].lat_deg) << k;
      ASSERT_EQ(on[k].lon_deg, off[k].lon_deg) << k;
      ASSERT_EQ(on[k].lost, off[k].lost) << k;
      ASSERT_EQ(StatusOf(on[k]), StatusOf(off[k])) << k;
      ASSERT_EQ(on[k].cloud_cov_lat_lat, off[k].cloud_cov_lat_lat) << k;
      if (StatusOf(on[k]) == StepStatus::kConverging) {
        EXPECT_GE(on[k].cov_lat_lat + on[k].cov_lon_lon, on[k].cloud_cov_lat_lat + on[k].cloud_cov_lon_lon) << k;
        EXPECT_GE(on[k].cov_lat_lat * on[k].cov_lon_lon - on[k].cov_lat_lon * on[k].cov_lat_lon, 0.0) << k;
        widened += on[k].cov_lat_lat + on[k].cov_lon_lon > off[k].cov_lat_lat + off[k].cov_lon_lon;
      } else {
        EXPECT_EQ(on[k].cov_lat_lat, off[k].cov_lat_lat) << k;
        EXPECT_EQ(on[k].cov_lon_lon, off[k].cov_lon_lon) << k;
      }
    }
    EXPECT_GT(widened, 0);
    const double with = MeanConvergingNees(run, on), without = MeanConvergingNees(run, off);
    std::printf("path %d: converging steps' mean NEES %.3g with the mixture, %.3g with the cloud's\n", c.number,
                with, without);
    EXPECT_LT(with, c.below);
    EXPECT_GT(without, c.above_without);
  }
}

// The shadows' spread in the published covariance (ParticleFilterOptions::acquisition_ensemble_covariance,
// issue 25 item 4; docs/ACCURACY.md, "The PF's converging covariance from the shadows' spread"). Tuning
// path 396 (3 nT, PF, seed 1; its kidnap at step 72 comes after the shadows have stopped): the filter's
// cloud collapses on a wrong basin (a loss from step 9, published ok from step 19 with a 0.001° cloud
// 0.1° off), two shadows (K = 3, flag off) settle elsewhere. Over the steps the shadows ran that published
// converging or ok, the mean NEES (2 dof) of the published covariance: measured with the shadows'
// spread 1.17 (equal weights), 0.87 (by evidence) and 1.21 (equal, isotropic), asserted below 2.5, 2
// and 2.5 (a 2× regression fails); without it 5,051, asserted above 1,000. The estimates, lost flags, statuses and cloud_cov_* are
// the filter's alone (bit for bit those of the defaults, K = 1), and so is every covariance with the
// shadows run but their spread off; a step the shadows ran publishes at least what it did without them.
double MeanShadowedNees(const PathRun& run, const std::vector<StepDiagnostics>& steps, int* n_out) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const StepDiagnostics& d = steps[k];
    if (d.ensemble_chi2 <= 0.0 || d.lost) continue;  // the shadows did not run, or a lost step
    const double e0 = d.lat_deg - run.true_lat[k], e1 = d.lon_deg - run.true_lon[k];
    const double a = d.cov_lat_lat, b = d.cov_lat_lon, c = d.cov_lon_lon, det = a * c - b * b;
    sum += det > 0.0 ? (c * e0 * e0 - 2.0 * b * e0 * e1 + a * e1 * e1) / det : INFINITY;
    ++n;
  }
  *n_out = n;
  return n > 0 ? sum / n : NAN;
}

TEST(PfConverging, TheShadowsSpreadWidensAnAcquisitionsCovariance) {
  using Mode = ParticleFilterOptions::EnsembleCovariance;
  const GeoGrid& g = CrustalMap();
  const std::size_t layer = g.layer("anomaly_nT");
  const PathRun run = testing_paths::GeneratedPathRun(396, "3", "3");
  auto run_with = [&](int k, Mode mode, bool isotropic = false) {
    ParticleFilterOptions o;
    o.seed = 1;
    o.acquisition_ensemble = k;
    o.acquisition_ensemble_flag = false;
    o.acquisition_ensemble_covariance = mode;
    o.acquisition_ensemble_isotropic = isotropic;
    std::vector<StepDiagnostics> steps;
    MatchParticleFilter(ParticleFilterKind::kPf, g, layer, run.path, o, &steps);
    return steps;
  };
  const std::vector<StepDiagnostics> alone = run_with(1, Mode::kOff), shadows = run_with(3, Mode::kOff);
  int n = 0;
  const double without = MeanShadowedNees(run, shadows, &n);
  std::printf("path 396: steps shadowed %d, mean NEES without the shadows' spread %.4g\n", n, without);
  ASSERT_GT(n, 10) << "the shadows did not run";
  EXPECT_GT(without, 1000.0);
  struct Case {
    Mode mode;
    bool isotropic;
    double below;
  };
  for (const Case& c : {Case{Mode::kEqual, false, 2.5}, Case{Mode::kEvidence, false, 2.0},
                        Case{Mode::kEqual, true, 2.5}}) {
    const std::string name = std::string(c.mode == Mode::kEqual ? "equal" : "evidence") + (c.isotropic ? ", isotropic" : "");
    SCOPED_TRACE(name);
    const std::vector<StepDiagnostics> with = run_with(3, c.mode, c.isotropic);
    ASSERT_EQ(with.size(), alone.size());
    int widened = 0;
    for (std::size_t k = 0; k < with.size(); ++k) {
      ASSERT_EQ(with[k].lat_deg, alone[k].lat_deg) << k;
      ASSERT_EQ(with[k].lon_deg, alone[k].lon_deg) << k;
      ASSERT_EQ(with[k].lost, alone[k].lost) << k;
      ASSERT_EQ(StatusOf(with[k]), StatusOf(alone[k])) << k;
      ASSERT_EQ(with[k].cloud_cov_lat_lat, alone[k].cloud_cov_lat_lat) << k;
      ASSERT_EQ(shadows[k].cov_lat_lat, alone[k].cov_lat_lat) << k;
      ASSERT_EQ(shadows[k].cov_lon_lon, alone[k].cov_lon_lon) << k;
      const double tr = with[k].cov_lat_lat + with[k].cov_lon_lon, tr0 = alone[k].cov_lat_lat + alone[k].cov_lon_lon;
      if (with[k].ensemble_chi2 > 0.0 && !with[k].lost) {
        EXPECT_GE(tr, tr0) << k;
        EXPECT_GE(with[k].cov_lat_lat * with[k].cov_lon_lon - with[k].cov_lat_lon * with[k].cov_lat_lon, 0.0) << k;
        widened += tr > tr0;
      } else {
        EXPECT_EQ(with[k].cov_lat_lat, alone[k].cov_lat_lat) << k;
        EXPECT_EQ(with[k].cov_lon_lon, alone[k].cov_lon_lon) << k;
      }
    }
    EXPECT_GT(widened, 0);
    const double nees = MeanShadowedNees(run, with, &n);
    std::printf("path 396: mean NEES with the shadows' spread (%s) %.4g\n", name.c_str(), nees);
    EXPECT_LT(nees, c.below);
  }

  ParticleFilterOptions bad;
  bad.acquisition_ensemble_covariance = Mode::kEqual;
  EXPECT_FALSE(bad.IsValid(nullptr)) << "the shadows' spread without shadows";
  bad.acquisition_ensemble = 3;
  EXPECT_TRUE(bad.IsValid(nullptr));
  bad.acquisition_ensemble_covariance = static_cast<Mode>(7);
  EXPECT_FALSE(bad.IsValid(nullptr));
  bad.acquisition_ensemble_covariance = Mode::kOff;
  bad.acquisition_ensemble_isotropic = true;
  EXPECT_FALSE(bad.IsValid(nullptr)) << "isotropic without the shadows' spread";
}

TEST(PfConverging, StatusNamesAndOptions) {
  StepDiagnostics d;
  EXPECT_STREQ(StepStatusName(StatusOf(d)), "ok");
  d.converging = true;
  EXPECT_STREQ(StepStatusName(StatusOf(d)), "converging");
  d.update = StepUpdate::kAllOffMap;
  EXPECT_STREQ(StepStatusName(StatusOf(d)), "off_map");
  d.lost = true;
  EXPECT_STREQ(StepStatusName(StatusOf(d)), "lost");
  ParticleFilterOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.settle_updates = -1;
  EXPECT_FALSE(o.IsValid(&why));
  o.settle_updates = 0;
  EXPECT_TRUE(o.IsValid(&why)) << why;
}

}  // namespace
}  // namespace magnav::mapmatch
