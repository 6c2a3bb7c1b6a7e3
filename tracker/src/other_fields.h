// The joint multi-dipole model, track by track: a track is given a sample
// minus the predicted fields of the other tracks. Those fields are models
// (each track's state and moment are estimates), so their error is added to
// the sample's noise: MultiTrackerOptions::kOtherFieldRelativeError of their
// norm, spread over the elements (B: norm/√3 per axis; T: norm/3 per element),
// in quadrature with the sample's σ. Units: T, T/m.
#pragma once

#include <cmath>

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

}  // namespace magnav::tracker
