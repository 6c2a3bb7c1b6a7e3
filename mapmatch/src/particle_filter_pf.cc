// The PF strategy: tempered update, systematic resampling, regularisation
// (particle_filter_impl.h says which file holds what).
#include "particle_filter_impl.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace magnav::mapmatch::internal {

// Tempered update (see the header): 1 unless the full reading would leave
// fewer than min_update_ess_fraction·N effective particles; then the largest
// β with ESS(β) ≥ that floor, by bisection (counted).
double Filter::PfTemperedExponent() {
  const std::size_t n = p_.size();
  double beta = 1.0;
  const double floor_ess = o_.min_update_ess_fraction * static_cast<double>(n);
  if (floor_ess > 0.0 && EssWith(1.0) < floor_ess) {
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (lo + hi);
      (EssWith(mid) >= floor_ess ? lo : hi) = mid;
    }
    beta = lo;
    ++counters_.tempered_updates;
  }
  return beta;
}

// Systematic resampling (and the optional regularisation) when the ESS after
// the update is below resample_ess_fraction·N.
void Filter::PfResample(StepDiagnostics* d) {
  const std::size_t n = p_.size();
  if (d->ess < o_.resample_ess_fraction * static_cast<double>(n)) {
    Resample();
    if (o_.regularization_bandwidth > 0.0) Regularise();
    d->resampled = true;
    ++counters_.resamples;
  }
}

// ESS of the weights w_i ∝ exp(logw_i + β loglik_i) (before they are applied).
double Filter::EssWith(double beta) const {
  double mx = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < p_.size(); ++i) mx = std::max(mx, logw_[i] + beta * loglik_[i]);
  double s1 = 0.0, s2 = 0.0;
  for (std::size_t i = 0; i < p_.size(); ++i) {
    const double w = std::exp(logw_[i] + beta * loglik_[i] - mx);
    s1 += w, s2 += w * w;
  }
  return s2 > 0.0 ? s1 * s1 / s2 : 0.0;
}

// Systematic resampling: one uniform offset, N evenly spaced pointers.
void Filter::Resample() {
  const std::size_t n = p_.size();
  const double step = 1.0 / static_cast<double>(n);
  std::uniform_real_distribution<double> u(0.0, step);
  double pointer = u(rng_), cum = p_[0].weight;
  std::vector<Particle> out(n);
  std::size_t j = 0;
  int unique = 0;
  std::size_t last_j = n;
  for (std::size_t i = 0; i < n; ++i) {
    while (pointer > cum && j + 1 < n) cum += p_[++j].weight;
    out[i] = p_[j];
    out[i].weight = step;
    if (j != last_j) ++unique, last_j = j;
    pointer += step;
  }
  p_.swap(out);
  std::fill(logw_.begin(), logw_.end(), std::log(step));
  unique_ = unique;
}

// Regularised PF (Musso, Oudjane & Le Gland 2001): after resampling every
// particle moves by h·L·ε, ε ~ N(0, I₂), L Lᵀ = the cloud's covariance
// (now equal-weighted, i.e. that of the weighted cloud before resampling),
// h = bandwidth · h_opt, h_opt = (4 / ((d + 2) N))^(1/(d + 4)) = N^(−1/6) for
// d = 2 (the Gaussian kernel's optimal width for a Gaussian density). The
// copies that resampling made become distinct, near where the evidence put
// them; the cloud's variance grows by h² (≈ 7 % at N = 3000).
void Filter::Regularise() {
  const std::size_t n = p_.size();
  double mlat = 0.0, mlon = 0.0;
  for (const Particle& q : p_) mlat += q.lat_deg, mlon += q.lon_deg;
  mlat /= static_cast<double>(n);
  mlon /= static_cast<double>(n);
  double a = 0.0, b = 0.0, c = 0.0;
  for (const Particle& q : p_) {
    const double x = q.lat_deg - mlat, y = q.lon_deg - mlon;
    a += x * x, b += x * y, c += y * y;
  }
  a /= static_cast<double>(n), b /= static_cast<double>(n), c /= static_cast<double>(n);
  // Cholesky of [[a, b], [b, c]] (a degenerate cloud gets no jitter along its null direction).
  const double l11 = std::sqrt(std::max(a, 0.0));
  const double l21 = l11 > 0.0 ? b / l11 : 0.0;
  const double l22 = std::sqrt(std::max(c - l21 * l21, 0.0));
  const double h = o_.regularization_bandwidth * std::pow(static_cast<double>(n), -1.0 / 6.0);
  std::normal_distribution<double> unit(0.0, 1.0);
  for (Particle& q : p_) {
    const double e1 = unit(rng_), e2 = unit(rng_);
    q.lat_deg += h * l11 * e1;
    q.lon_deg += h * (l21 * e1 + l22 * e2);
  }
  unique_ = static_cast<int>(n);
}

}  // namespace magnav::mapmatch::internal
