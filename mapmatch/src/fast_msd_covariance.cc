#include "fast_msd_covariance.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

namespace magnav::mapmatch::internal {

PathCovariance FastMsdCovariance(const std::vector<double>& g_lat, const std::vector<double>& g_lon,
                                 const std::vector<double>& resid, const std::vector<char>& data, double lambda) {
  using M2 = Eigen::Matrix2d;
  const std::size_t n = g_lat.size();
  PathCovariance out;
  out.lat_lat.assign(n, std::numeric_limits<double>::infinity());
  out.lat_lon.assign(n, 0.0);
  out.lon_lon.assign(n, std::numeric_limits<double>::infinity());
  double sw = 0.0, swr2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!data[i]) continue;
    const double w = (i == 0 || i == n - 1) ? 0.5 : 1.0;
    sw += w;
    swr2 += w * resid[i] * resid[i];
  }
  if (n < 2 || sw == 0.0) return out;
  // Block tridiagonal P·σ²: diagonal D_i = w_i g gᵀ + (λ/2) d_i I, off-diagonal −(λ/2) I.
  const double h = 0.5 * lambda;
  std::vector<M2> s_inv(n);  // inverses of the forward Schur complements
  for (std::size_t i = 0; i < n; ++i) {
    const double d = (i == 0 || i == n - 1) ? 1.0 : 2.0;
    M2 D = h * d * M2::Identity();
    if (data[i]) {
      const Eigen::Vector2d g(g_lat[i], g_lon[i]);
      D += ((i == 0 || i == n - 1) ? 0.5 : 1.0) * g * g.transpose();
    }
    if (i > 0) D -= h * h * s_inv[i - 1];
    s_inv[i] = D.inverse();
  }
  // Backward: Σ_i = S_i⁻¹ + S_i⁻¹ B Σ_{i+1} Bᵀ S_i⁻¹ with B = −(λ/2) I.
  std::vector<M2> sigma(n);
  sigma[n - 1] = s_inv[n - 1];
  for (std::size_t i = n - 1; i-- > 0;) {
    sigma[i] = s_inv[i] + h * h * s_inv[i] * sigma[i + 1] * s_inv[i];
    sigma[i] = 0.5 * (sigma[i] + sigma[i].transpose());
  }
  double edf = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!data[i]) continue;
    const Eigen::Vector2d g(g_lat[i], g_lon[i]);
    edf += ((i == 0 || i == n - 1) ? 0.5 : 1.0) * g.dot(sigma[i] * g);
  }
  // At least one residual degree of freedom's worth: a path fitted exactly says nothing of its noise.
  const double s2 = swr2 / std::max(sw - edf, 1.0);
  out.s2_nT2 = s2;
  out.edf = edf;
  for (std::size_t i = 0; i < n; ++i) {
    out.lat_lat[i] = s2 * sigma[i](0, 0);
    out.lat_lon[i] = s2 * sigma[i](0, 1);
    out.lon_lon[i] = s2 * sigma[i](1, 1);
  }
  return out;
}

}  // namespace magnav::mapmatch::internal
