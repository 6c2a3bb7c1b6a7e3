// Cramér–Rao lower bound of single-sample dipole localisation with unknown
// moment.
//
// Frames and units: world NED; r_DtoS (m) from the dipole to the sensor, m_W
// (A·m²), σ_B (T per axis), σ_T (T/m per element). Parameters θ = [p_DinW (3);
// m_W (3)], measurement z = [B (3); Txx, Txy, Txz, Tyy, Tyz] with Jacobian
// [−J_z_r, J_z_m] (core DipoleMeasurement; ∂r/∂p_D = −I). Noise: B independent
// σ_B²; tensor off-diagonals σ_T², diagonals Txx, Tyy variance σ_T² with
// correlation −1/2 (symmetric trace-free noise, as in the reference data).
// Fisher information F = Jᵀ R⁻¹ J (6×6).
#pragma once

#include <Eigen/Core>

namespace magnav::inversion {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

Matrix6d SingleSampleFisher(const Eigen::Vector3d& r_DtoS, const Eigen::Vector3d& m_W, double sigma_B,
                            double sigma_T);

// sqrt(trace of the position block of F⁻¹): the bound on the RMS 3-D position
// error of any unbiased single-sample estimator (m). Infinity if F is singular.
double PositionCrlb(const Eigen::Vector3d& r_DtoS, const Eigen::Vector3d& m_W, double sigma_B, double sigma_T);

}  // namespace magnav::inversion
