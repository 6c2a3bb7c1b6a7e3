#include "magnav/localizer/models.h"

#include "magnav/core/dipole.h"
#include "magnav/core/frames.h"
#include "magnav/core/motion.h"

namespace magnav::localizer {

namespace {
// Rows/columns of core's 6-state (x, y, z, v, h, ω) kept in the 5-state.
constexpr int kCoreIndex[5] = {0, 1, 3, 4, 5};
}  // namespace

VesselVector PropagateVessel(const VesselVector& x, double dt_s, VesselCovariance* F) {
  const CtState<double> s{x[kX], x[kY], 0.0, x[kV], x[kHeading], x[kTurnRate]};
  const CtState<double> o = PropagateCoordinatedTurn(s, dt_s);
  if (F != nullptr) {
    const Eigen::Matrix<double, 6, 6> F6 = CoordinatedTurnJacobian(s, dt_s);
    for (int i = 0; i < 5; ++i) {
      for (int j = 0; j < 5; ++j) (*F)(i, j) = F6(kCoreIndex[i], kCoreIndex[j]);
    }
  }
  VesselVector out;
  out << o.x, o.y, o.v, o.heading, o.turn_rate;
  return out;
}

VesselCovariance ProcessCovariance(const LocalizerProcessNoise& q, double dt_s) {
  VesselVector d;
  d << q.position_m_per_sqrt_s, q.position_m_per_sqrt_s, q.speed_mps_per_sqrt_s, q.heading_rad_per_sqrt_s,
      q.turn_rate_radps_per_sqrt_s;
  return (d.array().square() * std::abs(dt_s)).matrix().asDiagonal();
}

Eigen::Vector3d VesselFieldAtSensor(const VesselVector& x, const Vessel& vessel, const Eigen::Vector3d& p_SinW,
                                    Jacobian3x5* J_B_x, Jacobian3x2* J_B_s) {
  const Eigen::Vector3d p_VinW(x[kX], x[kY], vessel.z_m);
  Eigen::Vector3d J_mW_h;
  const Eigen::Vector3d m_W = WorldMoment(vessel.m_B_Am2, x[kHeading], &J_mW_h);
  Mat3 J_B_r, J_B_m;
  const Eigen::Vector3d B = DipoleB(p_SinW - p_VinW, m_W, &J_B_r, &J_B_m);
  if (J_B_x != nullptr) {
    J_B_x->setZero();
    // r = p_S − p_V: moving the vessel by δp changes r by −δp.
    J_B_x->leftCols<2>() = -J_B_r.leftCols<2>();
    J_B_x->col(kHeading) = J_B_m * J_mW_h;
  }
  if (J_B_s != nullptr) *J_B_s = J_B_r.leftCols<2>();
  return B;
}

}  // namespace magnav::localizer
