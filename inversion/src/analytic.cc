#include "magnav/inversion/analytic.h"

#include <algorithm>
#include <cmath>

#include "magnav/core/tensor.h"
#include "magnav/core/units.h"

namespace magnav::inversion {
namespace {

bool FiniteInput(const Mat3& T, const Vec3& dB) { return T.allFinite() && dB.allFinite(); }

// Variance per component of the Euler-row error e = δT r + 3 δB, ≈ σ_T² |r|² +
// 9 σ_B² (independent elements): isotropic, so Vᵀ e has the same variance.
// NaN when neither sigma is known.
double EulerRowVariance(double r_norm, const NoiseSigmas& noise) {
  if (!(noise.sigma_B > 0.0) && !(noise.sigma_T > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return noise.sigma_T * noise.sigma_T * r_norm * r_norm + 9.0 * noise.sigma_B * noise.sigma_B;
}

// Shared core of TED and TED+EGT in T's eigenbasis. row_weight < 0 means
// plain TED (no fourth row).
bool SolveInEigenbasis(const Mat3& T, const Vec3& dB, double row_weight, const NoiseSigmas& noise,
                       AnalyticSolution* out) {
  if (!FiniteInput(T, dB)) return false;
  const double s = T.norm();
  if (!(s > 0.0) || !std::isfinite(s)) return false;
  const SortedEigen eig = SortedEigenDecomposition(T);
  if (!eig.values.allFinite()) return false;
  const int k = eig.SmallestMagnitudeIndex();
  const Vec3 lam = eig.values / s;  // scaled eigenvalues, Σλ² = 1 for symmetric T
  const Vec3 c = eig.vectors.transpose() * (dB / s);
  Vec3 y, gain;  // gain in unscaled units: m per (T) of Euler-row error
  double sv_min = std::numeric_limits<double>::infinity(), sv_max = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double w2 = (row_weight >= 0.0 && i == k) ? row_weight * row_weight : 0.0;
    const double d = lam[i] * lam[i] + w2;  // squared singular value
    const double sv = std::sqrt(d);
    sv_min = std::min(sv_min, sv);
    sv_max = std::max(sv_max, sv);
    if (d > 0.0) {
      y[i] = -3.0 * lam[i] * c[i] / d;
      gain[i] = lam[i] / d / s;
    } else {  // pseudo-inverse: a zero singular value contributes nothing
      y[i] = 0.0;
      gain[i] = 0.0;
    }
  }
  if (!(sv_min > 0.0)) {  // singular: no unique solution
    out->cond = std::numeric_limits<double>::infinity();
    return false;
  }
  out->r_DtoS = eig.vectors * y;
  out->has_moment = false;
  out->cond = sv_max / sv_min;
  // r = V y with y_i = g_i (Vᵀ e)_i: cov r = V diag(g_i² var_e) Vᵀ.
  const double var_e = EulerRowVariance(out->r_DtoS.norm(), noise);
  Vec3 var_y = gain.cwiseAbs2() * var_e;
  if (row_weight > 0.0 && noise.sigma_T > 0.0 && std::isfinite(var_e)) {
    // The eigenvector row is noisy too: to first order b3 tilts by
    // Σ_j (v_jᵀ δT b3)/(λ_k − λ_j) v_j, so b3ᵀ r errs by ε with
    // var ε = σ_T² Σ_{j≠k} y_j² / (λ_k − λ_j)², and y_k takes the share
    // w² / (λ_k²/s² + w²) of it.
    double var_eps = 0.0;
    for (int j = 0; j < 3; ++j) {
      if (j == k) continue;
      const double gap = eig.values[k] - eig.values[j];
      var_eps += y[j] * y[j] / (gap * gap);
    }
    var_eps *= noise.sigma_T * noise.sigma_T;
    const double w2 = row_weight * row_weight;
    const double share = w2 / (lam[k] * lam[k] + w2);
    var_y[k] += share * share * var_eps;
  }
  out->cov_r = eig.vectors * var_y.asDiagonal() * eig.vectors.transpose();
  out->position_sigma_3d_m = std::sqrt(var_y.sum());
  return out->r_DtoS.allFinite();
}

}  // namespace

bool SolveTed(const Mat3& T, const Vec3& dB_W, const NoiseSigmas& noise, AnalyticSolution* out) {
  return SolveInEigenbasis(T, dB_W, -1.0, noise, out);
}

bool SolveTedEgt(const Mat3& T, const Vec3& dB_W, double egt_row_weight, const NoiseSigmas& noise,
                 AnalyticSolution* out) {
  if (!(egt_row_weight >= 0.0) || !std::isfinite(egt_row_weight)) return false;
  return SolveInEigenbasis(T, dB_W, egt_row_weight, noise, out);
}

bool SolveEgt(const Mat3& T, const Vec3& dB_W, const NoiseSigmas& noise, AnalyticSolution* out) {
  if (!FiniteInput(T, dB_W)) return false;
  const double s = T.norm();
  if (!(s > 0.0) || !std::isfinite(s) || !(dB_W.squaredNorm() > 0.0)) return false;
  const SortedEigen eig = SortedEigenDecomposition(T);
  if (!eig.values.allFinite()) return false;
  // Ascending order from core: λ3 = values[0], λ2 = values[1], λ1 = values[2].
  const double l1 = eig.values[2] / s, l2 = eig.values[1] / s, l3 = eig.values[0] / s;
  const Vec3 e1 = eig.vectors.col(2), e3 = eig.vectors.col(0);
  const double mu1 = l1 - l2, mu3 = l3 - l2;
  const double span = mu1 - mu3;
  if (!(span > 0.0)) return false;
  const double a = std::sqrt(std::max(0.0, mu1 / span));
  const double b = std::sqrt(std::max(0.0, -mu3 / span));
  const Mat3 Ts = 0.5 * (T + T.transpose()) / s;
  const Vec3 dBs = dB_W / s;

  double best_residual = std::numeric_limits<double>::infinity();
  Vec3 best_n = Vec3::Zero();
  double best_rho = 0.0;
  for (const double sign : {1.0, -1.0}) {
    const Vec3 n = (a * e1 + sign * b * e3).normalized();
    const Vec3 Tn = Ts * n;
    const double tn2 = Tn.squaredNorm();
    if (!(tn2 > 0.0)) continue;
    const double rho = -3.0 * Tn.dot(dBs) / tn2;
    const double residual = (rho * Tn + 3.0 * dBs).squaredNorm();
    if (residual < best_residual) {
      best_residual = residual;
      best_n = n;
      best_rho = rho;
    }
  }
  if (!std::isfinite(best_residual) || best_rho == 0.0) return false;
  const Vec3 n = best_rho > 0.0 ? best_n : Vec3(-best_n);
  const double rho = std::abs(best_rho);
  out->r_DtoS = rho * n;
  // M = T n + 3 λ2 n (unscaled, T/m); m = 4π ρ⁴ M / (3 μ0) = ρ⁴ M / (3 μ0/4π).
  const Vec3 M = s * (Ts * n + 3.0 * l2 * n);
  out->m_W = std::pow(rho, 4) * M / (3.0 * kMu0Over4Pi);
  out->has_moment = true;
  out->cond = eig.ConditionNumber();
  // Error propagation proxy: the Euler rows with the eigenvector row at weight 1.
  AnalyticSolution proxy;
  if (SolveInEigenbasis(T, dB_W, 1.0, noise, &proxy)) {
    out->cov_r = proxy.cov_r;
    out->position_sigma_3d_m = proxy.position_sigma_3d_m;
  }
  return out->r_DtoS.allFinite() && out->m_W.allFinite();
}

}  // namespace magnav::inversion
