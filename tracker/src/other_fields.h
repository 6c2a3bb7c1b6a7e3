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

#include "magnav/core/gradiometer.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::tracker {

// `sigma_B`, `sigma_T`: the sample's own noise (its σ or the options'
// default).
inline void RemoveOtherFields(const Eigen::Vector3d& B_others, const Eigen::Matrix3d& T_others, double sigma_B,
                              double sigma_T, GradiometerSample* s) {
  s->B -= B_others;
  s->T -= T_others;
  const double rel = MultiTrackerOptions::kOtherFieldRelativeError;
  s->sigma_B = std::hypot(sigma_B, rel * B_others.norm() / std::sqrt(3.0));
  s->sigma_T = std::hypot(sigma_T, rel * T_others.norm() / 3.0);
}

// The variance per element of another track's predicted field at a sensor
// from that track's uncertainty, to first order: C = blockdiag(P of [x y z
// heading], P_m), J the field's derivatives by central differences of
// PredictedField; B: tr(J_B C J_Bᵀ)/3 (T²), T: tr(J_T C J_Tᵀ)/9 ((T/m)²), the
// same spread over the elements as the relative error's. The position-
// moment cross-covariance is not kept by the batch and is left out.
struct OtherFieldVariance {
  double B = 0.0;  // T² per axis
  double T = 0.0;  // (T/m)² per element
};
inline OtherFieldVariance OtherFieldVarianceFromCovariance(const CtState<double>& s, const Eigen::Vector3d& m_B_Am2,
                                                           const Eigen::Matrix<double, 6, 6>& P_state,
                                                           const Eigen::Matrix3d& P_m, const Eigen::Vector3d& p_SinW) {
  // Columns: d/dx, d/dy, d/dz, d/dheading, d/dm_x, d/dm_y, d/dm_z.
  Eigen::Matrix<double, 3, 7> JB;
  Eigen::Matrix<double, 9, 7> JT;
  const double m_step = std::max(m_B_Am2.norm(), 1.0) * 1e-4;  // A·m²
  const double steps[7] = {1e-3, 1e-3, 1e-3, 1e-5, m_step, m_step, m_step};  // m, m, m, rad, A·m² ×3
  for (int c = 0; c < 7; ++c) {
    Eigen::Vector3d B[2];
    Eigen::Matrix3d T[2];
    for (int side = 0; side < 2; ++side) {
      const double h = side == 0 ? steps[c] : -steps[c];
      CtState<double> x = s;
      Eigen::Vector3d m = m_B_Am2;
      if (c == 0) x.x += h;
      if (c == 1) x.y += h;
      if (c == 2) x.z += h;
      if (c == 3) x.heading += h;
      if (c >= 4) m(c - 4) += h;
      PredictedField(x, m, p_SinW, &B[side], &T[side]);
    }
    JB.col(c) = (B[0] - B[1]) / (2.0 * steps[c]);
    const Eigen::Matrix3d dT = (T[0] - T[1]) / (2.0 * steps[c]);
    JT.col(c) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dT.data());
  }
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
  s->B -= B_others;
  s->T -= T_others;
  s->sigma_B = std::sqrt(sigma_B * sigma_B + var.B);
  s->sigma_T = std::sqrt(sigma_T * sigma_T + var.T);
}

}  // namespace magnav::tracker
