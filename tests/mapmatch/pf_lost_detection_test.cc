// Lost-track detection, sixth round (issue 25 item 3; docs/ACCURACY.md, "Lost-track detection, sixth
// round"; ParticleFilterOptions::ins_glitch_* and acquisition_bias_test_chi2). Fixed seeds with margins;
// the rates on generated paths are scripts/calibration_pf's, outside CI.
//   * The INS glitch test: the 0.5 nT reference path kidnapped 0.008° (the INS jumps in one step,
//     applied as motion, while the vehicle does not move) at step 90 in 6 directions, both filters
//     with their defaults: every loss that starts at the kidnap is flagged within 20 steps of its
//     start (measured: directions 0, 1, 3, 4, 5 lost from step 90, each method, 5 of 5 flagged);
//     with the test off (ins_glitch_ratio = 0, the rules of before) 3 of 5 (the PF's CUSUM, the
//     AFPF's bias test). Kidnapped at step 60 instead, the PF's losses of directions 0, 3, 4 start
//     at steps 94–117 (a re-acquisition settling on a wrong place, after the glitch's 20-step
//     hold) and are not flagged: not asserted, because not met.
//   * The bias test during acquisition: generated tuning path 329 (3 nT; the PF's single cloud
//     collapses on a wrong basin at step 6 and stays there; before, first flagged at step 65):
//     flagged within 20 steps of the loss's start; not with acquisition_bias_test_chi2 = 0.
//   * Neither raises an alarm on clean runs: the crustal reference 0.01° 0.5 nT and 0.1° 5 nT paths
//     (filter seed 2; pf_status_test's CleanRunsRaiseNoAlarm runs seed 1 on three reference paths)
//     and generated clean tuning paths 321–323 (3 nT) and 341–343 (5 nT), both filters, seed 1.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/mapmatch/particle_filter.h"
#include "crustal_path_run.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

using testing_paths::LoadPathRun;
using testing_paths::PathRun;
const GeoGrid& Map() { return testing_paths::CrustalMap(); }

PathRun Generated(int number, const std::string& noise, const std::string& tag, const std::string& offset = "0.01") {
  return testing_paths::GeneratedPathRun(number, noise, tag, offset);
}

// From step `from` on the INS is `deg` off in direction `dir_rad` (applied as motion) while the vehicle
// does not move (scripts/calibration_pf's kidnap).
PathRun Kidnapped(double dir_rad, std::size_t from = 60, double deg = 0.008) {
  PathRun run = LoadPathRun(testing::ReferencePath("mappath_crustal_off0p01deg_noise0p5nT.csv"));
  for (std::size_t k = from; k < run.path.size(); ++k) {
    run.path.lat_deg[k] += deg * std::cos(dir_rad);
    run.path.lon_deg[k] += deg * std::sin(dir_rad);
  }
  return run;
}

// The loss's first step: beyond 3 σ of the cloud's own covariance (2-D NEES > 9) for 10 steps in a row
// (scripts/calibration_pf's definition).
std::optional<std::size_t> LossStart(const PathRun& run, const std::vector<StepDiagnostics>& steps) {
  int beyond = 0;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const StepDiagnostics& d = steps[k];
    const double e0 = d.lat_deg - run.true_lat[k], e1 = d.lon_deg - run.true_lon[k];
    const double a = d.cloud_cov_lat_lat, b = d.cloud_cov_lat_lon, c = d.cloud_cov_lon_lon;
    const double det = a * c - b * b;
    const double nees = det > 0.0 ? (c * e0 * e0 - 2.0 * b * e0 * e1 + a * e1 * e1) / det : INFINITY;
    beyond = !(nees <= 9.0) ? beyond + 1 : 0;
    if (beyond == 10) return k - 9;
  }
  return std::nullopt;
}

constexpr std::size_t kKidnapStep = 90;

bool FlaggedIn(const std::vector<StepDiagnostics>& steps, std::size_t from, std::size_t to) {
  for (std::size_t k = from; k <= to && k < steps.size(); ++k) {
    if (steps[k].lost) return true;
  }
  return false;
}

TEST(PfLostDetection, AnInsGlitchFlagsEveryKidnapLoss) {
  for (const ParticleFilterKind kind : {ParticleFilterKind::kPf, ParticleFilterKind::kAfpf}) {
    SCOPED_TRACE(ParticleFilterKindName(kind));
    int losses = 0, detected = 0, detected_off = 0;
    for (int j = 0; j < 6; ++j) {
      SCOPED_TRACE("direction " + std::to_string(j));
      const PathRun run = Kidnapped(j * 2.399963, kKidnapStep);
      for (const bool on : {true, false}) {
        ParticleFilterOptions o;
        o.seed = 1;
        if (!on) o.ins_glitch_ratio = 0.0;
        std::vector<StepDiagnostics> steps;
        MatchParticleFilter(kind, Map(), 0, run.path, o, &steps);
        if (on) {
          EXPECT_FALSE(FlaggedIn(steps, 0, kKidnapStep - 1)) << "flagged before the kidnap";
          // the jump departs; the glitch is confirmed by the usual step after it
          EXPECT_GT(steps[kKidnapStep].ins_step_ratio, o.ins_glitch_ratio);
          EXPECT_FALSE(steps[kKidnapStep].ins_glitch);
          EXPECT_TRUE(steps[kKidnapStep + 1].ins_glitch);
        }
        const std::optional<std::size_t> start = LossStart(run, steps);
        // (a loss may start a step or two before the kidnap: the estimate after a step is judged)
        if (!start || *start + 5 < kKidnapStep) continue;
        const bool flagged = FlaggedIn(steps, *start, *start + 20);
        if (on) {
          ++losses;
          detected += flagged ? 1 : 0;
          EXPECT_TRUE(flagged) << "loss from step " << *start << " not flagged within 20 steps";
        } else {
          detected_off += flagged ? 1 : 0;
        }
      }
    }
    RecordProperty(std::string(ParticleFilterKindName(kind)) + "_kidnap_losses", losses);
    RecordProperty(std::string(ParticleFilterKindName(kind)) + "_flagged_within_20_glitch_off", detected_off);
    EXPECT_GE(losses, 3);  // the kidnaps must make losses for this test to mean anything
    EXPECT_EQ(detected, losses);
    EXPECT_LT(detected_off, losses) << "the test adds nothing over the rules of before";
    printf("%s: %d losses, flagged %d, with the glitch test off %d\n", ParticleFilterKindName(kind), losses, detected,
           detected_off);
  }
}

TEST(PfLostDetection, TheBiasTestDuringAcquisitionFlagsAWrongBasin) {
  const PathRun run = Generated(329, "3", "3");
  for (const bool on : {true, false}) {
    SCOPED_TRACE(on ? "on" : "off");
    ParticleFilterOptions o;
    o.seed = 1;
    if (!on) o.acquisition_bias_test_chi2 = 0.0;
    std::vector<StepDiagnostics> steps;
    MatchParticleFilter(ParticleFilterKind::kPf, Map(), 0, run.path, o, &steps);
    const std::optional<std::size_t> start = LossStart(run, steps);
    ASSERT_TRUE(start.has_value());
    EXPECT_LE(*start, 20u);  // an acquisition loss (measured: from step 6)
    EXPECT_EQ(FlaggedIn(steps, *start, *start + 20), on) << "loss from step " << *start;
  }
}

// Seventh round (acquisition_collapse_ratio): two clean runs of scripts/calibration's PF scenarios
// (off0p01_noise3 path 3018, off0p1_noise5 path 3104; filter seed = path number, as the harness runs
// them) whose cloud collapses from the wide prior onto the right basin at steps 14–16 while its
// innovations are large and same-signed (12–34 nT): with the sixth round's window (ratio 0) the
// acquisition test counts them and flags a run that is never lost (steps 17–18, 19–22); with the
// window restricted to the innovations of a cloud at most 2× the current one's spread, no flag.
// (Tuning path 329's wrong-basin collapse is still flagged with the defaults: the test above.)
TEST(PfLostDetection, TheAcquisitionTestIgnoresACollapsingCloudsInnovations) {
  const std::vector<std::pair<int, PathRun>> runs = {{3018, Generated(3018, "3", "3", "0.01")},
                                                     {3104, Generated(3104, "5", "5", "0.1")}};
  for (const auto& [number, run] : runs) {
    for (const bool on : {true, false}) {
      SCOPED_TRACE("path " + std::to_string(number) + (on ? ", collapse ratio 2" : ", collapse ratio 0"));
      ParticleFilterOptions o;
      o.seed = static_cast<std::uint64_t>(number);
      if (!on) o.acquisition_collapse_ratio = 0.0;
      std::vector<StepDiagnostics> steps;
      const MatchResult r = MatchParticleFilter(ParticleFilterKind::kPf, Map(), 0, run.path, o, &steps);
      ASSERT_FALSE(LossStart(run, steps).has_value()) << "a clean run";
      EXPECT_EQ(FlaggedIn(steps, 0, steps.size() - 1), !on);
      if (on) {
        EXPECT_TRUE(r.converged) << r.BriefReport();
      }
    }
  }
}

// Strict-detection round (track_check_acquisition_only, an option: off by default): the track check
// (window 20, threshold 40) run only during acquisition. Tuning path 396 (kidnap regime, 3 nT, filter
// seed 1; its kidnap at step 72 comes after what is asserted here) collapses on a wrong basin at step 9
// and the default rules first flag it at step 32 (seventh round): with the check during acquisition it
// is flagged within 20 steps of the loss's start (measured: step 19); not with the defaults. Clean tuning
// path 339 (3 nT, seed 1): the check at every step flags it (measured: step 64, a chance fit on a settled
// track); during acquisition only, no flag. Both measured offline from --diagnostics first
// (docs/ACCURACY.md, "PF/AFPF strict lost-track detection: the missed losses by kind").
TEST(PfLostDetection, TheTrackCheckDuringAcquisitionOnly) {
  auto run_with = [](const PathRun& run, int window, bool acquisition_only) {
    ParticleFilterOptions o;
    o.seed = 1;
    o.track_check_window = window;
    o.track_check_acquisition_only = acquisition_only;
    std::vector<StepDiagnostics> steps;
    MatchParticleFilter(ParticleFilterKind::kPf, Map(), 0, run.path, o, &steps);
    return steps;
  };
  const PathRun lost = Generated(396, "3", "3");
  const std::vector<StepDiagnostics> on = run_with(lost, 20, true), off = run_with(lost, 0, false);
  const std::optional<std::size_t> start = LossStart(lost, on);
  ASSERT_TRUE(start.has_value());
  EXPECT_LE(*start, 20u);  // an acquisition loss (measured: from step 9)
  EXPECT_EQ(LossStart(lost, off), start) << "the check flags only: the same estimates";
  EXPECT_TRUE(FlaggedIn(on, *start, *start + 20)) << "loss from step " << *start;
  EXPECT_FALSE(FlaggedIn(off, *start, *start + 20)) << "the defaults flag it within 20 steps already";
  bool track_flag = false;
  for (std::size_t k = *start; k <= *start + 20 && k < on.size(); ++k) {
    track_flag = track_flag || on[k].track_check_failed;
  }
  EXPECT_TRUE(track_flag) << "flagged, but not by the track check";

  const PathRun clean = Generated(339, "3", "3");
  const std::vector<StepDiagnostics> every = run_with(clean, 20, false), acq = run_with(clean, 20, true);
  ASSERT_FALSE(LossStart(clean, acq).has_value()) << "a clean run";
  EXPECT_TRUE(FlaggedIn(every, 0, every.size() - 1))
      << "the check at every step no longer flags this clean run: the test shows nothing";
  EXPECT_FALSE(FlaggedIn(acq, 0, acq.size() - 1));
}

// The ensemble disagreement during acquisition (acquisition_ensemble, issue 25 item 3, branch pfens).
// Tuning path 396 (3 nT, PF, seed 1): a wrong-basin settle from step 9 that the defaults do not flag
// within 20 steps; two shadows (K = 3) settle elsewhere with evidence at least the filter's, and the
// flag comes at step 14 (measured offline from --diagnostics first, then with the option). Clean tuning
// path 324 (3 nT): a shadow settles 0.12 deg away (E up to 1.7e4), but the readings favour the filter,
// so no flag; without the evidence condition (acquisition_ensemble_nats very large) it is flagged.
// docs/ACCURACY.md, "Ensemble disagreement during acquisition".
TEST(PfLostDetection, TheEnsembleDisagreementDuringAcquisition) {
  auto run_with = [](const PathRun& run, int k, double nats) {
    ParticleFilterOptions o;
    o.seed = 1;
    o.acquisition_ensemble = k;
    o.acquisition_ensemble_nats = nats;
    std::vector<StepDiagnostics> steps;
    MatchParticleFilter(ParticleFilterKind::kPf, Map(), 0, run.path, o, &steps);
    return steps;
  };
  const ParticleFilterOptions defaults;
  const PathRun lost = Generated(396, "3", "3");
  const std::vector<StepDiagnostics> on = run_with(lost, 3, defaults.acquisition_ensemble_nats),
                                     off = run_with(lost, 1, defaults.acquisition_ensemble_nats);
  const std::optional<std::size_t> start = LossStart(lost, on);
  ASSERT_TRUE(start.has_value());
  EXPECT_LE(*start, 20u);  // an acquisition loss (measured: from step 9)
  EXPECT_EQ(LossStart(lost, off), start) << "the ensemble flags only: the same estimates";
  for (std::size_t k = 0; k < on.size(); ++k) {
    ASSERT_EQ(on[k].lat_deg, off[k].lat_deg) << "k " << k;
    ASSERT_EQ(on[k].cloud_cov_lat_lat, off[k].cloud_cov_lat_lat) << "k " << k;
  }
  EXPECT_TRUE(FlaggedIn(on, *start, *start + 20)) << "loss from step " << *start;
  EXPECT_FALSE(FlaggedIn(off, *start, *start + 20)) << "the defaults flag it within 20 steps already";
  bool ensemble_flag = false;
  for (std::size_t k = *start; k <= *start + 20 && k < on.size(); ++k) {
    ensemble_flag = ensemble_flag || (on[k].lost && !off[k].lost && on[k].ensemble_disagree);
  }
  EXPECT_TRUE(ensemble_flag) << "flagged, but not by the ensemble";

  const PathRun clean = Generated(324, "3", "3");
  const std::vector<StepDiagnostics> with = run_with(clean, 3, defaults.acquisition_ensemble_nats),
                                     any_shadow = run_with(clean, 3, 1e9);
  ASSERT_FALSE(LossStart(clean, with).has_value()) << "a clean run";
  double e = 0.0;
  for (const StepDiagnostics& d : with) e = std::max(e, d.ensemble_chi2);
  EXPECT_GT(e, 2.0 * defaults.acquisition_ensemble_chi2) << "no shadow disagrees: the test shows nothing";
  EXPECT_TRUE(FlaggedIn(any_shadow, 0, any_shadow.size() - 1))
      << "without the evidence condition this clean run is no longer flagged: the test shows nothing";
  EXPECT_FALSE(FlaggedIn(with, 0, with.size() - 1));

  ParticleFilterOptions bad;
  bad.acquisition_ensemble = 0;
  EXPECT_FALSE(bad.IsValid(nullptr));
  bad.acquisition_ensemble = 3;
  bad.acquisition_ensemble_nats = -1.0;
  EXPECT_FALSE(bad.IsValid(nullptr));
  bad.acquisition_ensemble_nats = 0.0;
  bad.subclouds = 3;
  EXPECT_FALSE(bad.IsValid(nullptr)) << "shadows beside pooled sub-clouds";
  bad.subclouds = 1;
  EXPECT_TRUE(bad.IsValid(nullptr));
}

TEST(PfLostDetection, CleanRunsRaiseNoAlarm) {
  std::vector<std::pair<std::string, PathRun>> runs;
  for (const char* name : {"mappath_crustal_off0p01deg_noise0p5nT.csv", "mappath_crustal_off0p1deg_noise5nT.csv"}) {
    runs.emplace_back(name, LoadPathRun(testing::ReferencePath(name)));
  }
  for (int i : {321, 322, 323}) runs.emplace_back("generated " + std::to_string(i), Generated(i, "3", "3"));
  for (int i : {341, 342, 343}) runs.emplace_back("generated " + std::to_string(i), Generated(i, "5", "5"));
  for (const auto& [name, run] : runs) {
    const bool reference = name.rfind("generated", 0) != 0;
    for (const ParticleFilterKind kind : {ParticleFilterKind::kPf, ParticleFilterKind::kAfpf}) {
      for (std::uint64_t seed = reference ? 2 : 1; seed <= (reference ? 2u : 1u); ++seed) {
        SCOPED_TRACE(name + " " + ParticleFilterKindName(kind) + " seed " + std::to_string(seed));
        ParticleFilterOptions o;
        o.seed = seed;
        std::vector<StepDiagnostics> steps;
        const MatchResult r = MatchParticleFilter(kind, Map(), 0, run.path, o, &steps);
        if (LossStart(run, steps)) continue;  // a loss (none expected) is not a clean run
        for (std::size_t k = 0; k < steps.size(); ++k) {
          ASSERT_FALSE(steps[k].ins_glitch) << "k " << k << " ratio " << steps[k].ins_step_ratio;
          ASSERT_FALSE(steps[k].lost) << "k " << k;
        }
        EXPECT_TRUE(r.converged) << r.BriefReport();
      }
    }
  }
}

}  // namespace
}  // namespace magnav::mapmatch
