// Dipole (vessel) tracker: a coordinated-turn vessel with a body-fixed dipole
// moment estimated from gradiometer samples by nonlinear least squares (Ceres).
//
// Frames and units: world = local NED (x north, y east, z down), metres. The
// vessel state per epoch is p_VinW (m), speed (m/s), heading (rad from north,
// clockwise seen from above) and turn rate (rad/s). The moment is in the BODY
// frame (x forward, y starboard, z down), A·m², shared by all epochs; the world
// moment is m_W = Rz(heading) m_B. B0_W is the constant background field (T)
// subtracted from every B. Covariances are in the same units squared.
//
// Two modes:
//  * SolveBatch: one problem over a whole pass (smoother), full covariance.
//  * WindowTracker: fixed-lag sliding window fed one sample at a time; the
//    epochs that leave the window are marginalised into a Gaussian prior on
//    the oldest kept state and the moment. It emits one estimate per epoch
//    (the newest state right after its window solve, i.e. a causal filter).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "magnav/core/gradiometer.h"
#include "magnav/core/motion.h"
#include "magnav/inversion/inverter.h"
#include "magnav/tracker/options.h"

namespace magnav {
class StateWriter;  // core/checkpoint.h
class StateReader;
}  // namespace magnav

namespace magnav::tracker {

// Samples of all gradiometers taken at one instant.
struct Epoch {
  double t_s = 0.0;
  std::vector<GradiometerSample> samples;
};

// Groups time-ordered samples into epochs (|Δt| ≤ tolerance_s). Throws
// InputError if the samples are not ordered by time.
std::vector<Epoch> GroupEpochs(const std::vector<GradiometerSample>& samples, double tolerance_s);

// A single-sample dipole fix is the inverter's (one struct for one meaning):
// the tracker reads its t_s, sensor_id, valid and p_DinW, and sets snr from
// the sample it matches. A fix rejected by its producer's gates (valid =
// false) is never used for a track, but tells the tracker that fixes are
// being produced (InitSource::kAuto).
using DipoleFix = inversion::DipoleFix;
// A fix as the tracker needs it (the inverter's defaults elsewhere).
DipoleFix MakeFix(double t_s, std::uint32_t sensor_id, const Eigen::Vector3d& p_DinW, bool valid = true);

// State vector layout of one epoch: [x, y, z, v, h, ω].
using StateVector = Eigen::Matrix<double, 6, 1>;
using StateCovariance = Eigen::Matrix<double, 6, 6>;

struct EpochEstimate {
  double t_s = 0.0;
  Eigen::Vector3d p_VinW = Eigen::Vector3d::Zero();  // vessel (dipole) position, m
  double speed_mps = 0.0;
  double heading_rad = 0.0;  // wrapped to (−π, π]
  double turn_rate_radps = 0.0;
  int num_samples = 0;  // samples of this epoch in the problem
  // false: do not use this estimate (the solve that made it failed, or its
  // state or covariance is not finite); its covariance is then not given.
  bool usable = false;
  bool has_covariance = false;
  StateCovariance cov_state = StateCovariance::Zero();  // order [x y z v h ω]

  Eigen::Vector3d v_VinW() const;                                              // m/s, world NED
  Eigen::Matrix3d cov_p_W() const { return cov_state.topLeftCorner<3, 3>(); }  // m²
};

struct TrackEstimate {
  std::vector<EpochEstimate> epochs;
  Eigen::Vector3d m_B_Am2 = Eigen::Vector3d::Zero();  // body moment
  Eigen::Matrix3d cov_m_B = Eigen::Matrix3d::Zero();  // (A·m²)²
  Summary summary;
};

struct InitialTrack;  // initialize.h

// Batch solve over all epochs of a pass. If no track can be initialised the
// result has summary.initialized == false and no epochs. `fixes`: single-sample
// fixes computed elsewhere (e.g. `magnav invert`'s output) for the
// initialiser, used as options.init.source says (see InitializeTrack); nullptr
// = none. `starts`: whole trajectories (the state at a time, world frame as
// above; nullopt where a start has none) the batch is restarted from after its
// own solve and its turn-rate restarts (TrackerOptions::batch_turn_change_points),
// each kept by the same rule (a cost lower by ≥ 1); e.g. the window track
// that found the vessel. nullptr = none.
using BatchStart = std::function<std::optional<CtState<double>>(double t_s)>;
TrackEstimate SolveBatch(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                         const TrackerOptions& options, const std::vector<DipoleFix>* fixes = nullptr,
                         const std::vector<BatchStart>* starts = nullptr);

// Sliding-window (fixed-lag) tracker. Not thread-safe; one track.
class WindowTracker {
 public:
  // Throws InputError if options are invalid.
  WindowTracker(const Eigen::Vector3d& B0_W, const TrackerOptions& options);
  ~WindowTracker();
  WindowTracker(const WindowTracker&) = delete;
  WindowTracker& operator=(const WindowTracker&) = delete;

  // Adds one sample (non-decreasing time). A sample with a later time closes
  // the current epoch, which is then processed; the returned estimates are
  // those produced by that (one per processed epoch; none while no track
  // could be started). A sample that fails core's CheckSample (non-finite
  // time, B, T, position or σ; all-zero tensor) is refused: counted in
  // Summary::num_rejected_samples, never seen by the solver. Throws
  // InputError if the time goes back.
  std::vector<EpochEstimate> AddSample(const GradiometerSample& sample);
  // Processes the pending epoch and solves what is not solved yet (end of
  // stream).
  std::vector<EpochEstimate> Flush();
  // Processes one complete epoch directly (later than every previous one).
  // Once a track exists, an epoch with no sample is a coasting step: only the
  // motion model links it, so the state's covariance grows.
  std::vector<EpochEstimate> AddEpoch(const Epoch& epoch);
  // Starts the track from an initialisation made elsewhere (the multi-vessel
  // tracker's initiator) over the epochs it came from (time-ordered; their
  // samples become the first window), instead of waiting for the tracker's
  // own initialiser. Returns the newest epoch's estimate. Throws InputError if
  // a track exists already or the epochs are empty or out of order.
  std::vector<EpochEstimate> Start(const InitialTrack& init, const std::vector<Epoch>& epochs);
  // The newest window state propagated by the coordinated-turn model to
  // t_s (prediction; no measurement). nullopt before a track exists.
  std::optional<CtState<double>> PredictState(double t_s) const;
  // Time of the newest epoch in the window (−inf before a track exists).
  double last_epoch_time() const;
  // Per-sensor background offsets (cluster_background.h): offset(sensor_id,
  // t_s), world NED in T, is added to B0 in the measurement model of every
  // sample in the window now and of every sample appended later, until the
  // next call (an empty function: B0 alone, the default). The next window
  // solve uses them. Not in the checkpoint: whoever sets them sets them
  // again after RestoreState (MultiTracker does).
  using BackgroundOffsetFn = std::function<Eigen::Vector3d(std::uint32_t sensor_id, double t_s)>;
  void SetBackgroundOffsets(BackgroundOffsetFn offset);
  // Each sensor's own offset's prior from outside (SensorOffsetOptions::quiet:
  // the sensor's offset from its quiet data, MultiTracker): true with the
  // offset (world NED, T) and its σ per axis (T) at t_s, false for none (the
  // window's own rule). Not in the checkpoint: whoever sets it sets it again.
  using SensorOffsetPriorFn =
      std::function<bool(std::uint32_t sensor_id, double t_s, Eigen::Vector3d* mean_W, double* sigma_T)>;
  void SetSensorOffsetPrior(SensorOffsetPriorFn prior);
  // The window's epochs, oldest first: time, state and the sensors of its
  // samples (empty before a track exists).
  struct WindowEpochView {
    double t_s = 0.0;
    CtState<double> state{};
    std::vector<std::uint32_t> sensor_ids;
  };
  std::vector<WindowEpochView> WindowView() const;
  // The multi-tracker's back-filled start (TrackState::kStart):
  // FirstStrongEpoch is the time of the window's first solved epoch with a
  // sample where the window's state and moment predict a tensor of at least
  // min_tensor_snr · σ_T (‖T̂‖_F); NaN if none (or before a track exists).
  // SolvedBetween gives the window's current estimates of its solved epochs
  // with t_from_s ≤ t ≤ t_until_s (smoothed: solved with every later epoch
  // of the window), each with its covariance as the live estimates (the
  // window's marginal at its last solve); empty if none is in the window.
  double FirstStrongEpoch(double min_tensor_snr) const;
  std::vector<EpochEstimate> SolvedBetween(double t_from_s, double t_until_s);
  // Hands the initialiser a fix computed elsewhere (every fix magnav-inverter
  // publishes, rejected ones included: with InitSource::kAuto the first fix,
  // valid or not, makes the initialiser try the fixes handed in first), used
  // as options.init.source says (see InitializeTrack). A fix may come before or after its sample;
  // valid fixes are kept while no track exists, for the span the initialiser
  // looks at (at most kMaxPendingFixes), then dropped. Throws InputError if
  // the time, or the position of a valid fix, is not finite.
  void AddFix(const DipoleFix& fix);
  static constexpr std::size_t kMaxPendingFixes = 100000;

  bool initialized() const;
  // Current body moment estimate and its covariance (valid once initialised).
  Eigen::Vector3d m_B_Am2() const;
  Eigen::Matrix3d cov_m_B() const;
  // Summary of the last window solve.
  const Summary& last_summary() const;
  // Over the solved epochs of the window: Σ over its sensors of n_j ‖ē_j‖²,
  // ē_j the mean whitened residual (8) of sensor j's n_j samples, and its
  // dof 8·(sensors); both 0 before a usable solve (variance_factor.h). With
  // sensor_offset.window_lines the means are per sensor and per quarter of
  // the window's span (a line takes out each sensor's mean and trend, not
  // what bends within the window), dof 8 per (sensor, quarter) less 6 per
  // sensor whose line was fitted (and that has more than two quarters).
  void ResidualMeansChi2(double* chi2, double* dof) const;

  // Checkpoint (tracker/checkpoint.h): everything that changes after
  // construction (the initiator's buffer and fixes, the epoch being filled,
  // the window's epochs and states, the moment, the marginalisation prior,
  // counters), every double bit for bit; the factors are rebuilt from them.
  // RestoreState into a tracker made with the same B0 and options, fed
  // nothing; then it goes on exactly as the saved one would. Throws
  // CheckpointError if the bytes do not fit.
  void SaveState(StateWriter& w) const;
  void RestoreState(StateReader& r);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace magnav::tracker
