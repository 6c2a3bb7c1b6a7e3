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

}  // namespace

std::vector<M2> SandwichDiagonalBlocks(const BlockTridiagonal& m, const BlockTridiagonal& a) {
  const std::size_t n = m.diag.size();
  std::vector<M2> x(n);
  if (n == 0) return x;
  // Forward: S_i⁻¹ (p), Q_i = S_i⁻¹ B_i (q), K_i = S_i⁻¹ Ṡ_i S_i⁻¹ (k).
  std::vector<M2> p(n), k(n), q(n - 1);
  M2 s = m.diag[0], sd = a.diag[0];
  for (std::size_t i = 0;; ++i) {
    p[i] = s.inverse();
    k[i] = p[i] * sd * p[i];
    k[i] = 0.5 * (k[i] + k[i].transpose());
    if (i + 1 == n) break;
    q[i] = p[i] * m.upper[i];
    const M2 aq = a.upper[i].transpose() * q[i];
    s = m.diag[i + 1] - q[i].transpose() * m.upper[i];
    s = 0.5 * (s + s.transpose());
    sd = a.diag[i + 1] - aq - aq.transpose() + q[i].transpose() * sd * q[i];
    sd = 0.5 * (sd + sd.transpose());
  }
  // Backward: Σ_i (M⁻¹'s diagonal blocks) and X_i.
  M2 sigma = p[n - 1];
  x[n - 1] = k[n - 1];
  for (std::size_t i = n - 1; i-- > 0;) {
    const M2 qd = p[i] * a.upper[i] - k[i] * m.upper[i];
    const M2 t = qd * sigma * q[i].transpose();
    x[i] = k[i] + q[i] * x[i + 1] * q[i].transpose() - t - t.transpose();
    x[i] = 0.5 * (x[i] + x[i].transpose());
    sigma = p[i] + q[i] * sigma * q[i].transpose();
    sigma = 0.5 * (sigma + sigma.transpose());
  }
  return x;
}

bool CapAtPrior(Eigen::Matrix2d* cov, double prior_var_deg2) {
  if (!(prior_var_deg2 > 0.0)) return false;
  // Positive semi-definite with trace inside: both eigenvalues are (no eigensolver on the usual path).
  const bool psd = cov->allFinite() && (*cov)(0, 0) >= 0.0 && cov->determinant() >= 0.0;
  if (psd && cov->trace() <= prior_var_deg2) return false;
  Eigen::SelfAdjointEigenSolver<M2> es(*cov);
  const V2 ev = es.eigenvalues();
  if (ev.allFinite() && ev.maxCoeff() <= prior_var_deg2) return false;
  V2 capped;
  for (int k = 0; k < 2; ++k) {
    capped(k) = std::isfinite(ev(k)) ? std::min(ev(k), prior_var_deg2) : prior_var_deg2;
  }
  if (!es.eigenvectors().allFinite()) {
    *cov = prior_var_deg2 * M2::Identity();
    return true;
  }
  *cov = es.eigenvectors() * capped.asDiagonal() * es.eigenvectors().transpose();
  return true;
}

double CurvatureSecondMoment(const Eigen::Matrix2d& hessian, const Eigen::Matrix2d& cov) {
  const M2 hc = hessian * cov;
  return 0.5 * (hc(0, 0) * hc(0, 0) + 2.0 * hc(0, 1) * hc(1, 0) + hc(1, 1) * hc(1, 1)) +
         0.25 * hc.trace() * hc.trace();
}

double BilinearErrorBound(const Eigen::Matrix2d& hessian, double step_lat_deg, double step_lon_deg) {
  return 0.125 * (step_lat_deg * step_lat_deg * std::abs(hessian(0, 0)) +
                  step_lon_deg * step_lon_deg * std::abs(hessian(1, 1)));
}

bool CurvatureUpdateContracts(double v, double next, double last_change, double s2) {
  if (!std::isfinite(next)) return false;
  const double change = std::abs(next - v);
  // A change below 1e-9 of the reading's variance is convergence, whichever way it moves.
  return change <= last_change || change <= 1e-9 * (s2 + v);
}

namespace {

// The smoother's error covariance (the sandwich), with the curvature term iterated: per point
// the diagonal block of M⁻¹ (Gᵀ W R W G + (λ/2)² τ² L) M⁻¹, M = Gᵀ W G + (λ/2) L
// (h = λ/2, ω = W's diagonal). A point's curvature term stops being updated (is held at its last
// value, and the point flagged in *limited) at the first pass where its change does not shrink
// (CurvatureUpdateContracts): there the fixed point does not contract (fast_msd_covariance.h).
std::vector<M2> SmootherErrorCovariance(const std::vector<V2>& g, const std::vector<double>& omega, double h,
                                        double s2, double tau2, const std::vector<double>& h_ll,
                                        const std::vector<double>& h_ln, const std::vector<double>& h_nn,
                                        int curvature_iterations, const std::vector<double>& map_var,
                                        std::vector<char>* limited) {
  const std::size_t n = g.size();
  const auto degree = [n](std::size_t i) { return (i == 0 || i + 1 == n) ? 1.0 : 2.0; };  // the path graph's
  const double kt2 = h * h * tau2;                                                          // (λ/2)² τ²
  BlockTridiagonal m, a;  // M and the middle factor A
  m.upper.assign(n - 1, -h * M2::Identity());
  a.upper.assign(n - 1, -kt2 * M2::Identity());
  for (std::size_t i = 0; i < n; ++i) {
    m.diag.push_back(h * degree(i) * M2::Identity() + omega[i] * g[i] * g[i].transpose());
  }
  a.diag.resize(n);
  std::vector<double> v(n, 0.0);  // the curvature term's second moment per reading (nT²)
  std::vector<double> last_change(n, std::numeric_limits<double>::infinity());
  limited->assign(n, 0);
  std::vector<M2> cov;
  for (int pass = 0;; ++pass) {
    for (std::size_t i = 0; i < n; ++i) {
      a.diag[i] = kt2 * degree(i) * M2::Identity() +
                  omega[i] * omega[i] * (s2 + map_var[i] + v[i]) * g[i] * g[i].transpose();
    }
    cov = SandwichDiagonalBlocks(m, a);
    if (pass + 1 >= curvature_iterations) return cov;
    for (std::size_t i = 0; i < n; ++i) {
      if ((*limited)[i]) continue;
      M2 H;
      H << h_ll[i], h_ln[i], h_ln[i], h_nn[i];
      const double next = CurvatureSecondMoment(H, cov[i]);
      if (!CurvatureUpdateContracts(v[i], next, last_change[i], s2)) {
        (*limited)[i] = omega[i] > 0.0 ? 1 : 0;  // without a data term v does not enter
        if (omega[i] > 0.0) continue;
      }
      last_change[i] = std::abs(next - v[i]);
      v[i] = std::isfinite(next) ? next : v[i];
    }
  }
}

// EM for σ², τ² in the linearised model (the posterior at h* = σ²/τ²) from *s2_io, *tau2_io:
// readings y at gradients g with weights w (their sum sw). At most 100 iterations. Each is one
// block-tridiagonal factorisation (forward) and one pass back for the posterior mean and M(h*)⁻¹'s
// diagonal and first off-diagonal blocks (the oracle in tests/mapmatch/fast_msd_covariance_test.cc
// computes the same with separate solve and block passes).
void EstimateScales(const std::vector<V2>& g, const std::vector<double>& w, const std::vector<double>& y,
                    double sw, double* s2_io, double* tau2_io) {
  const std::size_t n = g.size();
  double s2 = *s2_io, tau2 = *tau2_io;
  std::vector<M2> s_inv(n), wggt(n);
  std::vector<V2> b(n), mu(n), wyg(n);
  std::vector<double> gsg(n), tr(n), tr_off(n);  // gᵀ Σ_i g, trace Σ_i, trace Σ_{i,i+1}
  for (std::size_t i = 0; i < n; ++i) {
    wggt[i] = w[i] * g[i] * g[i].transpose();
    wyg[i] = w[i] * y[i] * g[i];
  }
  for (int it = 0; it < 100; ++it) {
    const double h = s2 / tau2;
    for (std::size_t i = 0; i < n; ++i) {
      M2 D = h * ((i == 0 || i == n - 1) ? 1.0 : 2.0) * M2::Identity() + wggt[i];
      b[i] = wyg[i];
      if (i > 0) {
        D -= h * h * s_inv[i - 1];
        b[i] += h * (s_inv[i - 1] * b[i - 1]);
      }
      s_inv[i] = D.inverse();
    }
    mu[n - 1] = s_inv[n - 1] * b[n - 1];
    M2 sigma = s_inv[n - 1];
    gsg[n - 1] = g[n - 1].dot(sigma * g[n - 1]);
    tr[n - 1] = sigma.trace();
    for (std::size_t i = n - 1; i-- > 0;) {
      mu[i] = s_inv[i] * (b[i] + h * mu[i + 1]);
      const M2 off = h * s_inv[i] * sigma;
      sigma = s_inv[i] + h * off * s_inv[i].transpose();
      sigma = 0.5 * (sigma + sigma.transpose());
      gsg[i] = g[i].dot(sigma * g[i]);
      tr[i] = sigma.trace();
      tr_off[i] = off.trace();
    }
    double rs = 0.0, ds = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (w[i] > 0.0) {
        const double r = y[i] - g[i].dot(mu[i]);
        rs += w[i] * (r * r + s2 * gsg[i]);
      }
      if (i + 1 < n) ds += (mu[i + 1] - mu[i]).squaredNorm() + s2 * (tr[i] + tr[i + 1] - 2.0 * tr_off[i]);
    }
    const double s2_new = rs / sw, tau2_new = ds / (2.0 * static_cast<double>(n - 1));
    if (!(s2_new > 0.0) || !(tau2_new > 0.0) || !std::isfinite(s2_new) || !std::isfinite(tau2_new)) break;
    const bool done = std::abs(s2_new - s2) <= 1e-9 * s2 && std::abs(tau2_new - tau2) <= 1e-9 * tau2;
    s2 = s2_new;
    tau2 = tau2_new;
    if (done) break;
  }
  *s2_io = s2;
  *tau2_io = tau2;
}

// EstimateScales's inputs from a solution: per point with a data term its gradient g (nT/deg), weight w
// (½ at the two ends, the smoother's) and pseudo-observation y = g·ê − r (nT); sw = Σ w.
struct ScaleInputs {
  std::vector<V2> g;
  std::vector<double> w, y;
  double sw = 0.0;
};
ScaleInputs MakeScaleInputs(const std::vector<double>& g_lat, const std::vector<double>& g_lon,
                            const std::vector<double>& resid, const std::vector<char>& data,
                            const std::vector<double>& e_lat, const std::vector<double>& e_lon) {
  const std::size_t n = g_lat.size();
  ScaleInputs in;
  in.g.assign(n, V2::Zero());
  in.w.assign(n, 0.0);
  in.y.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!data[i]) continue;
    in.g[i] = V2(g_lat[i], g_lon[i]);
    in.w[i] = (i == 0 || i == n - 1) ? 0.5 : 1.0;
    in.y[i] = in.g[i].dot(V2(e_lat[i], e_lon[i])) - resid[i];
    in.sw += in.w[i];
  }
  return in;
}

}  // namespace

ErrorCovariance FastMsdErrorCovariance(const std::vector<double>& g_lat, const std::vector<double>& g_lon,
                                       const std::vector<double>& resid, const std::vector<char>& data,
                                       const std::vector<double>& e_lat, const std::vector<double>& e_lon,
                                       const std::vector<double>& h_ll, const std::vector<double>& h_ln,
                                       const std::vector<double>& h_nn, double lambda,
                                       int curvature_iterations, double prior_var_deg2,
                                       const std::vector<double>& map_var_nT2) {
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
  const ScaleInputs in = MakeScaleInputs(g_lat, g_lon, resid, data, e_lat, e_lon);
  const std::vector<V2>& g = in.g;
  const std::vector<double>& w = in.w;
  double s2 = laplace.s2_nT2, tau2 = s2 / h;
  EstimateScales(g, w, in.y, in.sw, &s2, &tau2);
  out.s2_nT2 = s2;
  out.tau2_deg2 = tau2;
  out.edf = laplace.edf;
  // The map's representation error per reading (nT²); none without a data term or when not given.
  std::vector<double> map_var(n, 0.0);
  for (std::size_t i = 0; i < n && map_var_nT2.size() == n; ++i) {
    if (data[i] && std::isfinite(map_var_nT2[i]) && map_var_nT2[i] > 0.0) map_var[i] = map_var_nT2[i];
  }
  std::vector<M2> cov = SmootherErrorCovariance(g, w, h, s2, tau2, h_ll, h_ln, h_nn, curvature_iterations,
                                                map_var, &out.curvature_limited);
  for (std::size_t i = 0; i < n; ++i) {
    out.curvature_limited_points += out.curvature_limited[i] ? 1 : 0;
    cov[i] = 0.5 * (cov[i] + cov[i].transpose());
    out.prior_limited.push_back(CapAtPrior(&cov[i], prior_var_deg2) ? 1 : 0);
    out.prior_limited_points += out.prior_limited[i];
    out.lat_lat[i] = cov[i](0, 0);
    out.lat_lon[i] = cov[i](0, 1);
    out.lon_lon[i] = cov[i](1, 1);
  }
  return out;
}

PathScales EstimatePathScales(const std::vector<double>& g_lat, const std::vector<double>& g_lon,
                              const std::vector<double>& resid, const std::vector<char>& data,
                              const std::vector<double>& e_lat, const std::vector<double>& e_lon, double lambda) {
  PathScales out;
  const std::size_t n = g_lat.size();
  const PathCovariance laplace = FastMsdCovariance(g_lat, g_lon, resid, data, lambda);
  if (n < 2 || !(laplace.s2_nT2 > 0.0) || !std::isfinite(laplace.s2_nT2)) return out;
  const ScaleInputs in = MakeScaleInputs(g_lat, g_lon, resid, data, e_lat, e_lon);
  double s2 = laplace.s2_nT2, tau2 = s2 / (0.5 * lambda);
  EstimateScales(in.g, in.w, in.y, in.sw, &s2, &tau2);
  out.s2_nT2 = s2;
  out.tau2_deg2 = tau2;
  return out;
}

}  // namespace magnav::mapmatch::internal
