// Internal: the multi-tracker's side of the cluster background
// (cluster_background.h): the raw epochs of the last window span, the
// offsets, and the offset step over the live tracks' windows.
#pragma once

#include <deque>
#include <limits>
#include <vector>

#include "magnav/tracker/cluster_background.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"

namespace magnav {
class StateWriter;
class StateReader;
}  // namespace magnav

namespace magnav::tracker::internal {

class WindowClusterBackground {
 public:
  WindowClusterBackground(const Eigen::Vector3d& B0_W, const MultiTrackerOptions& options);
  bool enabled() const { return options_.cluster_background.enabled; }
  // The raw epoch joins the span the offsets are estimated over.
  void AddRaw(const Epoch& raw);
  // Offset step, when one is due at t_s (every window_solve_interval_s):
  // every live engine's window (its states, moment and sensors; at t_s its
  // prediction) gives the tracks; afterwards every engine takes the new
  // offsets. Returns whether a step was made.
  bool StepIfDue(double t_s, const std::vector<WindowTracker*>& engines);
  // The epoch's samples with their sensor's offset at its time taken off B
  // (and put back: a track's window adds the offsets in its model).
  Epoch Corrected(const Epoch& raw) const;
  void PutBack(Epoch* e) const;
  // The function an engine's window takes (reads the current offsets).
  WindowTracker::BackgroundOffsetFn Fn() const;
  const SensorOffsets& offsets() const { return offsets_; }
  // The last step's clusters and samples.
  const ClusterStepStats& last_step() const { return last_step_stats_; }
  void SaveState(StateWriter& w) const;
  void RestoreState(StateReader& r);

 private:
  Eigen::Vector3d B0_W_;
  MultiTrackerOptions options_;
  std::deque<Epoch> raw_;
  SensorOffsets offsets_;
  double last_step_t_ = -std::numeric_limits<double>::infinity();
  ClusterStepStats last_step_stats_;
};

}  // namespace magnav::tracker::internal
