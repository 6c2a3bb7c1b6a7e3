// EKF-SLAM of the sensor positions (METHODS.md §3; Callmer, Skoglund,
// Gustafsson 2010): state = [vessel (x, y, v, heading, turn rate);
// sensor 1 (x, y); ...; sensor M (x, y)], prior from the deployment guesses,
// coordinated-turn prediction (models.h), one update per magnetometer sample
// (3-axis field of the known body moment turned by the heading) and per GNSS
// fix.
//
// Numerics: each sample is its own update (3 rows touching 5 vessel + 2
// sensor columns), so an update costs O(n²) for n = 5 + 2M, and the
// prediction O(n) (only the vessel rows change). The covariance is updated in
// Joseph form, P⁺ = (I − KH) P (I − KH)ᵀ + K R Kᵀ, expanded so that it stays
// O(n²) (P − K Uᵀ − U Kᵀ + K S Kᵀ with U = P Hᵀ, S = H P Hᵀ + R). Only the
// lower triangle of P is stored and updated (symmetric by construction; one
// sweep of memory per update, which is what an update costs at M = 1000).
//
// Frames and units: types.h (NED, m, s, T, rad).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "magnav/localizer/options.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/types.h"

namespace magnav {
class StateWriter;  // core/checkpoint.h
class StateReader;
}  // namespace magnav

namespace magnav::localizer {

// The 1-σ (m) a fix is used with: options.gnss_sigma_m if set, else the fix's.
double GnssSigma(const GnssFix& fix, const LocalizerOptions& options);

// Initial vessel state at time t0_s from the GNSS fixes of the first
// `window_s` seconds after t0 (straight-line least-squares fit: position,
// speed, heading; turn rate 0) and its covariance (position σ from the fit,
// speed/heading/turn-rate σ from options.initial). Fixes off the line beyond
// the outlier gate (options.gate_probability) are dropped one by one, worst
// first, and the line refitted. False if fewer than two fixes span at least
// 2 s in that window.
bool InitialVesselFromGnss(const std::vector<GnssFix>& fixes, double t0_s, const LocalizerOptions& options,
                           VesselVector* x0, VesselCovariance* P0, double window_s = 10.0);

class LocalizerEkf {
 public:
  // Prior: vessel x0, P0 at time t0_s; sensors from their deployment guesses.
  // Throws InputError if the options are invalid.
  LocalizerEkf(const Vessel& vessel, const std::vector<SensorPrior>& sensors, double t0_s, const VesselVector& x0,
               const VesselCovariance& P0, const LocalizerOptions& options);

  // Moves the state to t_s (≥ time()). False (state unchanged) if t_s is
  // earlier than time() or not finite, or if the predicted state or
  // covariance would not be finite (e.g. a time 1e300 s ahead).
  bool Predict(double t_s);
  // Predicts to the sample's time and updates. False if not applied:
  // kFailed for an unknown sensor, a non-finite value, a sample earlier than
  // time() or a failed prediction (state unchanged), or a singular innovation
  // covariance (state predicted to the sample's time); kRejected (state
  // predicted to the sample's time, not updated) when the normalised
  // innovation squared is beyond the gate (LocalizerOptions::gate_probability,
  // gate_release_after). last_outcome() tells which.
  bool Update(const MagSample& sample);
  bool Update(const GnssFix& fix);

  enum class Outcome { kApplied, kRejected, kFailed };
  Outcome last_outcome() const { return last_outcome_; }
  // Updates refused by the gate so far, and those applied beyond it (a
  // stream's gate opened by a run of refusals, LocalizerOptions::gate_release_after).
  std::uint64_t rejected_magnetometer() const { return rejected_magnetometer_; }
  std::uint64_t rejected_gnss() const { return rejected_gnss_; }
  std::uint64_t gate_releases() const { return gate_releases_; }

  double time() const { return t_s_; }
  int num_sensors() const { return static_cast<int>(sensors_.size()); }
  const Eigen::VectorXd& state() const { return x_; }
  // Full covariance (n × n, a copy: only the lower triangle is stored).
  Eigen::MatrixXd covariance() const;
  VesselVector vessel_state() const { return x_.head<5>(); }
  // Current estimate of every sensor (covariance; the bounds are left zero).
  std::vector<SensorEstimate> SensorEstimates() const;
  // Normalised innovation squared of the last magnetometer or GNSS update
  // (applied or refused).
  double last_nis() const { return last_nis_; }

  // Checkpoint (checkpoint.h): everything that changes after construction
  // (time, state, covariance, gate states, counters), bit for bit.
  void SaveState(StateWriter& w) const;
  // Into an EKF made with the same vessel, sensors and options (any t0, x0,
  // P0). Throws CheckpointError if the bytes do not fit (state untouched).
  void RestoreState(StateReader& r);

 private:
  int Column(std::uint32_t sensor_id) const;  // −1 if unknown
  // Columns c .. c+w−1 of the full covariance, from the lower triangle.
  Eigen::MatrixXd Columns(int c, int w) const;
  void JosephUpdate(const Eigen::MatrixXd& U, const Eigen::MatrixXd& K, const Eigen::MatrixXd& L_S);
  // The outlier gate of one stream (a sensor, or the GNSS).
  struct GateState {
    int refused_in_a_row = 0;
    bool open = false;  // after a run of refusals, until an update fits
  };
  // The gate on one update of a stream with NIS `nis` against `threshold`:
  // true to apply it; counts refusals and releases, sets last_outcome_. An
  // update applied beyond the gate (a released stream) is applied with its
  // innovation covariance S scaled by *inflate = nis / threshold (≥ 1): its
  // gain and its covariance reduction shrink by that factor, so that an
  // update the linearisation cannot explain cannot collapse the covariance
  // around a wrong state; 1 for an update within the gate.
  bool Gate(double nis, double threshold, GateState* stream, double* inflate);

  Vessel vessel_;
  std::vector<SensorPrior> sensors_;
  LocalizerOptions options_;
  double t_s_;
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  double last_nis_ = 0.0;
  double gate_magnetometer_nis_;  // χ² quantiles (3 and 2 dof) of options_.gate_probability
  double gate_gnss_nis_;
  std::vector<GateState> magnetometer_gate_;  // per sensor
  GateState gnss_gate_;
  Outcome last_outcome_ = Outcome::kApplied;
  std::uint64_t rejected_magnetometer_ = 0, rejected_gnss_ = 0, gate_releases_ = 0;
};

// The whole pass through the EKF, as a stream (stream.h StreamingLocalizer,
// the code magnav-localizer runs): in time order, fixes before samples at
// equal times, samples in file order. The vessel starts from InitialVesselFromGnss at the first epoch
// (throws InputError if that fails: the start of the vessel is unknown).
// Result: the final sensor estimates with their covariance and the bounds
// (crlb.h) evaluated along the filtered trajectory, and the filtered vessel
// state at every epoch.
Localization RunEkf(const Pass& pass, const LocalizerOptions& options);

// The same EKF as a bounded stream (StreamOptions::bounded: what
// magnav-localizer runs; `magnav localize --method ekf-bounded`): equal
// sensor estimates and covariances, the bounds from IncrementalCrlb (crlb.h),
// the trajectory only the bound's last window.
Localization RunEkfBounded(const Pass& pass, const LocalizerOptions& options, const IncrementalCrlbOptions& bound = {});

}  // namespace magnav::localizer
