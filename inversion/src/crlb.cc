#include "magnav/inversion/crlb.h"

#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "magnav/core/dipole.h"

namespace magnav::inversion {

Matrix6d SingleSampleFisher(const Eigen::Vector3d& r_DtoS, const Eigen::Vector3d& m_W, double sigma_B,
                            double sigma_T) {
  Jacobian8x3 J_z_r, J_z_m;
  DipoleMeasurement(r_DtoS, m_W, &J_z_r, &J_z_m);
  Eigen::Matrix<double, 8, 6> J;
  J.leftCols<3>() = -J_z_r;  // ∂z/∂p_D
  J.rightCols<3>() = J_z_m;
  Eigen::Matrix<double, 8, 8> R = Eigen::Matrix<double, 8, 8>::Zero();
  R.topLeftCorner<3, 3>().diagonal().setConstant(sigma_B * sigma_B);
  const double v = sigma_T * sigma_T;
  // Packed order Txx(3), Txy(4), Txz(5), Tyy(6), Tyz(7).
  for (int k = 3; k < 8; ++k) R(k, k) = v;
  R(3, 6) = R(6, 3) = -0.5 * v;
  return J.transpose() * R.ldlt().solve(J);
}

double PositionCrlb(const Eigen::Vector3d& r_DtoS, const Eigen::Vector3d& m_W, double sigma_B,
                    double sigma_T) {
  const Matrix6d F = SingleSampleFisher(r_DtoS, m_W, sigma_B, sigma_T);
  // Scale the parameters so F is well conditioned before inverting.
  const Eigen::Matrix<double, 6, 1> d = F.diagonal().cwiseSqrt();
  if (!(d.minCoeff() > 0.0) || !d.allFinite()) return std::numeric_limits<double>::infinity();
  const Matrix6d Fs = d.cwiseInverse().asDiagonal() * F * d.cwiseInverse().asDiagonal();
  Eigen::LDLT<Matrix6d> ldlt(Fs);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0.0)) {
    return std::numeric_limits<double>::infinity();
  }
  const Matrix6d cov = d.cwiseInverse().asDiagonal() * ldlt.solve(Matrix6d::Identity()) *
                       d.cwiseInverse().asDiagonal();
  return std::sqrt(cov.topLeftCorner<3, 3>().trace());
}

}  // namespace magnav::inversion
