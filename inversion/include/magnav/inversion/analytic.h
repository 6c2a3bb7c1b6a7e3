// Single-sample analytic dipole inversion (no gates): tensor Euler
// deconvolution (TED), TED with the eigenvector row (TED+EGT), and the
// closed-form eigen-analysis (EGT) disambiguated by B.
//
// Frames and units: every vector and tensor is in the world NED frame (the
// gradiometer axes are assumed aligned with NED). T is the measured gradient
// tensor T_ij = ∂B_i/∂x_j in T/m, dB_W = B − B0 the anomaly field in T (B0 the
// regional field). The result r_DtoS = p_S − p_D (m) points from the dipole to
// the sensor, so the dipole is at p_D = p_S − r_DtoS. Moments in A·m².
//
// All solvers work on T/‖T‖_F (and dB/‖T‖_F), so their precision does not
// depend on the units or magnitude of the signal. They use the symmetric part
// of T; reject asymmetric samples before calling them (see inverter.h).
#pragma once

#include <limits>

#include <Eigen/Core>

namespace magnav::inversion {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

struct AnalyticSolution {
  Vec3 r_DtoS = Vec3::Zero();  // m, from the dipole to the sensor
  Vec3 m_W = Vec3::Zero();     // A·m², world NED (only when has_moment)
  bool has_moment = false;     // EGT yields the moment in closed form; TED(+EGT) do not
  // Condition number of the linear system the method solved:
  //   TED:     cond(T) = |λ|max / |λ|min;
  //   TED+EGT: σmax/σmin of the scaled 4×3 matrix [T/‖T‖_F; w b3ᵀ];
  //   EGT:     cond(T) (informative; EGT does not invert T).
  double cond = std::numeric_limits<double>::infinity();
  // First-order covariance of r_DtoS (and so of the dipole position), m²,
  // world NED, from σ_B, σ_T propagated through the Euler rows
  // (δr = −A⁺ [δT r + 3 δB; 0]) and the eigenvector row; NaN when no sigmas
  // were given.
  Mat3 cov_r = Mat3::Constant(std::numeric_limits<double>::quiet_NaN());
  // The 3-D RMS 1-σ error sqrt(trace cov_r), m (NOT a per-axis σ: for an
  // isotropic error each axis has σ = position_sigma_3d_m/√3).
  double position_sigma_3d_m = std::numeric_limits<double>::quiet_NaN();
};

// Noise levels used for cov_r (0 = unknown).
struct NoiseSigmas {
  double sigma_B = 0.0;  // T per axis
  double sigma_T = 0.0;  // T/m per element
};

// TED: r = −3 T⁻¹ dB. Returns false for a non-finite or exactly singular T.
bool SolveTed(const Mat3& T, const Vec3& dB_W, const NoiseSigmas& noise, AnalyticSolution* out);

// TED+EGT: least-squares (Moore–Penrose) solution of
//   [T/s; w b3ᵀ] r = [−3 dB/s; 0],  s = ‖T‖_F,
// b3 the unit eigenvector of the eigenvalue of smallest magnitude (⊥ r for a
// dipole), w = egt_row_weight (relative to the unit-norm scaled tensor rows).
// The pseudo-inverse is applied in T's eigenbasis, where the 4×3 matrix has
// orthogonal columns and its SVD is explicit: singular values
// sqrt(λ_i²/s² + w² δ_ik). Returns false for non-finite input or T = 0.
bool SolveTedEgt(const Mat3& T, const Vec3& dB_W, double egt_row_weight, const NoiseSigmas& noise,
                 AnalyticSolution* out);

// EGT closed form. With λ1 ≥ λ2 ≥ λ3 the eigenvalues (λ2 = M·n is the middle
// one), μ1 = λ1 − λ2 ≥ 0, μ3 = λ3 − λ2 ≤ 0 and e1, e3 the eigenvectors:
//   n = ± sqrt(μ1/(μ1−μ3)) e1 ± sqrt(−μ3/(μ1−μ3)) e3     (two lines, ± each)
// For each line, Euler's relation T (ρ n) = −3 dB gives the least-squares
// range ρ = −3 (T n)·dB / |T n|²; the line with the smaller Euler residual
// wins and the sign of ρ orients n (r = ρ n). The moment follows from
// M = T n + 3 λ2 n and m = 4π ρ⁴ M / (3 μ0) with n = r/|r|.
// Returns false for non-finite input, T = 0 or dB = 0.
bool SolveEgt(const Mat3& T, const Vec3& dB_W, const NoiseSigmas& noise, AnalyticSolution* out);

}  // namespace magnav::inversion
