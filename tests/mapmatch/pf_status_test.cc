// The particle filters' status (issue 25, items 3 and 6), on a few fixed seeds
// with margins (the full measurement is scripts/calibration_pf, outside CI):
//   * the AFPF at 5 nT noise with its defaults: second-half mean error within
//     25 % of the INS's on the crustal reference 0.01° 5 nT path (the target;
//     measured 13–24 % over seeds 1–3 with afpf_max_sigma_nT 20, 16–24 % with
//     the 15 of before), within 4 % on the 0.1° one (measured 2.0–2.2 %;
//     1.7–2.3 % with 15: a 2× regression breaks both); with the fixed 5 nT σ
//     of before issue 25, --afpf-sigma-factor 0: 133–705 %. Its figure on
//     generated paths (held out: 0.01° mean 16 %) is scripts/calibration_pf's,
//     outside CI (docs/ACCURACY.md, "AFPF at 5 nT with its defaults");
//   * clean runs raise no lost-track alarm (reference 0.5 / 3 / 5 nT paths);
//   * a run whose readings stop matching the map near its end is lost and
//     says so: never "converged" (before: "converged … lost from k = …,
//     recovered", the re-initialisation having cleared the alarm).
//   * a kidnapped PF (from step 60 the INS is 0.008° off while the vehicle
//     is not: the filter follows it off the truth) with the innovation-bias
//     test on (bias_test_chi2 = 12; off by default, see particle_filter.h)
//     raises the lost flag within 20 steps of the kidnap, and a run beyond
//     3 σ of its own covariance over its last 10 steps is not "converged";
//     6 directions on the 0.5 nT reference path (with the divergence rule
//     alone direction 2 is lost from step 60 and never flagged). Not
//     asserted, because not met: a later loss (a re-acquisition locking onto
//     a wrong basin, directions 0, 3, 4 from steps 94–117) flagged within 20
//     steps;
//   * the AFPF there with its defaults (direction 1): a run lost at its end
//     never says "converged" (its detection rate is below target:
//     docs/ACCURACY.md, "Lost-track detection").
//   * the AFPF there with its defaults, 6 directions: at least 2 of its
//     losses flagged within 20 steps (3 of 4 measured; none with the
//     divergence rule alone);
//   * a lost filter publishes at least the prior square's covariance, not
//     its collapsed cloud's (issue 25 item 4).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/mapmatch/particle_filter.h"
#include "crustal_path_run.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

using testing_paths::LoadPathRun;
using testing_paths::PathRun;
const GeoGrid& Map() { return testing_paths::CrustalMap(); }
PathRun Load(const std::string& name) { return LoadPathRun(testing::ReferencePath(name)); }

// Second-half mean error of `lat, lon` over that of the INS.
double SecondHalfRatio(const PathRun& run, const std::vector<double>& lat, const std::vector<double>& lon) {
  const std::size_t n = run.path.size(), h = n / 2;
  double e = 0.0, ins = 0.0;
  for (std::size_t k = h; k < n; ++k) {
    e += std::hypot(lat[k] - run.true_lat[k], lon[k] - run.true_lon[k]);
    ins += std::hypot(run.path.lat_deg[k] - run.true_lat[k], run.path.lon_deg[k] - run.true_lon[k]);
  }
  return e / ins;
}

TEST(PfStatus, AfpfHoldsAt5nTWithItsDefaults) {
  const std::pair<const char*, double> paths[] = {{"mappath_crustal_off0p01deg_noise5nT.csv", 0.25},
                                                  {"mappath_crustal_off0p1deg_noise5nT.csv", 0.04}};
  for (const auto& [name, bound] : paths) {
    const PathRun run = Load(name);
    for (std::uint64_t seed = 1; seed <= 2; ++seed) {
      SCOPED_TRACE(std::string(name) + " seed " + std::to_string(seed));
      ParticleFilterOptions o;
      o.seed = seed;
      const MatchResult r = MatchParticleFilter(ParticleFilterKind::kAfpf, Map(), 0, run.path, o);
      EXPECT_LE(SecondHalfRatio(run, r.lat_deg, r.lon_deg), bound) << r.BriefReport();
    }
  }
}

TEST(PfStatus, CleanRunsRaiseNoAlarm) {
  for (const char* name : {"mappath_crustal_off0p01deg_noise0p5nT.csv", "mappath_crustal_off0p1deg_noise3nT.csv",
                           "mappath_crustal_off0p1deg_noise5nT.csv"}) {
    const PathRun run = Load(name);
    for (const ParticleFilterKind kind : {ParticleFilterKind::kPf, ParticleFilterKind::kAfpf}) {
      SCOPED_TRACE(std::string(name) + " " + ParticleFilterKindName(kind));
      ParticleFilterOptions o;
      o.seed = 1;
      std::vector<StepDiagnostics> steps;
      const MatchResult r = MatchParticleFilter(kind, Map(), 0, run.path, o, &steps);
      EXPECT_TRUE(r.converged) << r.BriefReport();
      EXPECT_TRUE(r.reason.empty()) << r.BriefReport();
      for (const StepDiagnostics& d : steps) ASSERT_FALSE(d.lost);
    }
  }
}

// The last 25 readings are replaced by a constant far from the map's values
// there (+300 nT on a ±60 nT anomaly): no particle fits, the filter is lost,
// re-initialises, and is lost again; the summary must not say "converged".
TEST(PfStatus, ALostRunNeverSaysConverged) {
  PathRun run = Load("mappath_crustal_off0p1deg_noise0p5nT.csv");
  const std::size_t n = run.path.size();
  for (std::size_t k = n - 25; k < n; ++k) run.path.measured_nT[k] = 300.0;
  for (const ParticleFilterKind kind : {ParticleFilterKind::kPf, ParticleFilterKind::kAfpf}) {
    SCOPED_TRACE(ParticleFilterKindName(kind));
    ParticleFilterOptions o;
    o.seed = 1;
    std::vector<StepDiagnostics> steps;
    const MatchResult r = MatchParticleFilter(kind, Map(), 0, run.path, o, &steps);
    bool flagged = false;
    for (std::size_t k = n - 25; k < n; ++k) flagged = flagged || steps[k].lost;
    EXPECT_TRUE(flagged);
    EXPECT_FALSE(r.converged) << r.BriefReport();
    EXPECT_NE(r.reason.find("lost"), std::string::npos) << r.BriefReport();
    EXPECT_EQ(r.reason.find("recovered"), std::string::npos) << r.BriefReport();
  }
}

}  // namespace
}  // namespace magnav::mapmatch

namespace magnav::mapmatch {
namespace {

// From step `from` on the INS is `deg` off in direction `dir_rad` (applied as motion) while the
// vehicle does not move (scripts/calibration_pf's kidnap).
PathRun Kidnapped(double dir_rad, std::size_t from = 60, double deg = 0.008) {
  PathRun run = Load("mappath_crustal_off0p01deg_noise0p5nT.csv");
  for (std::size_t k = from; k < run.path.size(); ++k) {
    run.path.lat_deg[k] += deg * std::cos(dir_rad);
    run.path.lon_deg[k] += deg * std::sin(dir_rad);
  }
  return run;
}

// 2-D NEES of step k's estimate against a covariance (deg²).
double Nees(const PathRun& run, std::size_t k, const StepDiagnostics& d, double cll, double cln, double cnn) {
  const double e0 = d.lat_deg - run.true_lat[k], e1 = d.lon_deg - run.true_lon[k];
  const double det = cll * cnn - cln * cln;
  return det > 0.0 ? (cnn * e0 * e0 - 2.0 * cln * e0 * e1 + cll * e1 * e1) / det
                   : std::numeric_limits<double>::infinity();
}

// Per step: the estimate beyond 3 σ of its cloud's own covariance (2-D NEES > 9; a lost filter
// publishes the prior's, cov_*, which would hide the loss).
std::vector<bool> Beyond3Sigma(const PathRun& run, const std::vector<StepDiagnostics>& steps) {
  std::vector<bool> bad;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const StepDiagnostics& d = steps[k];
    bad.push_back(!(Nees(run, k, d, d.cloud_cov_lat_lat, d.cloud_cov_lat_lon, d.cloud_cov_lon_lon) <= 9.0));
  }
  return bad;
}

// Beyond 3 σ over the last 10 steps.
bool LostAtEnd(const std::vector<bool>& bad) {
  bool lost = bad.size() >= 10;
  for (std::size_t k = bad.size() - std::min<std::size_t>(10, bad.size()); k < bad.size(); ++k) lost = lost && bad[k];
  return lost;
}

bool FlaggedIn(const std::vector<StepDiagnostics>& steps, std::size_t from, std::size_t to) {
  for (std::size_t k = from; k <= to && k < steps.size(); ++k) {
    if (steps[k].lost) return true;
  }
  return false;
}

TEST(PfStatus, AKidnappedPfIsFlaggedWithin20Steps) {
  for (int j = 0; j < 6; ++j) {
    SCOPED_TRACE("direction " + std::to_string(j));
    const PathRun run = Kidnapped(j * 2.399963);
    ParticleFilterOptions o;
    o.seed = 1;
    o.bias_test_chi2 = 12.0;
    std::vector<StepDiagnostics> steps;
    const MatchResult r = MatchParticleFilter(ParticleFilterKind::kPf, Map(), 0, run.path, o, &steps);
    EXPECT_TRUE(FlaggedIn(steps, 60, 80)) << r.BriefReport();
    EXPECT_FALSE(LostAtEnd(Beyond3Sigma(run, steps)) && r.converged) << r.BriefReport();
  }
}

// Direction 1: the AFPF is beyond 3 σ from step 59 to the end and its flag
// comes at step 144 (before the settling hold and the bias test: never
// flagged, and the summary said "converged").
TEST(PfStatus, AKidnappedAfpfLostAtItsEndNeverSaysConverged) {
  for (int j = 1; j < 2; ++j) {
    SCOPED_TRACE("direction " + std::to_string(j));
    const PathRun run = Kidnapped(j * 2.399963);
    ParticleFilterOptions o;
    o.seed = 1;
    std::vector<StepDiagnostics> steps;
    const MatchResult r = MatchParticleFilter(ParticleFilterKind::kAfpf, Map(), 0, run.path, o, &steps);
    if (LostAtEnd(Beyond3Sigma(run, steps))) {
      EXPECT_FALSE(r.converged) << r.BriefReport();
    }
  }
}

}  // namespace
}  // namespace magnav::mapmatch

namespace magnav::mapmatch {
namespace {

// A lost filter's published covariance says so (issue 25 item 4): at every
// step flagged lost it is at least the prior square's (h²/3 per axis), and
// the estimate lies within 3 σ of it, while the cloud's own covariance puts
// it beyond 3 σ at some of those steps (the kidnapped AFPF, direction 1,
// flagged at the end of its run; with lost_covariance_is_prior = false the
// published NEES is the cloud's and this test fails). Steps not flagged lost publish the cloud's covariance.
TEST(PfStatus, ALostFilterPublishesThePriorsCovariance) {
  const PathRun run = Kidnapped(1 * 2.399963);
  ParticleFilterOptions o;
  o.seed = 1;
  std::vector<StepDiagnostics> steps;
  MatchParticleFilter(ParticleFilterKind::kAfpf, Map(), 0, run.path, o, &steps);
  const double v = o.prior_half_width_deg * o.prior_half_width_deg / 3.0;
  int lost = 0, cloud_beyond = 0;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const StepDiagnostics& d = steps[k];
    if (!d.lost) {
      EXPECT_EQ(d.cov_lat_lat, d.cloud_cov_lat_lat) << "k " << k;
      EXPECT_EQ(d.cov_lon_lon, d.cloud_cov_lon_lon) << "k " << k;
      continue;
    }
    ++lost;
    EXPECT_GE(d.cov_lat_lat + d.cov_lon_lon, 2.0 * v * (1.0 - 1e-12)) << "k " << k;
    EXPECT_LE(Nees(run, k, d, d.cov_lat_lat, d.cov_lat_lon, d.cov_lon_lon), 9.0) << "k " << k;
    if (Nees(run, k, d, d.cloud_cov_lat_lat, d.cloud_cov_lat_lon, d.cloud_cov_lon_lon) > 9.0) ++cloud_beyond;
  }
  EXPECT_GE(lost, 3);  // measured 4 (the bias test)
  EXPECT_GE(cloud_beyond, 3);  // measured 4: what the cloud alone would have published
}

}  // namespace
}  // namespace magnav::mapmatch

namespace magnav::mapmatch {
namespace {

// The AFPF's detection rate on fixed seeds (issue 25 item 3; the full
// measurement is scripts/calibration_pf): the 0.5 nT reference path
// kidnapped 0.008° at step 60 in 6 directions, defaults. A direction counts
// when its run is beyond 3 σ of its cloud for 10 steps in a row and the lost
// flag comes within 20 steps of that loss's start. Not the target (90 %):
// a margin under today's 3 of 4 that a halving breaks (≈ 3 s).
TEST(PfStatus, AKidnappedAfpfIsFlaggedOnMostDirections) {
  int losses = 0, detected = 0;
  for (int j = 0; j < 6; ++j) {
    const PathRun run = Kidnapped(j * 2.399963);
    ParticleFilterOptions o;
    o.seed = 1;
    std::vector<StepDiagnostics> steps;
    MatchParticleFilter(ParticleFilterKind::kAfpf, Map(), 0, run.path, o, &steps);
    const std::vector<bool> bad = Beyond3Sigma(run, steps);
    int streak = 0;
    for (std::size_t k = 0; k < bad.size(); ++k) {
      streak = bad[k] ? streak + 1 : 0;
      if (streak == 10) {
        ++losses;
        const bool flagged = FlaggedIn(steps, k - 9, k + 11);
        detected += flagged ? 1 : 0;
        break;
      }
    }
  }
  // Measured: directions 1–4 lost from step 60, 1, 3 and 4 flagged within 20 steps (3 of 4);
  // with the divergence rule alone (afpf_bias_test_chi2 = 0) none of them.
  EXPECT_GE(losses, 3);
  EXPECT_GE(detected, 2) << losses << " losses";
}

}  // namespace
}  // namespace magnav::mapmatch

namespace magnav::mapmatch {
namespace {

// The PF's innovation CUSUM (issue 25 item 3, fifth round; particle_filter.h
// innovation_cusum_*), with its defaults: the 0.5 nT reference path kidnapped
// 0.008° at step 90 in 6 directions (seed 1). Measured: directions 0, 1, 3, 4
// and 5 make a loss from step 90 (beyond 3 σ of the cloud for 10 steps in a
// row); the CUSUM flags 0, 1 and 5 within 20 steps (at steps 9x), misses 3 and
// 4 (their readings differ from the truth's by 1–3 nT: the "small kidnaps" of
// docs/ACCURACY.md, fifth round); with it off (innovation_cusum_threshold = 0,
// the defaults of before) none of the five is flagged. Asserted: each of 0, 1
// and 5 flagged within 20 steps of its loss's start, none of the five with the
// CUSUM off (so the flags are the CUSUM's), and clean runs never flagged: the
// reference 0.01° 3 nT, 0.1° 5 nT and 0.1° 0.5 nT paths, PF seeds 2–3
// (CleanRunsRaiseNoAlarm runs seed 1). The rate on generated paths is
// scripts/calibration_pf's, outside CI. ≈ 1 s CPU.
TEST(PfStatus, TheInnovationCusumFlagsKidnapsAndNotCleanRuns) {
  int losses = 0, detected = 0, detected_off = 0;
  for (int j = 0; j < 6; ++j) {
    SCOPED_TRACE("direction " + std::to_string(j));
    const PathRun run = Kidnapped(j * 2.399963, 90);
    for (const bool on : {true, false}) {
      ParticleFilterOptions o;
      o.seed = 1;
      o.ins_glitch_ratio = 0.0;  // (the kidnap's INS step is a glitch: this test is the CUSUM's alone)
      if (!on) o.innovation_cusum_threshold = 0.0;
      std::vector<StepDiagnostics> steps;
      MatchParticleFilter(ParticleFilterKind::kPf, Map(), 0, run.path, o, &steps);
      const std::vector<bool> bad = Beyond3Sigma(run, steps);
      int streak = 0;
      for (std::size_t k = 0; k < bad.size(); ++k) {
        streak = bad[k] ? streak + 1 : 0;
        if (streak < 10) continue;
        const std::size_t start = k - 9;
        const bool flagged = start >= 90 && FlaggedIn(steps, start, start + 20);
        if (on) {
          ++losses;
          detected += flagged ? 1 : 0;
          if (j == 0 || j == 1 || j == 5) {
            EXPECT_TRUE(flagged) << "loss from step " << start << " not flagged";
          }
        } else {
          detected_off += flagged ? 1 : 0;
        }
        break;
      }
      if (on) {
        EXPECT_FALSE(FlaggedIn(steps, 0, 89)) << "flagged before the kidnap";
      }
    }
  }
  RecordProperty("kidnap_losses", losses);
  RecordProperty("flagged_within_20", detected);
  RecordProperty("flagged_within_20_cusum_off", detected_off);
  EXPECT_GE(losses, 4);  // measured 5: the kidnaps must make losses for this test to mean anything
  EXPECT_GE(detected, 3);
  EXPECT_EQ(detected_off, 0);
  for (const char* name : {"mappath_crustal_off0p01deg_noise3nT.csv", "mappath_crustal_off0p1deg_noise5nT.csv",
                           "mappath_crustal_off0p1deg_noise0p5nT.csv"}) {
    const PathRun run = Load(name);
    for (std::uint64_t seed = 2; seed <= 3; ++seed) {
      SCOPED_TRACE(std::string(name) + " seed " + std::to_string(seed));
      ParticleFilterOptions o;
      o.seed = seed;
      std::vector<StepDiagnostics> steps;
      const MatchResult r = MatchParticleFilter(ParticleFilterKind::kPf, Map(), 0, run.path, o, &steps);
      int flagged = 0;
      for (const StepDiagnostics& d : steps) flagged += d.lost ? 1 : 0;
      EXPECT_EQ(flagged, 0) << r.BriefReport();
      EXPECT_TRUE(r.converged) << r.BriefReport();
    }
  }
}

}  // namespace
}  // namespace magnav::mapmatch
