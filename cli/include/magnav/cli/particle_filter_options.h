// The particle filters' flags, shared by `magnav match --method pf|afpf` and
// `magnav-matcher` (mapmatch/particle_filter.h). Each flag's default is the
// option's documented default (--help shows it); a config file's keys are the
// flag names. Header-only: the program that includes it links
// magnav::mapmatch.
#pragma once

#include <map>
#include <string>
#include <type_traits>

#include <CLI/CLI.hpp>

#include "magnav/cli/options.h"
#include "magnav/mapmatch/particle_filter.h"

namespace magnav::cli {

inline void AddParticleFilterOptions(CLI::App& app, mapmatch::ParticleFilterOptions* f) {
  auto opt = [&](const char* name, auto* value, const char* help) {
    if constexpr (std::is_same_v<std::remove_cvref_t<decltype(*value)>, bool>) {
      AddSwitchOption(app, name, value, help)->capture_default_str();  // 0/1 only, not any integer
    } else {
      app.add_option(name, *value, help)->capture_default_str();
    }
  };
  opt("--particles", &f->num_particles, "pf: particles; afpf: the fewest it adapts down to (the paper: 3000)");
  opt("--max-particles", &f->max_particles, "afpf: particles at the start and at most (adaptive count)");
  opt("--particles-per-cell", &f->particles_per_cell,
      "afpf: adaptive count = this x map cells holding a particle (clamped to --particles..--max-particles)");
  opt("--seed", &f->seed, "pf, afpf: random seed (std::mt19937_64)");
  opt("--sigma", &f->measurement_sigma_nT,
      "afpf: likelihood sigma, nT (sensor + map + particle spacing; the paper's tau = sigma^2); pf: the same with "
      "--adaptive-sigma 0, else the largest and starting sigma");
  opt("--adaptive-sigma", &f->adaptive_sigma,
      "pf: likelihood sigma from the innovations of the last --sigma-window updates (1), in "
      "[--min-sigma, --sigma], or fixed at --sigma (0); afpf: see --afpf-sigma-factor");
  opt("--min-sigma", &f->min_measurement_sigma_nT, "pf with --adaptive-sigma 1: smallest likelihood sigma, nT");
  opt("--sigma-window", &f->sigma_window, "pf with --adaptive-sigma 1: updates in the sigma estimate");
  opt("--afpf-sigma-factor", &f->afpf_sigma_factor,
      "afpf: likelihood sigma = this x the innovations' sigma (last --sigma-window updates), in "
      "[--sigma, --afpf-max-sigma]; 0 = fixed at --sigma");
  opt("--afpf-max-sigma", &f->afpf_max_sigma_nT, "afpf: largest (and starting) adaptive likelihood sigma, nT");
  opt("--drift-sigma", &f->drift_sigma_deg,
      "pf, afpf: INS drift noise per step and axis, deg, for steps of at least --drift-step");
  opt("--min-update-spacing", &f->min_update_spacing_m,
      "pf, afpf: use a reading only once the INS has moved this far (m) since the last one used (readings a few "
      "metres apart repeat one another on a map of ~100 m cells); 0 = every reading");
  opt("--drift-step", &f->drift_step_m,
      "pf, afpf: while the INS steps are shorter than this on average (m), the drift per step is "
      "--drift-sigma x sqrt(mean step / this), a random walk in distance; 0 = --drift-sigma per step whatever its length");
  opt("--prior-half-width", &f->prior_half_width_deg,
      "pf, afpf: uniform prior square around the first INS point (clipped to the map), deg");
  opt("--resample-ess", &f->resample_ess_fraction, "pf: resample when ESS < this fraction of N");
  opt("--min-update-ess", &f->min_update_ess_fraction,
      "pf: temper a reading (likelihood^beta) that would leave fewer effective particles than this fraction of N; 0 = off");
  opt("--regularize", &f->regularization_bandwidth,
      "pf: after resampling jitter by this x N^(-1/6) x the cloud's covariance (regularised PF; 0 = off)");
  opt("--off-map-sigmas", &f->off_map_sigmas, "pf, afpf: an off-map particle's likelihood is that of this many sigma");
  opt("--max-step", &f->max_step_deg, "pf, afpf: a longer INS increment is a jump (not applied), deg");
  opt("--ins-glitch-ratio", &f->ins_glitch_ratio,
      "pf, afpf: an INS increment departing from the recent ones by more than this x their usual size is a glitch "
      "(lost for --ins-glitch-hold steps; 0 = off)");
  opt("--ins-glitch-hold", &f->ins_glitch_hold, "pf, afpf: steps lost after an INS glitch");
  opt("--divergence-window", &f->divergence_window, "pf, afpf: updates in the divergence test");
  opt("--divergence-nis", &f->divergence_nis, "pf, afpf: lost when the window's mean NIS exceeds this");
  opt("--track-check-window", &f->track_check_window,
      "pf, afpf: readings in the track check (a coarse re-search: lost when the recent readings, placed by the "
      "INS increments, fit much better shifted beyond 3 sigma of the filter); 0 = off");
  opt("--track-check-every", &f->track_check_every, "pf, afpf: run the track check every this many updates");
  opt("--track-check-chi2", &f->track_check_chi2,
      "pf, afpf: lost when the best shift lowers the track's squared residuals, against the best within 3 sigma, "
      "by more than this x max(sigma_n^2, best residual mean square)");
  opt("--track-check-step", &f->track_check_step_deg, "pf, afpf: the track check's coarse offset grid, deg");
  opt("--track-check-acquisition-only", &f->track_check_acquisition_only,
      "pf, afpf: run the track check only during acquisition (until --acquisition-steps after the cloud first "
      "settled) (1), or at every step (0)");
  opt("--bias-test-window", &f->bias_test_window,
      "pf, afpf: updates in the innovation-bias test (lost when (sum r)^2 / sum(sigma_n^2 + V) > --bias-test-chi2); "
      "0 = off");
  opt("--bias-test-chi2", &f->bias_test_chi2, "pf: the innovation-bias test's threshold (chi-square, 1 dof; 0 = off)");
  opt("--afpf-bias-test-chi2", &f->afpf_bias_test_chi2, "afpf: the innovation-bias test's threshold (0 = off)");
  opt("--acquisition-bias-test-chi2", &f->acquisition_bias_test_chi2,
      "pf: the bias test's threshold during acquisition (until --acquisition-steps after the cloud first settled); "
      "0 = off");
  opt("--afpf-acquisition-bias-test-chi2", &f->afpf_acquisition_bias_test_chi2,
      "afpf: the bias test's threshold during acquisition; 0 = off");
  opt("--acquisition-steps", &f->acquisition_steps,
      "pf, afpf: acquisition ends this many steps after the cloud's 1-sigma first fell below --settled-sigma");
  opt("--acquisition-collapse-ratio", &f->acquisition_collapse_ratio,
      "pf, afpf: the acquisition test keeps only the innovations recorded while the cloud's 1-sigma was at most this "
      "x the current one (0 = off: the last --bias-test-window updates)");
  opt("--acquisition-min-updates", &f->acquisition_min_updates,
      "pf, afpf: with --acquisition-collapse-ratio, the fewest innovations the acquisition test judges");
  opt("--innovation-cusum-window", &f->innovation_cusum_window,
      "pf, afpf: updates in the innovation CUSUM's noise reference s^2 = mean(r^2 - V)");
  opt("--innovation-cusum-delay", &f->innovation_cusum_delay,
      "pf, afpf: the reference window ends this many updates before the current one");
  opt("--innovation-cusum-drift", &f->innovation_cusum_drift,
      "pf, afpf: the CUSUM's drift: g <- max(0, g + min(r^2 / (s^2 + V), cap) - drift)");
  opt("--innovation-cusum-cap", &f->innovation_cusum_cap, "pf, afpf: one reading's largest term in the CUSUM");
  opt("--innovation-cusum-threshold", &f->innovation_cusum_threshold,
      "pf: lost while the innovation CUSUM g exceeds this (0 = off)");
  opt("--afpf-innovation-cusum-threshold", &f->afpf_innovation_cusum_threshold,
      "afpf: lost while the innovation CUSUM g exceeds this (0 = off)");
  opt("--settled-sigma", &f->settled_sigma_deg,
      "pf, afpf: after a re-initialisation stay lost until the cloud's 1-sigma spread is below this, deg; 0 = off");
  opt("--settle-updates", &f->settle_updates,
      "pf, afpf: status 'converging' (not ok) until the cloud's 1-sigma spread has stayed below --settled-sigma "
      "for this many updates in a row (from the start, after a re-initialisation or a widening); 0 = off");
  opt("--reinitialize-when-lost", &f->reinitialize_when_lost,
      "pf, afpf: spread the prior again around the INS position when lost (1) or stay lost (0)");
  opt("--lost-covariance-is-prior", &f->lost_covariance_is_prior,
      "pf, afpf: while lost publish at least the prior square's covariance (1) or the cloud's (0)");
  opt("--converging-covariance-mixture", &f->converging_covariance_mixture,
      "pf: while converging publish the covariance of the mixture of the clouds held since it started "
      "converging (offsets from the INS, about the current mean) when wider than the cloud's (1), or the cloud's (0)");
  opt("--afpf-converging-covariance-mixture", &f->afpf_converging_covariance_mixture,
      "afpf: the same (default 0: the cloud's covariance while converging)");
  opt("--offset-slide-updates", &f->offset_slide_updates,
      "pf, afpf (magnav match's summary, magnav-matcher's fixes): a run whose estimate slid against the INS over this many last "
      "updates beyond the drift model and its cloud's covariance (chi2 > --offset-slide-chi2) is not converged; 0 = off");
  opt("--offset-slide-chi2", &f->offset_slide_chi2, "pf, afpf: threshold of the offset-slide test (chi2, 2 dof)");
  opt("--subclouds", &f->subclouds,
      "pf, afpf: run K independent sub-clouds (each with --particles: K times the cost), publish the pooled cloud "
      "and flag lost when their means disagree (--subcloud-chi2); 1 = off");
  opt("--subcloud-chi2", &f->subcloud_chi2,
      "pf, afpf with --subclouds > 1: lost when two sub-cloud means differ by more than this (chi-square, 2 dof, "
      "against their summed covariances) for --subcloud-hold steps");
  opt("--subcloud-hold", &f->subcloud_hold, "pf, afpf with --subclouds > 1: steps the disagreement must last");
  opt("--acquisition-ensemble", &f->acquisition_ensemble,
      "pf, afpf: K clouds in all: run K-1 independently seeded shadow filters beside the filter while it acquires "
      "(until --acquisition-steps after its first ok step) and flag lost when a shadow's mean and the filter's "
      "disagree (--acquisition-ensemble-chi2) and the readings do not favour the filter "
      "(--acquisition-ensemble-nats); the estimate is the filter's, unchanged; 1 = off");
  opt("--acquisition-ensemble-chi2", &f->acquisition_ensemble_chi2,
      "pf, afpf with --acquisition-ensemble > 1: lost when the filter's and a shadow's means differ by more than "
      "this (chi-square, 2 dof, against their summed cloud covariances) for --acquisition-ensemble-hold steps");
  opt("--acquisition-ensemble-hold", &f->acquisition_ensemble_hold,
      "pf, afpf with --acquisition-ensemble > 1: steps the disagreement must last");
  opt("--acquisition-ensemble-window", &f->acquisition_ensemble_window,
      "pf, afpf with --acquisition-ensemble > 1: readings in each cloud's summed log evidence");
  opt("--acquisition-ensemble-nats", &f->acquisition_ensemble_nats,
      "pf, afpf with --acquisition-ensemble > 1: a disagreeing shadow counts unless its summed log evidence is "
      "below the filter's by more than this (the shadow is then the one lost)");
  opt("--acquisition-ensemble-flag", &f->acquisition_ensemble_flag,
      "pf, afpf with --acquisition-ensemble > 1: flag lost on the shadows' disagreement (1) or only run them (0: "
      "the lost flags are the filter's alone; for --acquisition-ensemble-covariance)");
  app.add_option("--acquisition-ensemble-covariance", f->acquisition_ensemble_covariance,
                 "pf, afpf with --acquisition-ensemble > 1: while the shadows run, a converging or ok step publishes "
                 "the covariance, about the filter's mean, of the mixture of its cloud and the shadows' (weights "
                 "equal, or by their summed log evidence over --acquisition-ensemble-window readings) when wider; "
                 "off = the filter's own")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, mapmatch::ParticleFilterOptions::EnsembleCovariance>{
              {"off", mapmatch::ParticleFilterOptions::EnsembleCovariance::kOff},
              {"equal", mapmatch::ParticleFilterOptions::EnsembleCovariance::kEqual},
              {"evidence", mapmatch::ParticleFilterOptions::EnsembleCovariance::kEvidence}},
          CLI::ignore_case))
      ->default_str("off");
  opt("--acquisition-ensemble-isotropic", &f->acquisition_ensemble_isotropic,
      "pf, afpf with --acquisition-ensemble-covariance: the clouds' offsets from the filter's mean spread evenly "
      "over both axes (1) or as they lie (0)");
  opt("--subcloud-window", &f->subcloud_window,
      "pf, afpf with --subclouds > 1: updates in each sub-cloud's summed log evidence (re-seeding)");
  opt("--subcloud-reseed", &f->subcloud_reseed_nats,
      "pf, afpf with --subclouds > 1: while they disagree, copy the best sub-cloud over one whose windowed log "
      "evidence is lower by more than this (nats); 0 = off");
  app.add_flag("--estimate-bias", f->estimate_bias, "pf, afpf: a map bias per particle (reading - bias vs the map)");
  opt("--bias-prior-sigma", &f->bias_prior_sigma_nT, "pf, afpf with --estimate-bias: prior sigma of the bias, nT");
  opt("--bias-drift-sigma", &f->bias_drift_sigma_nT, "pf, afpf with --estimate-bias: random walk of the bias per step, nT");
  opt("--fission-penalty", &f->fission_motion_penalty,
      "afpf: an offspring's weight pays its fission move as drift (1) or not, as the paper (0)");
  opt("--fission-lambda", &f->fission_lambda, "afpf: offspring variance scale lambda (the paper: 0.001)");
  opt("--fission-mu", &f->fission_mu_deg2, "afpf: parents' sampling variance mu, deg^2 (the paper: 1.6454e-4)");
}

// Options `magnav match` has for every method and `magnav-matcher` for its filters (one text,
// one meaning): the status review's plausible correction and the outlier gate.
inline void AddMaxCorrectionOption(CLI::App& app, double* max_correction_deg) {
  app.add_option("--max-correction", *max_correction_deg,
                 "largest correction (deg) a result may make and still be called converged (the prior on the "
                 "INS error); 0 = the method's own: 2 x --search-window, 2 x the pf/afpf prior half-width, else "
                 "the INS path's size")
      ->capture_default_str();
}

inline void AddOutlierSigmasOption(CLI::App& app, double* outlier_sigmas) {
  app.add_option("--outlier-sigmas", *outlier_sigmas,
                 "robust residuals of every method: a reading whose residual is beyond this many robust sigmas "
                 "(1.4826 MAD) is left out (counted as outliers in the summary); pf/afpf: a reading beyond this "
                 "many sigmas of the whole cloud's prediction is skipped; 0 = off")
      ->capture_default_str();
}

}  // namespace magnav::cli
