// Batch smoother of a whole pass: the vessel trajectory (one coordinated-turn
// state per epoch) and every sensor's (x, y) jointly, by nonlinear least
// squares over magnetometer (robust loss), GNSS, process-model and deployment
// prior residuals (cost_functions.h), solved with Ceres (Levenberg-Marquardt,
// sparse normal Cholesky).
//
// Why Ceres and not the tracker's chain elimination: that solver is built for
// a 6-state chain with one 3-parameter global block and the tracker's factor
// shapes (fixed-size kernels); here the global block is 2M sensor
// coordinates and M is not fixed. Ceres' sparse Cholesky exploits the same
// structure (the trajectory block is block-tridiagonal) without a second,
// generalised copy of it. The covariance is the inverse Gauss-Newton
// information at the solution marginalised onto the sensors by eliminating
// the trajectory (sparse LDLᵀ), as the bounds in crlb.h.
//
// Start: the EKF (ekf.h RunEkf) run over the same pass.
// Frames and units: types.h.
#pragma once

#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer {

// Solves the pass. `start`, if given, is the starting point (one state per
// EpochTimes entry and one estimate per sensor); else RunEkf(pass, options).
// Sensor covariances = batch covariance; bounds at the solution. Throws
// InputError on invalid options or input.
Localization SolveBatch(const Pass& pass, const LocalizerOptions& options, const Localization* start = nullptr);

}  // namespace magnav::localizer
