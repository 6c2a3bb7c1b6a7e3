#include "fast_msd_basins.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/LU>

namespace magnav::mapmatch::internal {
namespace {

// The 1-D transition kernel over index differences k = j_next − j (|k| ≤ half):
// exp(−(k·h + shift)² / (2 τ²)), shift = the published correction's increment.
std::vector<double> Kernel(double shift_deg, double step_deg, double tau2_deg2, int half) {
  std::vector<double> k(2 * half + 1);
  for (int i = -half; i <= half; ++i) {
    const double x = i * step_deg + shift_deg;
    k[i + half] = std::exp(-0.5 * x * x / tau2_deg2);
  }
  return k;
}

// out[a] = Σ_k in[a − k] kern[k + half] along one axis of a (2R+1)² grid
// (axis 0: a = row (lat), axis 1: column (lon)); forward = true convolves, false correlates
// (the backward pass applies the transpose).
void Apply(const std::vector<double>& in, std::vector<double>* out, const std::vector<double>& kern, int half, int side,
           int axis, bool forward) {
  std::fill(out->begin(), out->end(), 0.0);
  for (int r = 0; r < side; ++r) {
    for (int c = 0; c < side; ++c) {
      const double v = in[r * side + c];
      if (v == 0.0) continue;
      for (int k = -half; k <= half; ++k) {
        const int kk = forward ? k : -k;
        const int rr = axis == 0 ? r + kk : r, cc = axis == 0 ? c : c + kk;
        if (rr < 0 || rr >= side || cc < 0 || cc >= side) continue;
        (*out)[rr * side + cc] += v * kern[k + half];
      }
    }
  }
}

}  // namespace

BasinSpread FastMsdBasinSpread(const GeoGrid& grid, std::size_t layer, const std::vector<double>& lat_deg,
                               const std::vector<double>& lon_deg, const std::vector<double>& measured_nT,
                               const std::vector<char>& data, const std::vector<double>& e_lat,
                               const std::vector<double>& e_lon, const std::vector<Eigen::Matrix2d>& cov,
                               double s2_nT2, const std::vector<double>& map_var_nT2, double tau2_deg2,
                               double cap_nT, double step_deg, int radius, double chi2) {
  const std::size_t n = lat_deg.size();
  BasinSpread out;
  out.step_deg = step_deg;
  out.radius = radius;
  out.far_moment.assign(n, Eigen::Matrix2d::Zero());
  out.far_mass.assign(n, 0.0);
  if (n < 2 || !(tau2_deg2 > 0.0) || !(s2_nT2 > 0.0) || !(step_deg > 0.0) || radius < 1) return out;
  const int side = 2 * radius + 1;
  const std::size_t states = static_cast<std::size_t>(side) * side;
  const double cap2 = cap_nT * cap_nT;
  // Emissions, scaled per point to a maximum of 1.
  std::vector<std::vector<double>> like(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!data[i]) continue;
    auto& L = like[i];
    L.assign(states, 0.0);
    const double var = s2_nT2 + (map_var_nT2.empty() ? 0.0 : map_var_nT2[i]);
    double best = std::numeric_limits<double>::infinity();
    for (int a = 0; a < side; ++a) {
      for (int b = 0; b < side; ++b) {
        const auto s = grid.Sample(layer, lat_deg[i] + (a - radius) * step_deg, lon_deg[i] + (b - radius) * step_deg);
        double r2 = cap2;
        if (s) r2 = std::min(cap2, (s->value_nT - measured_nT[i]) * (s->value_nT - measured_nT[i]));
        L[a * side + b] = r2 / var;
        best = std::min(best, r2 / var);
      }
    }
    for (double& x : L) x = std::exp(-0.5 * (x - best));
  }
  const double tau = std::sqrt(tau2_deg2);
  // Kernels per step (the published increments differ per step).
  const auto half_for = [&](double shift) {
    return std::min(side - 1, static_cast<int>(std::ceil((std::abs(shift) + 5.0 * tau) / step_deg)));
  };
  std::vector<std::vector<double>> alpha(n, std::vector<double>(states));
  std::vector<double> tmp(states), tmp2(states);
  // Forward: α_0 uniform × emission.
  for (std::size_t s = 0; s < states; ++s) alpha[0][s] = data[0] ? like[0][s] : 1.0;
  const auto normalise = [](std::vector<double>* v) {
    double sum = 0.0;
    for (double x : *v) sum += x;
    if (sum > 0.0) {
      for (double& x : *v) x /= sum;
    }
  };
  normalise(&alpha[0]);
  for (std::size_t i = 1; i < n; ++i) {
    const double sa = e_lat[i] - e_lat[i - 1], sb = e_lon[i] - e_lon[i - 1];
    // d_i = d_{i−1} + k·h with weight exp(−(k h + shift)²/2τ²).
    const int ha = half_for(sa), hb = half_for(sb);
    Apply(alpha[i - 1], &tmp, Kernel(sa, step_deg, tau2_deg2, ha), ha, side, 0, true);
    Apply(tmp, &tmp2, Kernel(sb, step_deg, tau2_deg2, hb), hb, side, 1, true);
    for (std::size_t s = 0; s < states; ++s) alpha[i][s] = tmp2[s] * (data[i] ? like[i][s] : 1.0);
    normalise(&alpha[i]);
  }
  // Backward: β_{n−1} = 1; β_i = T (emission_{i+1} β_{i+1}); posterior ∝ α β.
  std::vector<double> beta(states, 1.0), post(states);
  for (std::size_t ii = n; ii-- > 0;) {
    if (ii + 1 < n) {
      const std::size_t j = ii + 1;
      for (std::size_t s = 0; s < states; ++s) tmp[s] = beta[s] * (data[j] ? like[j][s] : 1.0);
      const double sa = e_lat[j] - e_lat[ii], sb = e_lon[j] - e_lon[ii];
      const int ha = half_for(sa), hb = half_for(sb);
      Apply(tmp, &tmp2, Kernel(sa, step_deg, tau2_deg2, ha), ha, side, 0, false);
      Apply(tmp2, &beta, Kernel(sb, step_deg, tau2_deg2, hb), hb, side, 1, false);
      normalise(&beta);
    }
    double sum = 0.0;
    for (std::size_t s = 0; s < states; ++s) sum += (post[s] = alpha[ii][s] * beta[s]);
    if (!(sum > 0.0)) continue;
    Eigen::Matrix2d inv = cov[ii].inverse();
    if (!inv.allFinite()) continue;
    Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
    double mass = 0.0;
    const double cell = step_deg * step_deg / 12.0;
    for (int a = 0; a < side; ++a) {
      for (int b = 0; b < side; ++b) {
        const double p = post[a * side + b] / sum;
        if (p == 0.0) continue;
        const Eigen::Vector2d d((a - radius) * step_deg, (b - radius) * step_deg);
        if (d.dot(inv * d) <= chi2) continue;
        m += p * (d * d.transpose() + cell * Eigen::Matrix2d::Identity());
        mass += p;
      }
    }
    out.far_moment[ii] = m;
    out.far_mass[ii] = mass;
  }
  return out;
}

}  // namespace magnav::mapmatch::internal
