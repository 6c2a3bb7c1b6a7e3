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

namespace magnav::mapmatch::internal {
namespace {

using M2 = Eigen::Matrix2d;
using V2 = Eigen::Vector2d;

// Block-tridiagonal M = blkdiag(ω_i g gᵀ + h d_i I) − h (neighbours), factored by forward Schur complements.
struct Tridiag {
  std::vector<M2> s_inv;
  double h = 0.0;
  Tridiag(const std::vector<V2>& g, const std::vector<double>& omega, double h_) : s_inv(g.size()), h(h_) {
    const std::size_t n = g.size();
    for (std::size_t i = 0; i < n; ++i) {
      M2 D = h * ((i == 0 || i == n - 1) ? 1.0 : 2.0) * M2::Identity() + omega[i] * g[i] * g[i].transpose();
      if (i > 0) D -= h * h * s_inv[i - 1];
      s_inv[i] = D.inverse();
    }
  }
  // x = M⁻¹ b (b overwritten by the forward pass).
  void Solve(std::vector<V2>* b, std::vector<V2>* x) const {
    const std::size_t n = s_inv.size();
    for (std::size_t i = 1; i < n; ++i) (*b)[i] += h * (s_inv[i - 1] * (*b)[i - 1]);
    (*x)[n - 1] = s_inv[n - 1] * (*b)[n - 1];
    for (std::size_t i = n - 1; i-- > 0;) (*x)[i] = s_inv[i] * ((*b)[i] + h * (*x)[i + 1]);
  }
  // Diagonal blocks Σ_i of M⁻¹ and the off-diagonal Σ_{i,i+1}.
  void Blocks(std::vector<M2>* diag, std::vector<M2>* off) const {
    const std::size_t n = s_inv.size();
    diag->assign(n, M2::Zero());
    off->assign(n, M2::Zero());
    (*diag)[n - 1] = s_inv[n - 1];
    for (std::size_t i = n - 1; i-- > 0;) {
      (*off)[i] = h * s_inv[i] * (*diag)[i + 1];
      (*diag)[i] = s_inv[i] + h * (*off)[i] * s_inv[i].transpose();
      (*diag)[i] = 0.5 * ((*diag)[i] + (*diag)[i].transpose());
    }
  }
};

}  // namespace

ErrorCovariance FastMsdErrorCovariance(const std::vector<double>& g_lat, const std::vector<double>& g_lon,
                                       const std::vector<double>& resid, const std::vector<char>& data,
                                       const std::vector<double>& e_lat, const std::vector<double>& e_lon,
                                       const std::vector<double>& h_ll, const std::vector<double>& h_ln,
                                       const std::vector<double>& h_nn, double lambda, int curvature_iterations) {
  const std::size_t n = g_lat.size();
  ErrorCovariance out;
  out.lat_lat.assign(n, std::numeric_limits<double>::infinity());
  out.lat_lon.assign(n, 0.0);
  out.lon_lon.assign(n, std::numeric_limits<double>::infinity());
  const PathCovariance laplace = FastMsdCovariance(g_lat, g_lon, resid, data, lambda);
  if (n < 2 || !(laplace.s2_nT2 > 0.0) || !std::isfinite(laplace.s2_nT2)) {
    out.lat_lat = laplace.lat_lat;
    out.lat_lon = laplace.lat_lon;
    out.lon_lon = laplace.lon_lon;
    out.s2_nT2 = laplace.s2_nT2;
    out.edf = laplace.edf;
    return out;
  }
  const double h = 0.5 * lambda;
  std::vector<V2> g(n, V2::Zero());
  std::vector<double> w(n, 0.0), y(n, 0.0);
  double sw = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!data[i]) continue;
    g[i] = V2(g_lat[i], g_lon[i]);
    w[i] = (i == 0 || i == n - 1) ? 0.5 : 1.0;
    y[i] = g[i].dot(V2(e_lat[i], e_lon[i])) - resid[i];
    sw += w[i];
  }
  // EM for σ², τ² in the linearised model (the posterior at h* = σ²/τ²).
  double s2 = laplace.s2_nT2, tau2 = s2 / h;
  std::vector<M2> diag, off;
  std::vector<V2> mu(n), b(n);
  for (int it = 0; it < 100; ++it) {
    const Tridiag t(g, w, s2 / tau2);
    for (std::size_t i = 0; i < n; ++i) b[i] = w[i] * y[i] * g[i];
    t.Solve(&b, &mu);
    t.Blocks(&diag, &off);
    double rs = 0.0, ds = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (w[i] > 0.0) {
        const double r = y[i] - g[i].dot(mu[i]);
        rs += w[i] * (r * r + s2 * g[i].dot(diag[i] * g[i]));
      }
      if (i + 1 < n) {
        ds += (mu[i + 1] - mu[i]).squaredNorm() +
              s2 * (diag[i].trace() + diag[i + 1].trace() - 2.0 * off[i].trace());
      }
    }
    const double s2_new = rs / sw, tau2_new = ds / (2.0 * static_cast<double>(n - 1));
    if (!(s2_new > 0.0) || !(tau2_new > 0.0) || !std::isfinite(s2_new) || !std::isfinite(tau2_new)) break;
    const bool done = std::abs(s2_new - s2) <= 1e-9 * s2 && std::abs(tau2_new - tau2) <= 1e-9 * tau2;
    s2 = s2_new;
    tau2 = tau2_new;
    if (done) break;
  }
  out.s2_nT2 = s2;
  out.tau2_deg2 = tau2;
  out.edf = laplace.edf;
  // The smoother's error covariance (sandwich), with the curvature term iterated.
  const Tridiag m(g, w, h);
  std::vector<double> v(n, 0.0);
  std::vector<M2> cov(n);
  std::vector<V2> x(n);
  const double kt = h * std::sqrt(tau2);
  for (int pass = 0; pass <= std::max(curvature_iterations - 1, 0); ++pass) {
    std::fill(cov.begin(), cov.end(), M2::Zero());
    const auto accumulate = [&]() {
      m.Solve(&b, &x);
      for (std::size_t i = 0; i < n; ++i) cov[i] += x[i] * x[i].transpose();
    };
    for (std::size_t j = 0; j < n; ++j) {  // the readings: ω_j √R_j g_j at block j
      if (w[j] == 0.0) continue;
      std::fill(b.begin(), b.end(), V2::Zero());
      b[j] = w[j] * std::sqrt(s2 + v[j]) * g[j];
      accumulate();
    }
    for (std::size_t j = 0; j + 1 < n; ++j) {  // the random walk: (λ/2) τ (e_{j+1} − e_j) per axis
      for (int axis = 0; axis < 2; ++axis) {
        std::fill(b.begin(), b.end(), V2::Zero());
        b[j + 1](axis) = kt;
        b[j](axis) = -kt;
        accumulate();
      }
    }
    if (pass + 1 >= curvature_iterations) break;
    for (std::size_t i = 0; i < n; ++i) {
      M2 H;
      H << h_ll[i], h_ln[i], h_ln[i], h_nn[i];
      const M2 a = H * cov[i];
      v[i] = 0.5 * (a(0, 0) * a(0, 0) + 2.0 * a(0, 1) * a(1, 0) + a(1, 1) * a(1, 1)) + 0.25 * a.trace() * a.trace();
      if (!std::isfinite(v[i])) v[i] = 0.0;
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    out.lat_lat[i] = cov[i](0, 0);
    out.lat_lon[i] = 0.5 * (cov[i](0, 1) + cov[i](1, 0));
    out.lon_lon[i] = cov[i](1, 1);
  }
  return out;
}

}  // namespace magnav::mapmatch::internal
