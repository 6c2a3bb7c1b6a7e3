#include "magnav/mapmatch/particle_filter.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <numbers>
#include <numeric>
#include <utility>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/option_check.h"
#include "magnav/mapmatch/fix_schedule.h"
#include "particle_filter_impl.h"

namespace magnav::mapmatch {

const char* ParticleFilterKindName(ParticleFilterKind kind) {
  return kind == ParticleFilterKind::kPf ? "pf" : "afpf";
}

double DriftSigmaPerStep(const ParticleFilterOptions& o, double mean_step_m) {
  if (!(o.drift_step_m > 0.0) || !(mean_step_m >= 0.0) || mean_step_m >= o.drift_step_m) return o.drift_sigma_deg;
  return o.drift_sigma_deg * std::sqrt(std::max(mean_step_m, 1.0) / o.drift_step_m);
}

bool ParticleFilterOptions::IsValid(std::string* error) const {
  if (num_particles < 1) return Fail(error, "num_particles must be >= 1");
  if (!PositiveFinite(measurement_sigma_nT)) return Fail(error, "measurement_sigma_nT must be finite and > 0");
  if (!(std::isfinite(drift_sigma_deg) && drift_sigma_deg >= 0.0)) {
    return Fail(error, "drift_sigma_deg must be finite and >= 0");
  }
  if (!(std::isfinite(drift_step_m) && drift_step_m >= 0.0)) return Fail(error, "drift_step_m must be finite and >= 0");
  if (!(std::isfinite(min_update_spacing_m) && min_update_spacing_m >= 0.0)) {
    return Fail(error, "min_update_spacing_m must be finite and >= 0");
  }
  if (!PositiveFinite(prior_half_width_deg)) return Fail(error, "prior_half_width_deg must be finite and > 0");
  if (!(resample_ess_fraction >= 0.0 && resample_ess_fraction <= 1.0)) {
    return Fail(error, "resample_ess_fraction must be in [0, 1]");
  }
  if (!(outlier_sigmas == 0.0 || (std::isfinite(outlier_sigmas) && outlier_sigmas >= 2.0))) {
    return Fail(error, "outlier_sigmas must be 0 (off) or finite and >= 2");
  }
  if (max_consecutive_outliers < 0) return Fail(error, "max_consecutive_outliers must be >= 0");
  if (!(std::isfinite(off_map_sigmas) && off_map_sigmas >= 0.0)) {
    return Fail(error, "off_map_sigmas must be finite and >= 0");
  }
  if (!PositiveFinite(max_step_deg)) return Fail(error, "max_step_deg must be finite and > 0");
  if (!(std::isfinite(acquisition_bias_test_chi2) && acquisition_bias_test_chi2 >= 0.0 &&
        std::isfinite(afpf_acquisition_bias_test_chi2) && afpf_acquisition_bias_test_chi2 >= 0.0) ||
      acquisition_steps < 0) {
    return Fail(error, "acquisition_bias_test_chi2 and afpf_acquisition_bias_test_chi2 must be finite and >= 0 "
                       "(0 = off) and acquisition_steps >= 0");
  }
  if (!(std::isfinite(acquisition_collapse_ratio) &&
        (acquisition_collapse_ratio == 0.0 || acquisition_collapse_ratio >= 1.0)) ||
      acquisition_min_updates < 1 || (bias_test_window > 0 && acquisition_min_updates > bias_test_window)) {
    return Fail(error, "acquisition_collapse_ratio must be 0 (off) or finite and >= 1, and acquisition_min_updates "
                       "in [1, bias_test_window]");
  }
  if (!(std::isfinite(ins_glitch_ratio) && ins_glitch_ratio >= 0.0) || ins_glitch_hold < 1) {
    return Fail(error, "ins_glitch_ratio must be finite and >= 0 (0 = off) and ins_glitch_hold >= 1");
  }
  if (divergence_window < 1) return Fail(error, "divergence_window must be >= 1");
  if (track_check_window < 0) return Fail(error, "track_check_window must be >= 0 (0 = off)");
  if (track_check_every < 1) return Fail(error, "track_check_every must be >= 1");
  if (!PositiveFinite(track_check_chi2)) return Fail(error, "track_check_chi2 must be finite and > 0");
  if (!PositiveFinite(track_check_step_deg)) return Fail(error, "track_check_step_deg must be finite and > 0");
  if (!PositiveFinite(divergence_nis)) return Fail(error, "divergence_nis must be finite and > 0");
  if (bias_test_window < 0) return Fail(error, "bias_test_window must be >= 0 (0 = off)");
  if (!(std::isfinite(bias_test_chi2) && bias_test_chi2 >= 0.0)) {
    return Fail(error, "bias_test_chi2 must be finite and >= 0 (0 = off)");
  }
  if (!(std::isfinite(afpf_bias_test_chi2) && afpf_bias_test_chi2 >= 0.0)) {
    return Fail(error, "afpf_bias_test_chi2 must be finite and >= 0 (0 = off)");
  }
  if (!(std::isfinite(settled_sigma_deg) && settled_sigma_deg >= 0.0)) {
    return Fail(error, "settled_sigma_deg must be finite and >= 0 (0 = off)");
  }
  if (settle_updates < 0) return Fail(error, "settle_updates must be >= 0 (0 = no converging status)");
  if (!(std::isfinite(min_measurement_sigma_nT) && min_measurement_sigma_nT > 0.0 &&
        min_measurement_sigma_nT <= measurement_sigma_nT)) {
    return Fail(error, "min_measurement_sigma_nT must be finite, > 0 and <= measurement_sigma_nT");
  }
  if (sigma_window < 1) return Fail(error, "sigma_window must be >= 1");
  if (!(std::isfinite(afpf_sigma_factor) && afpf_sigma_factor >= 0.0)) {
    return Fail(error, "afpf_sigma_factor must be finite and >= 0 (0 = a fixed sigma)");
  }
  if (!(std::isfinite(afpf_max_sigma_nT) && afpf_max_sigma_nT >= measurement_sigma_nT)) {
    return Fail(error, "afpf_max_sigma_nT must be finite and >= measurement_sigma_nT");
  }
  if (!(min_update_ess_fraction >= 0.0 && min_update_ess_fraction <= 1.0)) {
    return Fail(error, "min_update_ess_fraction must be in [0, 1]");
  }
  if (!(std::isfinite(regularization_bandwidth) && regularization_bandwidth >= 0.0)) {
    return Fail(error, "regularization_bandwidth must be finite and >= 0");
  }
  if (!PositiveFinite(fission_lambda)) return Fail(error, "fission_lambda must be finite and > 0");
  if (!PositiveFinite(fission_mu_deg2)) return Fail(error, "fission_mu_deg2 must be finite and > 0");
  if (max_particles < num_particles) return Fail(error, "max_particles must be >= num_particles");
  if (!PositiveFinite(particles_per_cell)) return Fail(error, "particles_per_cell must be finite and > 0");
  if (!(std::isfinite(bias_prior_sigma_nT) && bias_prior_sigma_nT >= 0.0)) {
    return Fail(error, "bias_prior_sigma_nT must be finite and >= 0");
  }
  if (!(std::isfinite(bias_drift_sigma_nT) && bias_drift_sigma_nT >= 0.0)) {
    return Fail(error, "bias_drift_sigma_nT must be finite and >= 0");
  }
  if (innovation_cusum_window < 1 || innovation_cusum_delay < 0) {
    return Fail(error, "innovation_cusum_window must be >= 1 and innovation_cusum_delay >= 0");
  }
  if (!PositiveFinite(innovation_cusum_drift)) return Fail(error, "innovation_cusum_drift must be finite and > 0");
  if (!PositiveFinite(innovation_cusum_cap)) return Fail(error, "innovation_cusum_cap must be finite and > 0");
  if (!(std::isfinite(innovation_cusum_threshold) && innovation_cusum_threshold >= 0.0 &&
        std::isfinite(afpf_innovation_cusum_threshold) && afpf_innovation_cusum_threshold >= 0.0)) {
    return Fail(error, "innovation_cusum_threshold and afpf_innovation_cusum_threshold must be finite and >= 0 (0 = off)");
  }
  if (offset_slide_updates < 0 || !PositiveFinite(offset_slide_chi2)) {
    return Fail(error, "offset_slide_updates must be >= 0 (0 = off) and offset_slide_chi2 finite and > 0");
  }
  if (subclouds < 1 || subclouds > 64) return Fail(error, "subclouds must be in [1, 64] (1 = off)");
  if (!PositiveFinite(subcloud_chi2)) return Fail(error, "subcloud_chi2 must be finite and > 0");
  if (subcloud_hold < 1) return Fail(error, "subcloud_hold must be >= 1");
  if (subcloud_window < 1) return Fail(error, "subcloud_window must be >= 1");
  if (!(std::isfinite(subcloud_reseed_nats) && subcloud_reseed_nats >= 0.0)) {
    return Fail(error, "subcloud_reseed_nats must be finite and >= 0 (0 = off)");
  }
  if (acquisition_ensemble < 1 || acquisition_ensemble > 8) {
    return Fail(error, "acquisition_ensemble must be in [1, 8] (1 = off)");
  }
  if (!PositiveFinite(acquisition_ensemble_chi2)) return Fail(error, "acquisition_ensemble_chi2 must be finite and > 0");
  if (acquisition_ensemble_hold < 1 || acquisition_ensemble_window < 1) {
    return Fail(error, "acquisition_ensemble_hold and acquisition_ensemble_window must be >= 1");
  }
  if (!(std::isfinite(acquisition_ensemble_nats) && acquisition_ensemble_nats >= 0.0)) {
    return Fail(error, "acquisition_ensemble_nats must be finite and >= 0");
  }
  if (acquisition_ensemble_covariance != EnsembleCovariance::kOff &&
      acquisition_ensemble_covariance != EnsembleCovariance::kEqual &&
      acquisition_ensemble_covariance != EnsembleCovariance::kEvidence) {
    return Fail(error, "acquisition_ensemble_covariance must be off, equal or evidence");
  }
  if (acquisition_ensemble_covariance != EnsembleCovariance::kOff && acquisition_ensemble < 2) {
    return Fail(error, "acquisition_ensemble_covariance needs acquisition_ensemble > 1 (the shadows)");
  }
  if (acquisition_ensemble_isotropic && acquisition_ensemble_covariance == EnsembleCovariance::kOff) {
    return Fail(error, "acquisition_ensemble_isotropic needs acquisition_ensemble_covariance (equal or evidence)");
  }
  if (acquisition_ensemble > 1 && subclouds > 1) {
    return Fail(error, "acquisition_ensemble > 1 and subclouds > 1 cannot be combined");
  }
  return true;
}

namespace internal {

const StepDiagnostics& Filter::Step(double ins_lat, double ins_lon, double measured_nT) {
  StepDiagnostics d;
  ++counters_.steps;
  if (!initialised_) {
    if (!std::isfinite(ins_lat) || !std::isfinite(ins_lon)) {
      throw InputError(std::string(Name()) + ": the first INS position is not finite");
    }
    SpreadPrior(ins_lat, ins_lon);
    prev_lat_ = ins_lat;
    prev_lon_ = ins_lon;
    initialised_ = true;
    Update(measured_nT, &d);
  } else {
    const double from_lat = prev_lat_, from_lon = prev_lon_;  // the last finite INS position
    d.ins_jump = Predict(ins_lat, ins_lon);
    if (!d.ins_jump) {
      CheckInsGlitch((ins_lat - from_lat) * MetresPerDegreeLat(ins_lat),
                     (ins_lon - from_lon) * MetresPerDegreeLon(ins_lat), &d);
    }
    if (o_.min_update_spacing_m > 0.0 && std::isfinite(measured_nT) && std::isfinite(ins_lat) &&
        std::isfinite(ins_lon) &&
        std::hypot((ins_lat - update_lat_) * MetresPerDegreeLat(ins_lat),
                   (ins_lon - update_lon_) * MetresPerDegreeLon(ins_lat)) < o_.min_update_spacing_m) {
      SkipUpdate(StepUpdate::kSpaced, &d);
      ++counters_.spaced;
    } else {
      Update(measured_nT, &d);
    }
  }
  d.innovation_cusum = cusum_g_;  // held over steps without an update
  Estimate(&d);
  // (track_check_acquisition_only: only in the acquisition phase, as CheckAcquisitionBias's)
  if (o_.track_check_window > 0 && (!o_.track_check_acquisition_only || settled_at_ < 0 ||
                                    counters_.steps - 1 < settled_at_ + o_.acquisition_steps)) {
    CheckTrack(ins_lat, ins_lon, measured_nT, &d);
  }
  if (kind_ == ParticleFilterKind::kAfpf) AdaptCount(d);
  d.particles = static_cast<int>(p_.size());
  d.unique_particles = std::min(d.unique_particles, d.particles);  // after the AFPF's trim
  if (bias_failed_) ++counters_.bias_test_failures;
  if (CusumThreshold() > 0.0 && cusum_g_ > CusumThreshold()) ++counters_.innovation_cusum_alarms;
  CheckAcquisitionBias(&d);
  // The acquisition phase ends acquisition_steps after the cloud first settled (acquisition_bias_test_chi2).
  if (settled_at_ < 0 && std::sqrt(d.cov_lat_lat + d.cov_lon_lon) < o_.settled_sigma_deg) {
    settled_at_ = counters_.steps - 1;
  }
  // A re-initialised cloud stays lost until it has settled (settled_sigma_deg), at most
  // 2 divergence windows.
  if (reacquiring_ && (std::sqrt(d.cov_lat_lat + d.cov_lon_lon) < o_.settled_sigma_deg ||
                       ++reacquiring_steps_ > 2 * o_.divergence_window)) {
    reacquiring_ = false;
  }
  // The bias test and the track check flag but do not re-spread the cloud (see the header).
  const bool respread = d.lost && Diverged();
  if (!d.lost && reacquiring_) d.lost = d.reacquiring = true;
  // The converging status (settle_updates): the cloud's spread (d.cov_* before PublishCovariance).
  const double spread = std::sqrt(d.cov_lat_lat + d.cov_lon_lon);
  if (!(spread < o_.settled_sigma_deg)) {
    settle_count_ = 0;
  } else if (d.update == StepUpdate::kUpdated && settle_count_ < o_.settle_updates) {
    ++settle_count_;
  }
  if (d.lost) {
    ++counters_.lost_steps;
    if (respread && o_.reinitialize_when_lost && std::isfinite(ins_lat) && std::isfinite(ins_lon)) {
      SpreadPrior(ins_lat, ins_lon);
      nis_window_.clear();
      bias_window_.clear();
      acq_window_.clear();
      cusum_hist_.clear();
      cusum_g_ = 0.0;
      innov_.clear();
      track_.clear();
      track_lost_ = false;
      sigma_ = 0.0;  // starts again at measurement_sigma_nT
      ++counters_.reinitialisations;
      reacquiring_ = o_.settled_sigma_deg > 0.0;
      reacquiring_steps_ = 0;
      settle_count_ = 0;
      converging_cov_.Clear();
    }
  }
  d.converging = !d.lost && o_.settle_updates > 0 && o_.settled_sigma_deg > 0.0 && settle_count_ < o_.settle_updates;
  if (d.converging) ++counters_.converging_steps;
  PublishCovariance(&d);
  converging_cov_.Publish(ins_lat, ins_lon, &d);
  last_ = d;
  return last_;
}

void Filter::SpreadPrior(double lat, double lon) {
  const double h = o_.prior_half_width_deg;
  const double lat0 = std::max(lat - h, grid_.lat().first_deg), lat1 = std::min(lat + h, grid_.lat().last_deg());
  const double lon0 = std::max(lon - h, grid_.lon().first_deg), lon1 = std::min(lon + h, grid_.lon().last_deg());
  if (!(lat0 < lat1 && lon0 < lon1)) {
    throw InputError(std::string(Name()) + ": the prior square (±" + FormatNumber(h) + " deg around " +
                     FormatNumber(lat) + ", " + FormatNumber(lon) + ") does not overlap the map");
  }
  const int n = kind_ == ParticleFilterKind::kAfpf ? o_.max_particles : o_.num_particles;
  std::uniform_real_distribution<double> ulat(lat0, lat1), ulon(lon0, lon1);
  p_.assign(static_cast<std::size_t>(n), Particle{});
  logw_.assign(p_.size(), 0.0);
  for (Particle& q : p_) {
    q.lat_deg = ulat(rng_);
    q.lon_deg = ulon(rng_);
    q.weight = 1.0 / n;
  }
  if (o_.estimate_bias) {  // the bias prior N(0, bias_prior_sigma²), the same for every particle
    for (Particle& q : p_) q.bias_var_nT2 = o_.bias_prior_sigma_nT * o_.bias_prior_sigma_nT;
  }
}

// Moves every particle by the INS increment plus drift noise; true if the
// increment was a jump (not applied).
bool Filter::Predict(double lat, double lon) {
  double dlat = lat - prev_lat_, dlon = lon - prev_lon_;
  bool jump = false;
  if (!std::isfinite(lat) || !std::isfinite(lon)) {
    jump = true;  // the last finite INS position stays the reference
  } else {
    jump = std::hypot(dlat, dlon) > o_.max_step_deg;
    prev_lat_ = lat;
    prev_lon_ = lon;
  }
  if (jump) {
    dlat = dlon = 0.0;
    ++counters_.ins_jumps;
  } else {  // the INS step's length (m): its running mean gives the drift per step
    const double step_m = std::hypot(dlat * MetresPerDegreeLat(prev_lat_), dlon * MetresPerDegreeLon(prev_lat_));
    mean_step_m_ = mean_step_m_ < 0.0 ? step_m : mean_step_m_ + kStepMeanGain * (step_m - mean_step_m_);
  }
  drift_sd_deg_ = DriftSigmaPerStep(o_, mean_step_m_);
  std::normal_distribution<double> n(0.0, drift_sd_deg_);
  for (Particle& q : p_) {
    q.lat_deg += dlat + n(rng_);
    q.lon_deg += dlon + n(rng_);
  }
  if (o_.estimate_bias) {  // the bias's random walk, in its variance (no draws: it is marginalised)
    for (Particle& q : p_) q.bias_var_nT2 += o_.bias_drift_sigma_nT * o_.bias_drift_sigma_nT;
  }
  return jump;
}

void Filter::Normalise() {
  const double mx = *std::max_element(logw_.begin(), logw_.end());
  double sum = 0.0;
  for (std::size_t i = 0; i < p_.size(); ++i) {
    logw_[i] -= mx;
    p_[i].weight = std::exp(logw_[i]);
    sum += p_[i].weight;
  }
  const double lsum = std::log(sum);
  for (std::size_t i = 0; i < p_.size(); ++i) {
    p_[i].weight /= sum;
    logw_[i] -= lsum;
  }
}

// A step without a reading: the weights as they are.
void Filter::SkipUpdate(StepUpdate why, StepDiagnostics* d) {
  bias_failed_ = false;
  unique_ = static_cast<int>(p_.size());
  d->update = why;
  d->ess = Ess();
  d->lost = Lost();
}

void Filter::Update(double z, StepDiagnostics* d) {
  bias_failed_ = false;
  unique_ = static_cast<int>(p_.size());
  if (!std::isfinite(z)) {
    SkipUpdate(StepUpdate::kBadMeasurement, d);
    ++counters_.bad_measurements;
    return;
  }
  update_lat_ = prev_lat_, update_lon_ = prev_lon_;  // the next reading used is this far away (min_update_spacing_m)
  const std::size_t n = p_.size();
  loglik_.resize(n);
  bool any_on = false;
  double evidence = 0.0;  // Σ w_(k−1) p(z|x)
  // σ rises at once (the safe side) but falls by at most a factor
  // (1 − 1/sigma_window) per update: the cloud's spread V lags σ, and a
  // sudden small σ collapses a cloud that has not yet tightened.
  const double prev_sigma = sigma_ > 0.0                                       ? sigma_
                            : kind_ == ParticleFilterKind::kAfpf && adaptive_ ? o_.afpf_max_sigma_nT
                                                                              : o_.measurement_sigma_nT;
  sigma_ = std::max(CurrentSigma(), prev_sigma * (1.0 - 1.0 / o_.sigma_window));
  inv_two_var_ = 1.0 / (2.0 * sigma_ * sigma_);
  d->sigma_nT = sigma_;
  // Predicted residual moments over the particles on the map; pb: their mean bias variance
  // (estimate_bias: the predicted spread of z − noise is that of m(x) + b, plus P).
  double w_on = 0.0, r1 = 0.0, r2 = 0.0, pb = 0.0;
  if (o_.estimate_bias) resid_.assign(n, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < n; ++i) {
    bool on = false;
    double r = 0.0;
    loglik_[i] = LogLik(p_[i].lat_deg, p_[i].lon_deg, z - p_[i].bias_nT, p_[i].bias_var_nT2, &on, &r);
    any_on = any_on || on;
    evidence += p_[i].weight * std::exp(loglik_[i]);
    if (on) {
      w_on += p_[i].weight, r1 += p_[i].weight * r, r2 += p_[i].weight * r * r;
      pb += p_[i].weight * p_[i].bias_var_nT2;
      if (o_.estimate_bias) resid_[i] = r;
    }
  }
  if (w_on > 0.5) {  // the predictive moments (lost-track detection and diagnostics)
    const double mean = r1 / w_on;
    d->innovation_nT = mean;
    d->predicted_spread_nT = std::sqrt(std::max(r2 / w_on - mean * mean, 0.0) + pb / w_on);
    RecordInnovation(mean, d->predicted_spread_nT * d->predicted_spread_nT, d);
    RecordCusum(mean, d->predicted_spread_nT * d->predicted_spread_nT, d);
  }
  // The outlier gate (see outlier_sigmas): a reading no particle's prediction explains is skipped.
  if (o_.outlier_sigmas > 0.0 && w_on > 0.5 && consecutive_outliers_ < o_.max_consecutive_outliers) {
    const double mean = r1 / w_on, spread = std::max(r2 / w_on - mean * mean, 0.0) + pb / w_on;
    if (mean * mean > o_.outlier_sigmas * o_.outlier_sigmas * (sigma_ * sigma_ + spread)) {
      d->update = StepUpdate::kOutlier;
      ++counters_.outliers;
      ++consecutive_outliers_;
      // The divergence rule still hears of it, as a residual of outlier_sigmas: one spike
      // cannot make the filter lost (25 against a mean of 9 over 10 updates), a run of
      // "outliers" (a lost filter, not a spike) does within 4 steps.
      d->nis = evidence > 0.0 ? -2.0 * std::log(evidence) : std::numeric_limits<double>::infinity();
      nis_window_.push_back(std::min(d->nis, o_.outlier_sigmas * o_.outlier_sigmas));
      if (static_cast<int>(nis_window_.size()) > o_.divergence_window) nis_window_.pop_front();
      d->ess = Ess();
      d->lost = Lost();
      return;
    }
  }
  consecutive_outliers_ = 0;
  if (adaptive_ && w_on > 0.5) {
    // (mean residual)² and the cloud's spread of predicted map values:
    // E[(z − m̄)²] = σ² + Var(m) for a consistent filter (+ the bias's variance P with estimate_bias:
    // the innovations are those after removing each particle's bias estimate).
    const double mean = r1 / w_on, spread = std::max(r2 / w_on - mean * mean, 0.0) + pb / w_on;
    // (the AFPF: compact against its largest σ, since its own σ starts there)
    const double compact = kind_ == ParticleFilterKind::kAfpf ? o_.afpf_max_sigma_nT : o_.measurement_sigma_nT;
    if (spread <= compact * compact) {
      innov_.emplace_back(mean * mean, spread);
      if (static_cast<int>(innov_.size()) > o_.sigma_window) innov_.pop_front();
    } else {
      innov_.clear();  // a spread (acquiring, multimodal) cloud: its mean residual says nothing of σ
    }
  }
  if (!any_on) {
    d->update = StepUpdate::kAllOffMap;
    ++counters_.all_off_map;
    d->ess = Ess();
    d->lost = Lost();
    return;
  }
  ++counters_.updates;
  d->nis = evidence > 0.0 ? -2.0 * std::log(evidence) : std::numeric_limits<double>::infinity();
  nis_window_.push_back(d->nis);
  if (static_cast<int>(nis_window_.size()) > o_.divergence_window) nis_window_.pop_front();
  const double beta = kind_ == ParticleFilterKind::kPf ? PfTemperedExponent() : 1.0;
  d->likelihood_exponent = beta;
  for (std::size_t i = 0; i < n; ++i) logw_[i] += beta * loglik_[i];
  Normalise();
  d->ess = Ess();
  if (kind_ == ParticleFilterKind::kPf) {
    if (o_.estimate_bias && beta > 0.0) {  // each particle's bias posterior (the AFPF's: in Fission)
      for (std::size_t i = 0; i < n; ++i) {
        if (std::isfinite(resid_[i])) UpdateBias(&p_[i], resid_[i], sigma_ * sigma_ / beta);
      }
    }
    PfResample(d);
  } else {
    Fission(z);
  }
  d->lost = Lost();
}

}  // namespace internal

std::unique_ptr<SequentialMatcher> MakeParticleFilter(ParticleFilterKind kind, const GeoGrid& grid,
                                                      std::size_t layer, const ParticleFilterOptions& options) {
  if (options.subclouds > 1) return internal::MakeSubClouds(kind, grid, layer, options);
  if (options.acquisition_ensemble > 1) return internal::MakeAcquisitionEnsemble(kind, grid, layer, options);
  return std::make_unique<internal::Filter>(kind, grid, layer, options);
}

}  // namespace magnav::mapmatch
