// The joint multi-dipole model, track by track: a track is given a sample
// minus the predicted fields of the other tracks. Those fields are models
// (each track's state and moment are estimates), so their error is added to
// the sample's noise: MultiTrackerOptions::kOtherFieldRelativeError of their
// norm, spread over the elements (B: norm/√3 per axis; T: norm/3 per element),
// in quadrature with the sample's σ. Units: T, T/m.
// Batch, MultiTrackerOptions::batch_other_field_covariance: instead, that
// error's variance from the other track's own covariance (its position,
// heading and body moment: OtherFieldVariance).
#pragma once

#include <algorithm>
#include <cmath>

#include <Eigen/Core>

#include "magnav/core/dipole.h"
#include "magnav/core/frames.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/tensor.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::tracker {

// The fields subtracted from the sample, and their model error (σ per
// element: `model_sigma_B` T, `model_sigma_T` T/m) added in quadrature to
// the sample's own noise `sigma_B`, `sigma_T` (its σ or the options' default).
inline void RemoveModelledFields(const Eigen::Vector3d& B_others, const Eigen::Matrix3d& T_others, double sigma_B,
                                 double sigma_T, double model_sigma_B, double model_sigma_T, GradiometerSample* s) {
  s->B -= B_others;
  s->T -= T_others;
  s->sigma_B = std::hypot(sigma_B, model_sigma_B);
  s->sigma_T = std::hypot(sigma_T, model_sigma_T);
}

// The model error as `rel` of the fields' norm (kOtherFieldRelativeError
// unless given: the batch's batch_other_field_relative_error).
inline void RemoveOtherFields(const Eigen::Vector3d& B_others, const Eigen::Matrix3d& T_others, double sigma_B,
                              double sigma_T, GradiometerSample* s,
                              double rel = MultiTrackerOptions::kOtherFieldRelativeError) {
  RemoveModelledFields(B_others, T_others, sigma_B, sigma_T, rel * B_others.norm() / std::sqrt(3.0),
                       rel * T_others.norm() / 3.0, s);
}

// The variance per element of another track's predicted field at a sensor
// from that track's uncertainty, to first order: C = blockdiag(P of [x y z
// heading], P_m), J the field's analytic derivatives (core/dipole.h
// DipoleMeasurement's J_z_r and J_z_m, frames.h WorldMoment's ∂m_W/∂ψ); B:
// tr(J_B C J_Bᵀ)/3 (T²), T: tr(J_T C J_Tᵀ)/9 over the nine elements ((T/m)²),
// the same spread over the elements as the relative error's. The position-
// moment cross-covariance is not kept by the batch and is left out.
struct OtherFieldVariance {
  double B = 0.0;  // T² per axis
  double T = 0.0;  // (T/m)² per element
};

// The same variance as kOtherFieldRelativeError of the fields' norm
// (RemoveOtherFields' model error, squared), for `B` (T) and `T` (T/m).
inline OtherFieldVariance RelativeOtherFieldVariance(const Eigen::Vector3d& B, const Eigen::Matrix3d& T) {
  const double rel = MultiTrackerOptions::kOtherFieldRelativeError;
  return {rel * rel * B.squaredNorm() / 3.0, rel * rel * T.squaredNorm() / 9.0};
}
inline OtherFieldVariance OtherFieldVarianceFromCovariance(const CtState<double>& s, const Eigen::Vector3d& m_B_Am2,
                                                           const Eigen::Matrix<double, 6, 6>& P_state,
                                                           const Eigen::Matrix3d& P_m, const Eigen::Vector3d& p_SinW) {
  Eigen::Vector3d dmW_dpsi;
  const Eigen::Vector3d m_W = WorldMoment(m_B_Am2, s.heading, &dmW_dpsi);
  const Eigen::Matrix3d R = HeadingRotation(s.heading);
  Jacobian8x3 J_r, J_m;
  DipoleMeasurement(p_SinW - Eigen::Vector3d(s.x, s.y, s.z), m_W, &J_r, &J_m);
  // Columns: d/dx, d/dy, d/dz, d/dheading, d/dm_x, d/dm_y, d/dm_z (body).
  // The vessel's position enters r = p_S − p_D with a minus sign.
  Eigen::Matrix<double, 8, 7> J;
  J.leftCols<3>() = -J_r;
  J.col(3) = J_m * dmW_dpsi;
  J.rightCols<3>() = J_m * R;
  // The packed tensor's five rows to the nine elements (UnpackTensor5 is linear).
  Eigen::Matrix<double, 9, 5> L;
  for (int k = 0; k < 5; ++k) {
    const Eigen::Matrix3d e = UnpackTensor5(Tensor5::Unit(k));
    L.col(k) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(e.data());
  }
  const Eigen::Matrix<double, 3, 7> JB = J.topRows<3>();
  const Eigen::Matrix<double, 9, 7> JT = L * J.bottomRows<5>();
  Eigen::Matrix<double, 7, 7> C = Eigen::Matrix<double, 7, 7>::Zero();
  const int idx[4] = {0, 1, 2, 4};  // x y z heading in [x y z v h ω]
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) C(a, b) = P_state(idx[a], idx[b]);
  }
  C.bottomRightCorner<3, 3>() = P_m;
  OtherFieldVariance v;
  v.B = std::max(0.0, (JB * C * JB.transpose()).trace() / 3.0);
  v.T = std::max(0.0, (JT * C * JT.transpose()).trace() / 9.0);
  return v;
}

// RemoveOtherFields with the fields' error variance given (summed over the
// other tracks: OtherFieldVarianceFromCovariance).
inline void RemoveOtherFieldsWithVariance(const Eigen::Vector3d& B_others, const Eigen::Matrix3d& T_others,
                                          const OtherFieldVariance& var, double sigma_B, double sigma_T,
                                          GradiometerSample* s) {
  RemoveModelledFields(B_others, T_others, sigma_B, sigma_T, std::sqrt(var.B), std::sqrt(var.T), s);
}

}  // namespace magnav::tracker
