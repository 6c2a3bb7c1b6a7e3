// Cramér–Rao lower bounds of the sensor positions (METHODS.md §3).
//
// Joint bound: the inverse of the Fisher information over the whole
// trajectory (vessel state at every epoch) and every sensor's (x, y), from the
// magnetometers, the GNSS fixes, the coordinated-turn process model and the
// deployment prior, marginalised onto the sensors (a posterior / Bayesian
// bound: the prior and process noise are part of it). Known-trajectory bound:
// the same with the trajectory perfectly known, i.e. per sensor the inverse of
// its magnetometer + prior information. The joint bound is the larger: a shift
// common to all sensors is only as well known as the vessel's absolute
// position.
//
// Frames and units: types.h; covariances in m². Evaluated at a given
// trajectory and sensor positions: the truth in tests, the estimate in
// `magnav localize` and magnav-localizer (where no truth is known).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer {

// The epochs of a pass: times at which the estimators keep a vessel state
// (samples and fixes within options.epoch_tolerance_s of an epoch's first
// time share it). A trajectory handed to ComputeCrlb has one state per epoch.
std::vector<double> EpochTimes(const Pass& pass, const LocalizerOptions& options);

struct CrlbResult {
  std::vector<Eigen::Matrix2d> joint;             // per sensor, m²
  std::vector<Eigen::Matrix2d> known_trajectory;  // per sensor, m²
  Eigen::MatrixXd joint_full;                     // 2M × 2M joint bound of all sensors
  bool ok = false;                                // false: information singular
};

// Bounds at a trajectory (one state per EpochTimes entry) and sensor
// positions (Pass::sensors order). Throws InputError on size mismatch.
CrlbResult ComputeCrlb(const Pass& pass, const LocalizerOptions& options, const std::vector<VesselVector>& trajectory,
                       const std::vector<Eigen::Vector2d>& sensors_xy);

// The bounds at a trajectory and at the sensors' estimated positions, written
// into each estimate's crlb_* fields; returns the full result.
CrlbResult AttachCrlb(const Pass& pass, const LocalizerOptions& options, const std::vector<VesselVector>& trajectory,
                      std::vector<SensorEstimate>* sensors);

}  // namespace magnav::localizer
