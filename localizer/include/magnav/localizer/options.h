// Options of the sensor localiser (EKF-SLAM and batch smoother).
//
// Units: SI (m, s, rad, T). Process noise is given as random-walk
// intensities: the 1-σ change per √s, so over dt the added variance is σ² dt.
// Defaults were tuned on the reference pass (`localize_*.csv`); see
// docs/ACCURACY.md for what was tuned and what is held out.
#pragma once

#include <optional>
#include <string>

#include "magnav/core/loss.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer {

using magnav::LossType;  // core/loss.h

// Coordinated-turn process model x_{k+1} = f(x_k, dt) + w, w ~ N(0, Q dt),
// Q = diag(σ_p², σ_p², σ_v², σ_h², σ_ω²).
struct LocalizerProcessNoise {
  // Position random walk on top of the coordinated-turn prediction (x, y).
  double position_m_per_sqrt_s = 0.05;
  // Speed random walk.
  double speed_mps_per_sqrt_s = 0.01;
  // Heading random walk added to h + ω dt.
  double heading_rad_per_sqrt_s = 0.005;
  // Turn-rate random walk: large enough to follow the onset of a turn
  // (a step of 0.1 rad/s on the reference pass) within a few seconds.
  double turn_rate_radps_per_sqrt_s = 0.01;

  bool IsValid(std::string* error) const;
};

// Uncertainty of the vessel's initial state (EKF start; the batch is started
// from the EKF). Position σ is the GNSS fit's when the start comes from GNSS.
struct InitialVesselSigma {
  double position_m = 10.0;  // used only with LocalizerOptions::vessel_start
  double speed_mps = 0.5;
  double heading_rad = 0.5;
  double turn_rate_radps = 0.05;

  bool IsValid(std::string* error) const;
};

struct LocalizerOptions {
  LocalizerProcessNoise process;
  InitialVesselSigma initial;
  // Where the vessel starts (state at the first sample: x, y, speed, heading,
  // turn rate), for a pass without GNSS fixes at its start; σ from `initial`.
  // Unset (default): the start comes from the first GNSS fixes, and without
  // them the EKF refuses to start (no guessed start).
  std::optional<VesselVector> vessel_start;
  // 1-σ noise of each magnetometer axis (T). Set from the file's
  // "# sigma_B_T:" line by `magnav localize` when present.
  double sigma_B_T = 1e-9;
  // GNSS 1-σ per axis (m) for every fix, overriding the fixes' own sigma;
  // 0 (default) = each fix's own sigma. A fix without a sigma (≤ 0) and no
  // override is refused (EKF) or an error (batch, bounds): never a guess.
  double gnss_sigma_m = 0.0;
  // Batch: robust loss on each magnetometer residual (3-vector, whitened) and
  // its scale in σ. Huber at 3σ leaves Gaussian residuals almost untouched and
  // bounds the pull of a spike.
  LossType magnetometer_loss = LossType::kHuber;
  double magnetometer_loss_scale_sigma = 3.0;
  // Batch: the same for each GNSS fix (2-vector, whitened): one fix 9e6 m off
  // pulls like a 3σ residual, not like a 3e6σ one.
  LossType gnss_loss = LossType::kHuber;
  double gnss_loss_scale_sigma = 3.0;
  // Outlier gate, as a probability per update. EKF: a magnetometer (3 dof) or
  // GNSS (2 dof) update whose normalised innovation squared (innovation
  // covariance S = H P Hᵀ + R, so a large P during convergence widens the gate)
  // exceeds the χ² quantile of this probability (magnav::ChiSquareQuantile,
  // core/nees.h) is refused and counted; at
  // 0.9999 the gate is NIS > 21.1 (3 dof) / 18.4 (2 dof): a valid update is
  // refused once in 10⁴. Batch: residuals beyond the same quantile at the
  // solution are counted as outliers (the robust losses above bound their
  // pull; nothing is removed). 1 = no gate (every update applied).
  double gate_probability = 0.9999;
  // EKF: after this many refused updates in a row of one stream (a sensor, or
  // the GNSS), that stream's gate opens: its updates are applied whatever
  // their NIS until one falls within the gate again. A run of refusals means
  // the filter, not the data, is off: on the first pass over a sensor metres
  // off, the linearised S understates the innovations (NIS 25-80 on a held-out
  // draw while the EKF locks on) and a closed gate would lock the filter out
  // for good. A single outlier never makes a run. A released update is
  // applied with its innovation covariance scaled by NIS / gate (its gain
  // shrunk so): applied at full gain, one such update on the calibration
  // scenario's run 2003 collapsed a sensor's σ to 0.5 m 26 m off, and the
  // run ended metres off on every sensor. 0 = never open.
  int gate_release_after = 5;
  // EKF: iterations of each magnetometer update (iterated EKF, Gauss-Newton
  // on the update's MAP: the field and its Jacobian re-evaluated at the
  // updated vessel and sensor state, the gain and covariance reduction taken
  // at the last one). 1 = the plain EKF update, which linearises the 1/r³
  // field at a sensor still metres off and was over-confident while
  // converging (calibration, sixsensor_legs: ANEES 1.61 × dof, 56 % of epochs
  // inside their 95 % interval; with 2: 1.25 × dof, 78 %; 5 and 10 iterations
  // gave the same figures). The gate uses the first iteration's NIS (the
  // prior's), as the plain EKF. Iterating stops early when an iteration moves
  // the state by < 1 mm. At most kMaxMagnetometerIterations (each iteration
  // is a full field and Jacobian evaluation per update; beyond a handful
  // they change nothing, above).
  static constexpr int kMaxMagnetometerIterations = 20;
  int magnetometer_iterations = 2;
  // Batch: Ceres trust-region iterations and tolerances.
  int max_num_iterations = 50;
  double function_tolerance = 1e-10;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-10;
  int num_threads = 1;
  // Samples (and fixes) closer in time than this belong to one epoch (s).
  double epoch_tolerance_s = 1e-6;

  bool IsValid(std::string* error) const;
};

}  // namespace magnav::localizer
