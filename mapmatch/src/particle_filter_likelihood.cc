// The particle filters' measurement model: log-likelihood and the likelihood σ
// (particle_filter_impl.h says which file holds what).
#include "particle_filter_impl.h"

#include <algorithm>
#include <cmath>

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

}  // namespace magnav::mapmatch::internal
