#include "magnav/core/dipole.h"

#include <cmath>

#include <Eigen/Dense>

#include "magnav/core/units.h"

namespace magnav {

Vec3 DipoleB(const Vec3& r, const Vec3& m, Mat3* J_B_r, Mat3* J_B_m) {
  Vec3 B;
  DipoleBT(r, m, &B, J_B_r);  // ∂B/∂r = T
  if (J_B_m) {
    const double inv_r2 = 1.0 / r.squaredNorm();
    const double inv_r3 = inv_r2 * std::sqrt(inv_r2);
    *J_B_m = kMu0Over4Pi * (3.0 * inv_r3 * inv_r2 * r * r.transpose() - inv_r3 * Mat3::Identity());
  }
  return B;
}

Mat3 DipoleT(const Vec3& r, const Vec3& m) {
  Mat3 T;
  DipoleBT(r, m, nullptr, &T);
  return T;
}

void DipoleBT(const Vec3& r, const Vec3& m, Vec3* B, Mat3* T) {
  const double r2 = r.squaredNorm();
  const double inv_r2 = 1.0 / r2;
  const double inv_r = std::sqrt(inv_r2);
  const double inv_r3 = inv_r2 * inv_r;
  const double inv_r5 = inv_r3 * inv_r2;
  const double mr = m.dot(r);
  if (B) *B = kMu0Over4Pi * (3.0 * mr * inv_r5 * r - inv_r3 * m);
  if (T) {
    const double a = 3.0 * kMu0Over4Pi * inv_r5;
    const double c = -5.0 * mr * inv_r2;
    for (int i = 0; i < 3; ++i) {
      for (int j = i; j < 3; ++j) {
        double v = m[i] * r[j] + m[j] * r[i] + c * r[i] * r[j];
        if (i == j) v += mr;
        (*T)(i, j) = a * v;
        (*T)(j, i) = (*T)(i, j);
      }
    }
  }
}

namespace {
// Packed tensor component index -> (i, j).
constexpr int kPackI[5] = {0, 0, 0, 1, 1};
constexpr int kPackJ[5] = {0, 1, 2, 1, 2};
}  // namespace

Measurement8 DipoleMeasurement(const Vec3& r, const Vec3& m, Jacobian8x3* J_z_r,
                               Jacobian8x3* J_z_m) {
  const double r2 = r.squaredNorm();
  const double inv_r2 = 1.0 / r2;
  const double inv_r = std::sqrt(inv_r2);
  const double inv_r3 = inv_r2 * inv_r;
  const double inv_r5 = inv_r3 * inv_r2;
  const double inv_r7 = inv_r5 * inv_r2;
  const double inv_r9 = inv_r7 * inv_r2;
  const double mr = m.dot(r);
  const double k = kMu0Over4Pi;

  Vec3 B;
  Mat3 T;
  DipoleBT(r, m, &B, &T);
  Measurement8 z;
  z.head<3>() = B;
  for (int p = 0; p < 5; ++p) z[3 + p] = T(kPackI[p], kPackJ[p]);

  if (J_z_r) {
    J_z_r->topRows<3>() = T;  // ∂B/∂r = T
    // ∂T_ij/∂r_l = k [ 3δ_ij (m_l/r⁵ − 5 (m·r) r_l/r⁷)
    //               + 3 (m_i δ_jl + m_j δ_il)/r⁵ − 15 (m_i r_j + m_j r_i) r_l/r⁷
    //               − 15 (m_l r_i r_j + (m·r)(δ_il r_j + r_i δ_jl))/r⁷
    //               + 105 (m·r) r_i r_j r_l / r⁹ ]
    for (int p = 0; p < 5; ++p) {
      const int i = kPackI[p], j = kPackJ[p];
      for (int l = 0; l < 3; ++l) {
        const double dil = (i == l), djl = (j == l), dij = (i == j);
        double v = 3.0 * dij * (m[l] * inv_r5 - 5.0 * mr * r[l] * inv_r7);
        v += 3.0 * (m[i] * djl + m[j] * dil) * inv_r5;
        v -= 15.0 * (m[i] * r[j] + m[j] * r[i]) * r[l] * inv_r7;
        v -= 15.0 * (m[l] * r[i] * r[j] + mr * (dil * r[j] + r[i] * djl)) * inv_r7;
        v += 105.0 * mr * r[i] * r[j] * r[l] * inv_r9;
        (*J_z_r)(3 + p, l) = k * v;
      }
    }
  }
  if (J_z_m) {
    // ∂B_i/∂m_l = k (3 r_i r_l / r⁵ − δ_il / r³)
    // ∂T_ij/∂m_l = k [3 δ_ij r_l/r⁵ + 3 (δ_il r_j + δ_jl r_i)/r⁵ − 15 r_i r_j r_l / r⁷]
    J_z_m->topRows<3>() = k * (3.0 * inv_r5 * r * r.transpose() - inv_r3 * Mat3::Identity());
    for (int p = 0; p < 5; ++p) {
      const int i = kPackI[p], j = kPackJ[p];
      for (int l = 0; l < 3; ++l) {
        const double dil = (i == l), djl = (j == l), dij = (i == j);
        (*J_z_m)(3 + p, l) = k * (3.0 * dij * r[l] * inv_r5 + 3.0 * (dil * r[j] + djl * r[i]) * inv_r5 -
                                  15.0 * r[i] * r[j] * r[l] * inv_r7);
      }
    }
  }
  return z;
}

bool FitDipoleMoment(const Vec3& r, const Vec3& B, const Mat3& T, double sigma_B, double sigma_T,
                     Vec3* m_W) {
  if (!r.allFinite() || !B.allFinite() || !T.allFinite() || r.squaredNorm() == 0.0) return false;
  Jacobian8x3 A;
  DipoleMeasurement(r, Vec3::UnitX(), nullptr, &A);  // z = A m (linear in m)
  Measurement8 z;
  z.head<3>() = B;
  z.tail<5>() = PackTensor5(T);
  // Weights: 1/σ per row when both σ are known. Otherwise only their ratio
  // matters, and an unknown σ is replaced by the known one scaled by the
  // natural ratio of the rows (T ~ B/|r|, so σ_T ≈ σ_B/|r|): a known σ_B of
  // 1e-9 T must not meet a weight 1 on the T rows (1e9 against 1).
  const double rn = r.norm();
  double sB = sigma_B > 0.0 ? sigma_B : 0.0, sT = sigma_T > 0.0 ? sigma_T : 0.0;
  if (sB == 0.0 && sT == 0.0) {
    sB = 1.0;
    sT = 1.0 / rn;
  } else if (sB == 0.0) {
    sB = sT * rn;
  } else if (sT == 0.0) {
    sT = sB / rn;
  }
  const double wB = 1.0 / sB;
  const double wT = 1.0 / sT;
  A.topRows<3>() *= wB;
  z.head<3>() *= wB;
  A.bottomRows<5>() *= wT;
  z.tail<5>() *= wT;
  Eigen::ColPivHouseholderQR<Jacobian8x3> qr(A);
  if (qr.rank() < 3) return false;
  *m_W = qr.solve(z);
  return m_W->allFinite();
}

}  // namespace magnav
