// Process and measurement models of the sensor localiser, with analytic
// Jacobians, built on core's coordinated-turn kinematics (core/motion.h) and
// dipole field (core/dipole.h, core/frames.h).
//
// Frames and units: world NED (x north, y east, z down), metres, seconds,
// tesla, A·m², radians. Vessel state x = [x, y, v, heading, turn rate] (see
// types.h); the vessel's depth is known (Vessel::z_m), as is each sensor's.
#pragma once

#include <Eigen/Core>

#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer {

using Jacobian3x5 = Eigen::Matrix<double, 3, 5>;
using Jacobian3x2 = Eigen::Matrix<double, 3, 2>;

// Coordinated-turn prediction of the vessel state over dt seconds (exact,
// smooth through ω → 0); optional F = ∂f/∂x (5×5).
VesselVector PropagateVessel(const VesselVector& x, double dt_s, VesselCovariance* F = nullptr);

// Process noise covariance Q dt over dt seconds (diagonal).
VesselCovariance ProcessCovariance(const LocalizerProcessNoise& q, double dt_s);

// Field B (T, NED axes) at a sensor at p_SinW (m) from the vessel at state x,
// depth vessel.z_m, moment Rz(heading) · vessel.m_B_Am2.
// Optional Jacobians: J_B_x = ∂B/∂x (3×5; zero in v and turn-rate columns),
// J_B_s = ∂B/∂(sensor x, y) (3×2).
Eigen::Vector3d VesselFieldAtSensor(const VesselVector& x, const Vessel& vessel, const Eigen::Vector3d& p_SinW,
                                    Jacobian3x5* J_B_x = nullptr, Jacobian3x2* J_B_s = nullptr);

}  // namespace magnav::localizer
