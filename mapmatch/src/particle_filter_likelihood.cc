// The particle filters' measurement model: log-likelihood and the likelihood σ
// (particle_filter_impl.h says which file holds what).
#include "particle_filter_impl.h"

#include <algorithm>
#include <cmath>

namespace magnav::mapmatch::internal {

// Log-likelihood of a measurement at a point (the off-map floor outside).
double Filter::LogLik(double lat, double lon, double z, bool* on_map, double* residual) const {
  const auto s = grid_.Sample(layer_, lat, lon);
  *on_map = s.has_value();
  if (!s) return off_map_loglik_;
  const double r = z - s->value_nT;
  if (residual != nullptr) *residual = r;
  return -r * r * inv_two_var_;
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
