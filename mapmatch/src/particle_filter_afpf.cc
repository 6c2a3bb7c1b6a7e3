// The AFPF strategy: fission, pooling, selection of the heaviest, adaptive
// count (particle_filter_impl.h says which file holds what).
#include "particle_filter_impl.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace magnav::mapmatch::internal {

// The paper's fission, pooling and selection of the heaviest current-count particles.
void Filter::Fission(double z) {
  const std::size_t n = p_.size();
  double w_max = 0.0;
  for (const Particle& q : p_) w_max = std::max(w_max, q.weight);
  const double w_avg = 1.0 / static_cast<double>(n);
  const double spread = w_max - w_avg;
  pool_.assign(p_.begin(), p_.end());
  pool_logw_.assign(logw_.begin(), logw_.end());
  // estimate_bias: the parents kept in the pool carry their bias posterior; their offspring start
  // from the parent's prior bias (p_) and are updated by their own residual.
  const double noise_var = sigma_ * sigma_;
  if (o_.estimate_bias) {
    for (std::size_t i = 0; i < n; ++i) {
      if (std::isfinite(resid_[i])) UpdateBias(&pool_[i], resid_[i], noise_var);
    }
  }
  std::normal_distribution<double> unit(0.0, 1.0);
  const double penalty = o_.fission_motion_penalty && drift_sd_deg_ > 0.0
                             ? 0.5 / (drift_sd_deg_ * drift_sd_deg_)
                             : 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double wi = p_[i].weight;
    const double a = spread > 1e-15 * w_avg ? 1.0 / (1.0 + std::exp((wi - w_avg) / spread)) : 0.5;
    const double sd = std::sqrt(o_.fission_lambda * o_.fission_mu_deg2 * a);
    const long m = std::lround(static_cast<double>(n) * wi) + 2;
    for (long j = 0; j < m; ++j) {
      Particle c;
      c.lat_deg = p_[i].lat_deg + sd * unit(rng_);
      c.lon_deg = p_[i].lon_deg + sd * unit(rng_);
      c.bias_nT = p_[i].bias_nT;
      c.bias_var_nT2 = p_[i].bias_var_nT2;
      bool on = false;
      double r = 0.0;
      // The parent's prior weight times the offspring's likelihood, with the
      // parents' normaliser: logw_i − loglik_i + loglik(offspring).
      double lw = logw_[i] - loglik_[i] + LogLik(c.lat_deg, c.lon_deg, z - c.bias_nT, c.bias_var_nT2, &on, &r);
      if (o_.estimate_bias && on) UpdateBias(&c, r, noise_var);
      if (penalty > 0.0) {
        const double dl = c.lat_deg - p_[i].lat_deg, dn = c.lon_deg - p_[i].lon_deg;
        lw -= penalty * (dl * dl + dn * dn);
      }
      pool_logw_.push_back(lw);
      pool_.push_back(c);
    }
  }
  KeepHeaviest(n);
}

// Keeps the `n` heaviest of pool_ (descending weight) in p_, renormalised.
void Filter::KeepHeaviest(std::size_t n) {
  order_.resize(pool_.size());
  std::iota(order_.begin(), order_.end(), std::size_t{0});
  auto heavier = [this](std::size_t a, std::size_t b) {
    return pool_logw_[a] > pool_logw_[b] || (pool_logw_[a] == pool_logw_[b] && a < b);
  };
  n = std::min(n, order_.size());
  std::nth_element(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(n), order_.end(), heavier);
  std::sort(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(n), heavier);
  p_.resize(n);
  logw_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    p_[i] = pool_[order_[i]];
    logw_[i] = pool_logw_[order_[i]];
  }
  Normalise();
  unique_ = static_cast<int>(n);
}

// The AFPF's count for the next step from this step's spread (occupied map
// cells); trims the lightest particles (p_ is sorted heaviest first after
// KeepHeaviest).
void Filter::AdaptCount(const StepDiagnostics& d) {
  const double want = std::ceil(o_.particles_per_cell * d.occupied_cells);
  const std::size_t n = static_cast<std::size_t>(
      std::clamp(want, static_cast<double>(o_.num_particles), static_cast<double>(o_.max_particles)));
  if (n >= p_.size() || d.update != StepUpdate::kUpdated) return;
  p_.resize(n);
  logw_.resize(n);
  Normalise();
}

}  // namespace magnav::mapmatch::internal
