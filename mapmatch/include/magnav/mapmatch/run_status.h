// The status of a sequential matcher's run (pf, afpf), reviewed step by step: what
// `magnav match --method pf|afpf` says of a whole path at its end (MatchParticleFilter's
// "converged" / "not converged: …") and what `magnav-matcher` says at every fix — the same rules,
// in one place, so the live matcher and the offline one agree (issue 25; docs/ACCURACY.md "The
// live matcher says the same as the offline one").
//
// Fed every step of a run (the INS position given to the filter, the step's diagnostics and the
// filter's counters), it answers at any step with the status the run would have if it ended there:
//   lost          the filter's lost-track detector is raised at this step (StepDiagnostics::lost)
//   off_map       every particle off the map at this step (and the steps before it back to the
//                 last one with a particle on the map): dead-reckoning on the INS
//   sigma_capped  AFPF on dense readings (some reading spaced out by min_update_spacing_m): its
//                 likelihood σ at afpf_max_sigma_nT in half or more of the last 40 updates (the
//                 innovations beyond the largest noise it allows; "Dense readings II")
//   slid          dense readings: the estimate slid against the INS beyond the drift model and
//                 the cloud (offset_slide_updates, offset_slide_chi2; "Dense readings III")
//   unsettled     lost at a step fewer than 2 × divergence_window steps ago (a re-initialised
//                 cloud that has not had two windows to settle)
//   implausible   an estimate lies further from its INS position than the plausible correction
//                 (max_correction_deg; 0 = 2 × prior_half_width_deg, as PlausibleCorrectionDeg for
//                 pf/afpf; Match's ReviewResult makes the same check): any estimate of the run
//                 (RunStatusMemory::kWholeRun), or one of the last 2 × divergence_window steps (kRecent)
//   non_finite    an estimate is not finite: any of the run (kWholeRun) or of the last
//                 2 × divergence_window steps (kRecent)
//   converging    the filter has not settled at this step (StepDiagnostics::converging,
//                 settle_updates: its cloud still wider than settled_sigma_deg, or narrower for fewer
//                 than settle_updates updates): not "converged", and not an alarm (magnav-matcher
//                 publishes CONVERGING, not LOST)
//   converged     none of these (a run that was lost and has been quiet since says so in reason())
// Priority: non_finite, then as listed (off_map before lost only while the filter is not lost).
// Units: deg as in particle_filter.h.
#pragma once

#include <cstddef>
#include <deque>
#include <memory>
#include <string>

#include "magnav/mapmatch/particle_filter.h"

namespace magnav::mapmatch {

namespace internal {
class OffsetSlideTest;
}

// RunVerdict and RunVerdictName are in particle_filter.h (StepDiagnostics::run_status).

// How long an implausible or non-finite estimate counts against the run.
//   kWholeRun  for ever: the verdict on a finished run whose every row is written
//              (`magnav match`: one such row spoils the result file)
//   kRecent    for the last 2 × divergence_window steps, as a lost alarm does (unsettled): a live
//              matcher (magnav-matcher) runs for months; one bad estimate must not make every
//              later fix LOST until a restart
enum class RunStatusMemory { kWholeRun, kRecent };

class RunStatus {
 public:
  // max_correction_deg: the plausible correction (deg); 0 = 2 × options.prior_half_width_deg.
  RunStatus(ParticleFilterKind kind, const ParticleFilterOptions& options, double max_correction_deg = 0.0,
            RunStatusMemory memory = RunStatusMemory::kWholeRun);
  ~RunStatus();
  RunStatus(const RunStatus&) = delete;
  RunStatus& operator=(const RunStatus&) = delete;

  // One step: the INS position given to the filter (deg), the step's diagnostics, the filter's
  // counters after it, and the step's label k (the path's k; in reasons).
  void Add(double ins_lat_deg, double ins_lon_deg, const StepDiagnostics& d, const FilterCounters& counters,
           long long k);

  RunVerdict verdict() const;
  bool converged() const { return verdict() == RunVerdict::kConverged; }
  // Why not converged (or, converged after a lost episode, that it was lost and quiet since);
  // "" when converged without one. `kind`-specific wording as MatchParticleFilter's summary.
  std::string reason() const;
  // The offset-slide test's χ² now (0: off or not enough updates).
  double slide_chi2() const;

 private:
  ParticleFilterKind kind_;
  ParticleFilterOptions o_;
  double max_correction_deg_;
  std::unique_ptr<internal::OffsetSlideTest> slide_;
  static constexpr std::size_t kCapWindow = 40;
  std::deque<bool> at_cap_;
  std::size_t capped_ = 0;
  std::size_t steps_ = 0;
  long long first_lost_ = -1, last_lost_ = -1;
  std::size_t last_lost_step_ = 0, off_at_end_ = 0;
  bool lost_ = false, reacquiring_ = false, ins_glitch_ = false;
  bool converging_ = false;  // the last step's StepDiagnostics::converging
  double spread_deg_ = 0.0;  // the last step's cloud 1-σ spread (deg)
  int converging_steps_ = 0;
  int spaced_ = 0;
  RunStatusMemory memory_;
  // The largest correction (deg) and the first non-finite estimate: of the whole run (kWholeRun),
  // or of the steps since the last one (kRecent; both reset once the window has passed clean).
  double moved_deg_ = 0.0;
  long long first_non_finite_ = -1;
  std::size_t last_implausible_step_ = 0, last_non_finite_step_ = 0;
  bool any_implausible_ = false, any_non_finite_ = false;
  std::size_t settle_steps() const;
  bool non_finite_now() const;
  bool implausible_now() const;
};

}  // namespace magnav::mapmatch
