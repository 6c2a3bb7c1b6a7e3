// The status of a sequential matcher's run, step by step (run_status.h): the rules that were
// MatchParticleFilter's, now shared with magnav-matcher.
#include "magnav/mapmatch/run_status.h"

#include <cmath>

#include "magnav/core/csv.h"
#include "particle_filter_slide.h"

namespace magnav::mapmatch {

const char* RunVerdictName(RunVerdict v) {
  switch (v) {
    case RunVerdict::kConverged:
      return "converged";
    case RunVerdict::kLost:
      return "lost";
    case RunVerdict::kOffMap:
      return "off_map";
    case RunVerdict::kSigmaCapped:
      return "sigma_capped";
    case RunVerdict::kSlid:
      return "slid";
    case RunVerdict::kUnsettled:
      return "unsettled";
    case RunVerdict::kImplausible:
      return "implausible";
    case RunVerdict::kNonFinite:
      return "non_finite";
    case RunVerdict::kConverging:
      return "converging";
  }
  return "?";
}

RunStatus::RunStatus(ParticleFilterKind kind, const ParticleFilterOptions& options, double max_correction_deg,
                     RunStatusMemory memory)
    : kind_(kind),
      o_(options),
      max_correction_deg_(max_correction_deg > 0.0 ? max_correction_deg : 2.0 * options.prior_half_width_deg),
      slide_(std::make_unique<internal::OffsetSlideTest>(options)),
      memory_(memory) {}

RunStatus::~RunStatus() = default;

void RunStatus::Add(double ins_lat, double ins_lon, const StepDiagnostics& d, const FilterCounters& c, long long k) {
  const std::size_t p = steps_++;
  if (d.lost && first_lost_ < 0) first_lost_ = k;
  if (d.lost) last_lost_ = k, last_lost_step_ = p;
  lost_ = d.lost;
  reacquiring_ = d.reacquiring;
  ins_glitch_ = d.ins_glitch;
  converging_ = d.converging;
  spread_deg_ = std::sqrt(d.cloud_cov_lat_lat + d.cloud_cov_lon_lon);
  converging_steps_ = c.converging_steps;
  off_at_end_ = d.update == StepUpdate::kAllOffMap ? off_at_end_ + 1 : 0;
  if (d.update == StepUpdate::kUpdated && d.sigma_nT > 0.0) {
    const bool cap = d.sigma_nT >= o_.afpf_max_sigma_nT;
    at_cap_.push_back(cap);
    capped_ += cap;
    if (at_cap_.size() > kCapWindow) {
      capped_ -= at_cap_.front();
      at_cap_.pop_front();
    }
  }
  slide_->Add(ins_lat, ins_lon, d, c.reinitialisations);
  spaced_ = c.spaced;
  // kRecent: an episode that has passed its window clean is forgotten before this step counts.
  if (memory_ == RunStatusMemory::kRecent) {
    if (any_non_finite_ && !non_finite_now()) any_non_finite_ = false, first_non_finite_ = -1;
    if (any_implausible_ && !implausible_now()) any_implausible_ = false, moved_deg_ = 0.0;
  }
  if (!std::isfinite(d.lat_deg) || !std::isfinite(d.lon_deg)) {
    if (first_non_finite_ < 0) first_non_finite_ = k;
    any_non_finite_ = true;
    last_non_finite_step_ = p;
  } else {
    const double moved = std::hypot(d.lat_deg - ins_lat, d.lon_deg - ins_lon);
    if (moved > moved_deg_) moved_deg_ = moved;  // NaN (an INS jump to NaN) never counts
    if (max_correction_deg_ > 0.0 && moved > max_correction_deg_) {
      any_implausible_ = true;
      last_implausible_step_ = p;
    }
  }
}

std::size_t RunStatus::settle_steps() const { return 2 * static_cast<std::size_t>(o_.divergence_window); }

bool RunStatus::non_finite_now() const {
  if (!any_non_finite_) return false;
  return memory_ == RunStatusMemory::kWholeRun || steps_ - 1 - last_non_finite_step_ < settle_steps();
}

bool RunStatus::implausible_now() const {
  if (!any_implausible_) return false;
  return memory_ == RunStatusMemory::kWholeRun || steps_ - 1 - last_implausible_step_ < settle_steps();
}

double RunStatus::slide_chi2() const { return slide_->Chi2(); }

RunVerdict RunStatus::verdict() const {
  if (non_finite_now()) return RunVerdict::kNonFinite;
  const std::size_t settle = settle_steps();
  const bool unsettled = last_lost_ >= 0 && steps_ - 1 - last_lost_step_ < settle;
  // AFPF on dense readings (some readings spaced out, min_update_spacing_m): its σ is 3× the
  // innovations' σ, capped at afpf_max_sigma_nT; at the cap in at least half of the last 40 updates,
  // the innovations exceed the largest noise the filter allows — a map mismatch the NIS rules do not
  // see, since they divide by that σ. Measured (docs/ACCURACY.md, "Dense readings II"): 4 of the 5
  // AFPF runs > 1 km off on the dense tuning and fresh paths, 0 of the 23 on the track. Only where
  // readings are spaced out: the reference and held-out paths (no spaced reading) keep their status.
  const bool sigma_capped = kind_ == ParticleFilterKind::kAfpf && o_.afpf_sigma_factor > 0.0 && spaced_ > 0 &&
                            at_cap_.size() == kCapWindow && 2 * capped_ >= kCapWindow;
  // The estimate slid against the INS beyond the drift model and its cloud (offset_slide_*); on
  // dense readings only, like the cap rule: the reference and held-out paths keep their status.
  const bool slid = spaced_ > 0 && slide_->Chi2() > o_.offset_slide_chi2;
  if (off_at_end_ > 0 && !lost_) return RunVerdict::kOffMap;
  if (lost_) return RunVerdict::kLost;
  if (sigma_capped) return RunVerdict::kSigmaCapped;
  if (slid) return RunVerdict::kSlid;
  if (unsettled) return RunVerdict::kUnsettled;
  if (implausible_now()) return RunVerdict::kImplausible;
  // A filter converging at this step (settle_updates) has not settled: never "converged".
  if (converging_) return RunVerdict::kConverging;
  return RunVerdict::kConverged;
}

std::string RunStatus::reason() const {
  const ParticleFilterOptions& options = o_;
  const ParticleFilterKind kind = kind_;
  const std::size_t settle = 2 * static_cast<std::size_t>(options.divergence_window);
  switch (verdict()) {
    case RunVerdict::kNonFinite:
      return "non-finite position in the result (k = " + std::to_string(first_non_finite_) + ")" +
             (memory_ == RunStatusMemory::kRecent
                  ? " within the last " + std::to_string(settle_steps()) + " steps"
                  : std::string());
    case RunVerdict::kOffMap:
      return "off the map at the end: every particle off the map for the last " + std::to_string(off_at_end_) +
             " step(s)" + " (dead-reckoning on the INS)" +
             (first_lost_ >= 0 ? "; lost at k = " + std::to_string(last_lost_) : "");
    case RunVerdict::kLost:
      if (ins_glitch_) {
        return "lost: an INS glitch (an increment more than " + FormatNumber(options.ins_glitch_ratio) +
               "x the usual) within the last " + std::to_string(options.ins_glitch_hold) + " steps";
      }
      return reacquiring_
                 ? std::string("lost: re-initialised, the cloud not settled by the end")
                 : "lost (mean NIS over the last " + std::to_string(options.divergence_window) + " updates > " +
                       FormatNumber(options.divergence_nis) +
                       (options.bias_test_window > 0 &&
                                (kind == ParticleFilterKind::kAfpf ? options.afpf_bias_test_chi2
                                                                   : options.bias_test_chi2) > 0.0
                            ? ", or the innovation-bias test"
                        : options.bias_test_window > 0 &&
                                (kind == ParticleFilterKind::kAfpf ? options.afpf_acquisition_bias_test_chi2
                                                                   : options.acquisition_bias_test_chi2) > 0.0
                            ? ", or the innovation-bias test during acquisition"
                            : "") +
                       ((kind == ParticleFilterKind::kAfpf ? options.afpf_innovation_cusum_threshold
                                                           : options.innovation_cusum_threshold) > 0.0
                            ? ", or the innovation CUSUM"
                            : "") +
                       (options.track_check_window > 0 ? ", or the track check" : "") +
                       (options.subclouds > 1 ? ", or the sub-clouds disagree" : "") + ")";
    case RunVerdict::kSigmaCapped:
      return "innovations beyond the likelihood's cap: sigma at afpf_max_sigma_nT (" +
             FormatNumber(options.afpf_max_sigma_nT) + " nT) in " + std::to_string(capped_) + " of the last " +
             std::to_string(kCapWindow) + " updates (a map mismatch: a wrong place or a sensor noisier than the cap)";
    case RunVerdict::kSlid:
      return "the estimate slid " + FormatNumber(std::round(slide_->SlideMetres())) +
             " m against the INS over the last " + std::to_string(options.offset_slide_updates) + " updates (chi2 " +
             FormatNumber(std::round(slide_->Chi2() * 10.0) / 10.0) + " > " + FormatNumber(options.offset_slide_chi2) +
             " of the drift model and the cloud's covariance: a filter following a wrong place)";
    case RunVerdict::kUnsettled:
      return "lost at k = " + std::to_string(last_lost_) + (options.reinitialize_when_lost ? ", re-initialised" : "") +
             ", not settled by the end (fewer than " + std::to_string(settle) + " steps since)";
    case RunVerdict::kImplausible:
      return "implausible: moved a point " + FormatNumber(moved_deg_) + " deg, beyond the plausible correction of " +
             FormatNumber(max_correction_deg_) + " deg (max_correction_deg, --max-correction)" +
             (memory_ == RunStatusMemory::kRecent
                  ? " within the last " + std::to_string(settle_steps()) + " steps"
                  : std::string());
    case RunVerdict::kConverging:
      return "converging at the end: the cloud's 1-sigma spread " +
             FormatNumber(std::round(spread_deg_ * 1e5) / 1e5) + " deg, settled below " +
             FormatNumber(options.settled_sigma_deg) + " deg for fewer than " + std::to_string(options.settle_updates) +
             " updates (" + std::to_string(converging_steps_) + " converging steps in the run)";
    case RunVerdict::kConverged:
      if (first_lost_ >= 0) {
        return "lost from k = " + std::to_string(first_lost_) + ", last at k = " + std::to_string(last_lost_) +
               "; no lost-track alarm in the " + std::to_string(steps_ - 1 - last_lost_step_) +
               " steps since (not a proof of being on the track)";
      }
      return "";
  }
  return "";
}

}  // namespace magnav::mapmatch
