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

#include <cstdint>
#include <deque>
#include <map>
#include <vector>

#include <Eigen/Core>

#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"

namespace magnav {
class StateWriter;  // core/checkpoint.h
class StateReader;
}  // namespace magnav

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

// The joint bound of a stream in bounded memory (what the bounded EKF runs:
// StreamOptions::bounded, `magnav localize --method ekf-bounded`,
// magnav-localizer). The factor graph is a chain of vessel states with the
// sensors as one global block, so eliminating the epochs one by one, oldest
// first, gives the same sensor information as the batch elimination
// (ComputeCrlb): the recursion keeps the information of [the last folded
// epoch's vessel state; every sensor] ((5 + 2M)², constant) and folds an
// epoch into it — its motion factor, GNSS fixes and magnetometer samples —
// then eliminates the state before it (a 5×5 Schur complement, O(M²)).
//
// The only difference from ComputeCrlb is the linearisation point of the
// sensors: ComputeCrlb evaluates every sample at the final estimate; here an
// epoch is evaluated at the estimate of the time it leaves the window (lag_s
// after its time: by then the vessel has passed the sensor and the estimate
// has locked on), and the epochs still in the window at the sensors given to
// Bounds. The trajectory is the filtered one in both (the state after each
// epoch's last update). Memory: the window (at most lag_s of items and at
// most max_window_items, the oldest epochs folded first) plus the (5 + 2M)²
// information; nothing grows with the items consumed.
struct IncrementalCrlbOptions {
  double lag_s = 60.0;                     // sample time, s; 0 = fold every epoch as soon as the next starts
  std::size_t max_window_items = 20000;    // samples + fixes held at most (memory cap)

  bool IsValid(std::string* error) const;
};

class IncrementalCrlb {
 public:
  // Throws InputError if the options are invalid.
  IncrementalCrlb(const Vessel& vessel, const std::vector<SensorPrior>& sensors, const LocalizerOptions& options,
                  const IncrementalCrlbOptions& bound = {});

  // An update the estimator applied, in time order, with its state after it:
  // `state` = [vessel (5); sensor 1 (x, y); ...] (LocalizerEkf::state()).
  // Items within options.epoch_tolerance_s of the current epoch's first time
  // share its vessel state (EpochTimes). Unknown sensors are ignored.
  void Add(const MagSample& sample, const Eigen::VectorXd& state);
  void Add(const GnssFix& fix, const Eigen::VectorXd& state);

  // Bounds with the window evaluated at `sensors_xy` (Pass::sensors order;
  // the caller's current estimate). O(window · M² + M³); const, so a copy
  // can be evaluated outside a lock. ok = false before any item or if the
  // information is singular.
  CrlbResult Bounds(const std::vector<Eigen::Vector2d>& sensors_xy) const;

  // Sizes, for tests that nothing grows with uptime.
  std::size_t window_items() const { return window_items_; }
  std::size_t window_epochs() const { return window_.size(); }
  std::uint64_t folded_epochs() const { return folded_epochs_; }
  // The vessel state at each epoch of the window (time order).
  std::vector<double> WindowTimes() const;
  std::vector<VesselVector> WindowTrajectory() const;

  // Checkpoint (checkpoint.h): the folded information and the window, bit
  // for bit. RestoreState needs the same vessel, sensors and options; throws
  // CheckpointError if the bytes do not fit (state untouched).
  void SaveState(StateWriter& w) const;
  void RestoreState(StateReader& r);

 private:
  struct Epoch {
    double t_s = 0.0;
    VesselVector x;
    std::vector<MagSample> samples;
    std::vector<GnssFix> fixes;
  };
  // The recursion's state: information over [vessel state of the last
  // folded epoch; sensors], and per sensor its magnetometer + prior
  // information (the known-trajectory bound).
  struct Folded {
    Eigen::MatrixXd info;
    std::vector<Eigen::Matrix2d> known;
    bool has_state = false;
    double t_s = 0.0;
    VesselVector x;
  };
  Epoch& EpochAt(double t_s, const Eigen::VectorXd& state);
  void FoldOld(const Eigen::VectorXd& state);
  void Fold(const Epoch& e, const std::vector<Eigen::Vector2d>& sensors_xy, Folded* f) const;

  Vessel vessel_;
  std::vector<SensorPrior> sensors_;
  std::map<std::uint32_t, int> index_;  // sensor id → index
  LocalizerOptions options_;
  IncrementalCrlbOptions bound_;
  Folded folded_;
  std::deque<Epoch> window_;
  std::size_t window_items_ = 0;
  std::uint64_t folded_epochs_ = 0;
};

}  // namespace magnav::localizer
