#include <Eigen/Cholesky>

#include "magnav/core/frames.h"
#include "magnav/core/motion.h"
#include "magnav/core/tensor.h"
#include "magnav/tracker/cost_functions.h"

namespace magnav::tracker {

SqrtInfo8 MeasurementSqrtInfo(double sigma_B, double sigma_T, bool trace_free) {
  Eigen::Matrix<double, 8, 8> cov = Eigen::Matrix<double, 8, 8>::Zero();
  cov.diagonal().head<3>().setConstant(sigma_B * sigma_B);
  cov.diagonal().tail<5>().setConstant(sigma_T * sigma_T);
  if (trace_free) {
    // Packed order [Bx By Bz Txx Txy Txz Tyy Tyz]: Txx is 3, Tyy is 6.
    cov(3, 6) = cov(6, 3) = -0.5 * sigma_T * sigma_T;
  }
  // Information = cov⁻¹ = LᵀL with L upper triangular: from the Cholesky
  // factor of the information matrix.
  const Eigen::Matrix<double, 8, 8> info = cov.inverse();
  const Eigen::LLT<Eigen::Matrix<double, 8, 8>> llt(info);
  return llt.matrixU();
}

MeasurementCost::MeasurementCost(const GradiometerSample& sample, const Eigen::Vector3d& B0_W,
                                 const SqrtInfo8& sqrt_info, double moment_scale_Am2)
    : p_SinW_(sample.p_SinW), sqrt_info_(sqrt_info), moment_scale_(moment_scale_Am2) {
  B_minus_B0_ = sample.B - B0_W;
  z_.head<3>() = B_minus_B0_;
  z_.tail<5>() = PackTensor5(sample.T);
}

bool MeasurementCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const double* state = parameters[0];
  const Eigen::Vector3d p_VinW(state[0], state[1], state[2]);
  const double heading = state[4];
  const Eigen::Vector3d m_B = moment_scale_ * Eigen::Map<const Eigen::Vector3d>(parameters[1]);
  const Eigen::Vector3d r_DtoS = p_SinW_ - p_VinW;
  if (!(r_DtoS.squaredNorm() > 1e-12)) return false;

  Eigen::Vector3d J_mW_h;
  const Eigen::Vector3d m_W = WorldMoment(m_B, heading, &J_mW_h);
  Jacobian8x3 J_z_r, J_z_m;
  const bool want_J = jacobians != nullptr && (jacobians[0] != nullptr || jacobians[1] != nullptr);
  const Measurement8 pred =
      DipoleMeasurement(r_DtoS, m_W, want_J ? &J_z_r : nullptr, want_J ? &J_z_m : nullptr);
  Eigen::Map<Eigen::Matrix<double, 8, 1>> e(residuals);
  // lazyProduct: coefficient-based kernels for these small fixed sizes.
  e = sqrt_info_.lazyProduct(pred - z_);
  if (!field_used_) e.head<3>().setZero();
  if (!want_J) return true;

  if (jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 8, 6, Eigen::RowMajor>> J(jacobians[0]);
    J.setZero();
    J.leftCols<3>() = -sqrt_info_.lazyProduct(J_z_r);  // ∂r/∂p_V = −I
    J.col(4) = sqrt_info_.lazyProduct(J_z_m.lazyProduct(J_mW_h));
    if (!field_used_) J.topRows<3>().setZero();
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 8, 3, Eigen::RowMajor>> J(jacobians[1]);
    J = sqrt_info_.lazyProduct(J_z_m).lazyProduct(HeadingRotation(heading) * moment_scale_);
    if (!field_used_) J.topRows<3>().setZero();
  }
  return true;
}

Eigen::Vector3d MeasurementCost::BResidual(double const* const* parameters) const {
  const double* state = parameters[0];
  const Eigen::Vector3d m_B = moment_scale_ * Eigen::Map<const Eigen::Vector3d>(parameters[1]);
  const Eigen::Vector3d m_W = HeadingRotation(state[4]) * m_B;
  const Eigen::Vector3d r_DtoS = p_SinW_ - Eigen::Vector3d(state[0], state[1], state[2]);
  const Measurement8 pred = DipoleMeasurement(r_DtoS, m_W, nullptr, nullptr);
  return z_.head<3>() - pred.head<3>();
}

KinematicCost::KinematicCost(double dt_s, double sigma_p, double sigma_v, double sigma_h, double sigma_depth)
    : dt_(dt_s) {
  const double root_dt = std::sqrt(dt_s);
  w_ << 1.0 / (sigma_p * root_dt), 1.0 / (sigma_p * root_dt), 1.0 / (sigma_depth * root_dt),
      1.0 / (sigma_v * root_dt), 1.0 / (sigma_h * root_dt);
}

bool KinematicCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const double* s0 = parameters[0];
  const double* s1 = parameters[1];
  const CtState<double> a{s0[0], s0[1], s0[2], s0[3], s0[4], s0[5]};
  const CtState<double> p = PropagateCoordinatedTurn(a, dt_);
  residuals[0] = (s1[0] - p.x) * w_(0);
  residuals[1] = (s1[1] - p.y) * w_(1);
  residuals[2] = (s1[2] - p.z) * w_(2);
  residuals[3] = (s1[3] - s0[3]) * w_(3);
  residuals[4] = (s1[4] - p.heading) * w_(4);
  if (jacobians == nullptr) return true;
  // Residual rows are rows (x, y, z, v, heading) of x_{k+1} − f(x_k), weighted.
  static constexpr int kRows[5] = {0, 1, 2, 3, 4};
  if (jacobians[0] != nullptr) {
    const Eigen::Matrix<double, 6, 6> F = CoordinatedTurnJacobian(a, dt_);
    Eigen::Map<Eigen::Matrix<double, 5, 6, Eigen::RowMajor>> J(jacobians[0]);
    for (int r = 0; r < 5; ++r) J.row(r) = -w_(r) * F.row(kRows[r]);
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 5, 6, Eigen::RowMajor>> J(jacobians[1]);
    J.setZero();
    for (int r = 0; r < 5; ++r) J(r, kRows[r]) = w_(r);
  }
  return true;
}

bool TurnRateCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  residuals[0] = (parameters[1][5] - parameters[0][5]) * w_;
  if (jacobians != nullptr) {
    for (int b = 0; b < 2; ++b) {
      if (jacobians[b] == nullptr) continue;
      for (int i = 0; i < 6; ++i) jacobians[b][i] = 0.0;
      jacobians[b][5] = b == 0 ? -w_ : w_;
    }
  }
  return true;
}

bool PriorCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  Eigen::Matrix<double, 9, 1> x;
  x.head<6>() = Eigen::Map<const Eigen::Matrix<double, 6, 1>>(parameters[0]);
  x.tail<3>() = Eigen::Map<const Eigen::Vector3d>(parameters[1]);
  Eigen::Map<Eigen::Matrix<double, 9, 1>> e(residuals);
  e = L_ * (x - x_bar_) + c_;
  if (jacobians != nullptr) {
    if (jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 9, 6, Eigen::RowMajor>> J(jacobians[0]);
      J = L_.leftCols<6>();
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 9, 3, Eigen::RowMajor>> J(jacobians[1]);
      J = L_.rightCols<3>();
    }
  }
  return true;
}

}  // namespace magnav::tracker
