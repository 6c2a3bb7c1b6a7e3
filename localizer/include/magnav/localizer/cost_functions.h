// Residuals of the batch smoother (and of the information behind its
// covariance and the Cramér–Rao bounds), as Ceres cost functions with
// analytic Jacobians. Every residual is whitened (units of σ).
//
// Parameter blocks: a vessel state [x, y, v, heading, turn rate] (5; m, m,
// m/s, rad, rad/s) and a sensor's horizontal position [x, y] (2; m); frames
// and units as types.h (NED, SI).
#pragma once

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>

#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer {

// e = (B(x, s) − B_measured) / σ_B: the vessel's dipole field at the sensor
// (models.h VesselFieldAtSensor). Blocks: vessel state, sensor (x, y).
class MagnetometerCost final : public ceres::SizedCostFunction<3, 5, 2> {
 public:
  MagnetometerCost(const Vessel& vessel, double sensor_z_m, const Eigen::Vector3d& B_measured_T, double sigma_B_T);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  Vessel vessel_;
  double sensor_z_m_;
  Eigen::Vector3d B_T_;
  double inv_sigma_;
};

// e = W (x₁ − f(x₀, dt)), W = (Q dt)^(−1/2): the coordinated-turn model
// (models.h PropagateVessel, ProcessCovariance). Blocks: x₀, x₁.
class MotionCost final : public ceres::SizedCostFunction<5, 5, 5> {
 public:
  MotionCost(double dt_s, const LocalizerProcessNoise& q);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  double dt_s_;
  Eigen::Matrix<double, 5, 1> w_;  // diagonal of W
};

// e = (p_xy(x) − fix) / σ. Block: vessel state.
class GnssCost final : public ceres::SizedCostFunction<2, 5> {
 public:
  GnssCost(const Eigen::Vector2d& p_xy_m, double sigma_m);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  Eigen::Vector2d p_;
  double inv_sigma_;
};

// e = (s − s_deployed) / σ_deploy. Block: sensor (x, y).
class SensorPriorCost final : public ceres::SizedCostFunction<2, 2> {
 public:
  SensorPriorCost(const Eigen::Vector2d& p_xy_m, double sigma_m);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  Eigen::Vector2d p_;
  double inv_sigma_;
};

}  // namespace magnav::localizer
