#include "magnav/localizer/cost_functions.h"

#include "magnav/localizer/models.h"

namespace magnav::localizer {

namespace {
using RowMajor3x5 = Eigen::Matrix<double, 3, 5, Eigen::RowMajor>;
using RowMajor3x2 = Eigen::Matrix<double, 3, 2, Eigen::RowMajor>;
using RowMajor5x5 = Eigen::Matrix<double, 5, 5, Eigen::RowMajor>;
using RowMajor2x5 = Eigen::Matrix<double, 2, 5, Eigen::RowMajor>;
using RowMajor2x2 = Eigen::Matrix<double, 2, 2, Eigen::RowMajor>;
}  // namespace

MagnetometerCost::MagnetometerCost(const Vessel& vessel, double sensor_z_m, const Eigen::Vector3d& B_measured_T,
                                   double sigma_B_T)
    : vessel_(vessel), sensor_z_m_(sensor_z_m), B_T_(B_measured_T), inv_sigma_(1.0 / sigma_B_T) {}

bool MagnetometerCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const Eigen::Map<const VesselVector> x(parameters[0]);
  const Eigen::Vector3d p_S(parameters[1][0], parameters[1][1], sensor_z_m_);
  Jacobian3x5 J_x;
  Jacobian3x2 J_s;
  const bool want = jacobians != nullptr;
  const Eigen::Vector3d B = VesselFieldAtSensor(x, vessel_, p_S, want ? &J_x : nullptr, want ? &J_s : nullptr);
  Eigen::Map<Eigen::Vector3d>{residuals} = (B - B_T_) * inv_sigma_;
  if (want) {
    if (jacobians[0] != nullptr) Eigen::Map<RowMajor3x5>{jacobians[0]} = J_x * inv_sigma_;
    if (jacobians[1] != nullptr) Eigen::Map<RowMajor3x2>{jacobians[1]} = J_s * inv_sigma_;
  }
  return B.allFinite();
}

MotionCost::MotionCost(double dt_s, const LocalizerProcessNoise& q) : dt_s_(dt_s) {
  w_ = ProcessCovariance(q, dt_s).diagonal().cwiseSqrt().cwiseInverse();
}

bool MotionCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const Eigen::Map<const VesselVector> x0(parameters[0]);
  const Eigen::Map<const VesselVector> x1(parameters[1]);
  VesselCovariance F;
  const VesselVector predicted = PropagateVessel(x0, dt_s_, &F);
  Eigen::Map<VesselVector>{residuals} = w_.cwiseProduct(x1 - predicted);
  if (jacobians != nullptr) {
    if (jacobians[0] != nullptr) Eigen::Map<RowMajor5x5>{jacobians[0]} = -(w_.asDiagonal() * F);
    if (jacobians[1] != nullptr) {
      Eigen::Map<RowMajor5x5>{jacobians[1]} = VesselCovariance(w_.asDiagonal());
    }
  }
  return predicted.allFinite();
}

GnssCost::GnssCost(const Eigen::Vector2d& p_xy_m, double sigma_m) : p_(p_xy_m), inv_sigma_(1.0 / sigma_m) {}

bool GnssCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  Eigen::Map<Eigen::Vector2d>{residuals} = (Eigen::Vector2d(parameters[0][0], parameters[0][1]) - p_) * inv_sigma_;
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    Eigen::Map<RowMajor2x5> J(jacobians[0]);
    J.setZero();
    J(0, kX) = J(1, kY) = inv_sigma_;
  }
  return true;
}

SensorPriorCost::SensorPriorCost(const Eigen::Vector2d& p_xy_m, double sigma_m)
    : p_(p_xy_m), inv_sigma_(1.0 / sigma_m) {}

bool SensorPriorCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  Eigen::Map<Eigen::Vector2d>{residuals} = (Eigen::Vector2d(parameters[0][0], parameters[0][1]) - p_) * inv_sigma_;
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    Eigen::Map<RowMajor2x2>{jacobians[0]} = inv_sigma_ * Eigen::Matrix2d::Identity();
  }
  return true;
}

}  // namespace magnav::localizer
