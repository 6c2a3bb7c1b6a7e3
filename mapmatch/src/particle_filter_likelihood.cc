// The particle filters' measurement model: log-likelihood and the likelihood σ
// (particle_filter_impl.h says which file holds what).
#include "particle_filter_impl.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace magnav::mapmatch::internal {

// Log-likelihood of a measurement at a point (the off-map floor outside).
// With estimate_bias, `z` is the reading less the particle's bias estimate and
// `bias_var` that estimate's variance P (nT²): the bias marginalised, the
// residual is N(0, σ² + P); the log of (σ² + P)/σ² keeps particles with
// different P comparable (0 when P = 0, the likelihood without the bias).
double Filter::LogLik(double lat, double lon, double z, double bias_var, bool* on_map, double* residual) const {
  const auto s = grid_.Sample(layer_, lat, lon);
  *on_map = s.has_value();
  if (!s) return off_map_loglik_;
  const double r = z - s->value_nT;
  if (residual != nullptr) *residual = r;
  if (bias_var <= 0.0) return -r * r * inv_two_var_;
  const double var = sigma_ * sigma_, total = var + bias_var;
  return -0.5 * (r * r / total + std::log(total / var));
}

// The Kalman update of a particle's bias (estimate_bias) by a reading whose
// residual from its prediction m(x) + b is `r`, noise variance `noise_var`
// (σ², or σ²/β for a tempered PF update): b += P r / (σ² + P), P ← P σ² / (σ² + P).
void Filter::UpdateBias(Particle* q, double r, double noise_var) {
  const double total = noise_var + q->bias_var_nT2;
  if (!(total > 0.0)) return;
  q->bias_nT += q->bias_var_nT2 / total * r;
  q->bias_var_nT2 *= noise_var / total;
}

// The likelihood σ for this update (adaptive_sigma: from the innovations of
// the last sigma_window updates, see the header).
// AFPF (afpf_sigma_factor > 0): afpf_sigma_factor × that estimate in
// [measurement_sigma_nT, afpf_max_sigma_nT], afpf_max_sigma_nT until the window is full.
double Filter::CurrentSigma() const {
  const bool afpf = kind_ == ParticleFilterKind::kAfpf;
  const double hi = afpf && adaptive_ ? o_.afpf_max_sigma_nT : o_.measurement_sigma_nT;
  if (!adaptive_ || static_cast<int>(innov_.size()) < o_.sigma_window) return hi;
  double r2 = 0.0, spread = 0.0;
  for (const auto& [a, b] : innov_) r2 += a, spread += b;
  const double sd = std::sqrt(std::max((r2 - spread) / static_cast<double>(innov_.size()), 0.0));
  if (afpf) return std::clamp(o_.afpf_sigma_factor * sd, o_.measurement_sigma_nT, hi);
  return std::clamp(sd, o_.min_measurement_sigma_nT, hi);
}

// A reading left out by min_update_spacing_m (average_spaced_readings): each particle's residual
// z − m(x_i) at its position now is added to its sum, to be averaged into the next update
// (AveragedReadings). A reading the whole cloud's prediction does not explain (the outlier gate's
// rule, outlier_sigmas) is not added (counted as an outlier).
void Filter::AccumulateSpaced(double z, StepDiagnostics* d) {
  const std::size_t n = p_.size();
  if (spaced_steps_ == 0 || spaced_sum_.size() != n) {
    spaced_sum_.assign(n, 0.0);
    spaced_n_.assign(n, 0);
    spaced_steps_ = 0;
  }
  zt_.resize(n);
  double w_on = 0.0, r1 = 0.0, r2 = 0.0, pb = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto s = grid_.Sample(layer_, p_[i].lat_deg, p_[i].lon_deg);
    zt_[i] = s ? z - s->value_nT : std::numeric_limits<double>::quiet_NaN();
    if (!s) continue;
    const double r = zt_[i] - p_[i].bias_nT, w = p_[i].weight;
    w_on += w, r1 += w * r, r2 += w * r * r, pb += w * p_[i].bias_var_nT2;
  }
  if (o_.outlier_sigmas > 0.0 && w_on > 0.5) {
    const double mean = r1 / w_on, spread = std::max(r2 / w_on - mean * mean, 0.0) + pb / w_on;
    if (mean * mean > o_.outlier_sigmas * o_.outlier_sigmas * (sigma_ * sigma_ + spread)) {
      ++counters_.outliers;
      d->update = StepUpdate::kOutlier;
      return;
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isfinite(zt_[i])) spaced_sum_[i] += zt_[i], ++spaced_n_[i];
  }
  ++spaced_steps_;
}

// This update's reading per particle, zt_[i]: z, or — readings spaced out since the last update
// (AccumulateSpaced) — the mean of the particle's residuals over them and this one, referred to the
// particle's map value now: m(x_i) + (Σ_j (z_j − m(x_i,j)) + z − m(x_i)) / (n_i + 1). Empties the sums.
void Filter::AveragedReadings(double z) {
  const std::size_t n = p_.size();
  zt_.assign(n, z);
  if (spaced_steps_ > 0 && spaced_sum_.size() == n) {
    for (std::size_t i = 0; i < n; ++i) {
      if (spaced_n_[i] == 0) continue;
      const auto s = grid_.Sample(layer_, p_[i].lat_deg, p_[i].lon_deg);
      if (s) zt_[i] = s->value_nT + (spaced_sum_[i] + z - s->value_nT) / (spaced_n_[i] + 1);
    }
  }
  spaced_steps_ = 0;
}

}  // namespace magnav::mapmatch::internal
