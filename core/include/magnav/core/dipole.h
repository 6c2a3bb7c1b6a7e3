// Magnetic dipole forward model: flux density B and gradient tensor T at a
// sensor, with analytic Jacobians.
//
// Frames and units: every vector is in the same Cartesian frame (the world NED
// frame unless stated otherwise). r_DtoS = p_S − p_D is the vector from the
// dipole to the sensor in metres, m the dipole moment in A·m², B in tesla,
// T_ij = ∂B_i/∂x_j in tesla per metre (derivative with respect to the sensor
// position).
//
//   B    = μ0/4π [ 3 (m·r) r / r⁵ − m / r³ ]
//   T_ij = μ0/4π [ 3 δ_ij (m·r)/r⁵ + 3 (m_i r_j + m_j r_i)/r⁵ − 15 (m·r) r_i r_j / r⁷ ]
//
// T is symmetric and trace-free, and Euler's homogeneity gives T r = −3 B.
// Moving the dipole by δp changes r by −δp, so J_B_pD = −J_B_r.
#pragma once

#include <Eigen/Dense>

#include "magnav/core/tensor.h"

namespace magnav {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

// Field vector B (T) of a dipole with moment m_W (A·m²) at offset r_DtoS (m).
// Optional Jacobians: J_B_r = ∂B/∂r (= T), J_B_m = ∂B/∂m. r must be non-zero.
Vec3 DipoleB(const Vec3& r_DtoS, const Vec3& m_W, Mat3* J_B_r = nullptr, Mat3* J_B_m = nullptr);

// Gradient tensor T (T/m) of a dipole.
Mat3 DipoleT(const Vec3& r_DtoS, const Vec3& m_W);

// B and T at once (cheaper than the two calls).
void DipoleBT(const Vec3& r_DtoS, const Vec3& m_W, Vec3* B, Mat3* T);

// The 8-vector measurement of a gradiometer: [B (3, T); packed T (5, T/m)],
// packing as in tensor.h (Txx, Txy, Txz, Tyy, Tyz).
using Measurement8 = Eigen::Matrix<double, 8, 1>;
using Jacobian8x3 = Eigen::Matrix<double, 8, 3>;

// Measurement and its analytic Jacobians with respect to r_DtoS and m_W
// (either may be null). The T rows of J_z_r are third derivatives of the
// dipole potential.
Measurement8 DipoleMeasurement(const Vec3& r_DtoS, const Vec3& m_W, Jacobian8x3* J_z_r = nullptr,
                               Jacobian8x3* J_z_m = nullptr);

// Moment (A·m²) that best explains a measured B (T) and T (T/m) with a dipole at
// offset r_DtoS, by linear least squares on the 8 measurement rows weighted by
// 1/sigma_B and 1/sigma_T (the model is linear in m; a sigma of 0 = unknown is
// taken from the other as σ_T = σ_B/|r|, both unknown: that ratio with σ_B = 1).
// Returns false if the
// 8×3 system is rank deficient (r = 0 or non-finite input).
bool FitDipoleMoment(const Vec3& r_DtoS, const Vec3& B, const Mat3& T, double sigma_B,
                     double sigma_T, Vec3* m_W);

}  // namespace magnav
