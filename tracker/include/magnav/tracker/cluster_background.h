// Per-sensor background offsets estimated with the tracks of a cluster
// (issue 24 items 1 and 3): each sensor's B0 is the fixed B0 plus an offset
// b_s(t) (world NED, T; 3 parameters per sensor and epoch), estimated
// together with the tracks that see that sensor, so that a near vessel's B
// is explained by its track's dipole model and what is slow at a sensor (a
// far ship's B, tens of nT per minute; a sensor's drift) by the offset.
//
// The joint problem, per cluster (tracks coupled through the sensors in
// their windows, TrackClusters; clusters that share no sensor are
// independent):
//   min Σ_samples ‖W(z − Σ_tracks h(x_track) − [b_s(t); 0])‖²
//     + Σ_s ‖b_s(t_first)‖²/σ_0² + Σ_s Σ_k ‖b_s(t_k+1) − b_s(t_k)‖²/(q·Δt)
// (σ_0 = prior_sigma_T about B0, q = walk_T_per_sqrt_s², a random walk
// between epochs). It is solved by blocks (Gauss–Seidel): given the tracks,
// the offsets are linear and separate per sensor — each sensor's series is
// the exact minimiser of its part, a Kalman (RTS) smoother over the residual
// B = sample − B0 − Σ tracks' predicted B (SmoothOffsets); given the
// offsets, each track's window (or batch) solve takes them in its
// measurement model (WindowTracker::SetBackgroundOffsets; the batch: the
// samples minus the offsets). The window tracker does one offset step per
// window solve interval, warm-started from the tracks' previous solve (the
// windows overlap; the prior's mean at the window's start is the previous
// step's offset there), the batch one per refinement round. Block
// coordinate descent, not one Gauss–Newton over tracks and offsets: each
// step lowers the joint cost. A sample does not enter its sensor's offset
// (which random-walks through it) if its residual tensor (whitened,
// ‖·‖²/9) exceeds tensor_gate (a source no track explains) or the tracks'
// predicted tensor there reaches occupied_tensor_snr (a tracked vessel is
// near: its B is its track's to explain; without this rule two vessels near
// each other lost their tracks on the tuning files, the offsets taking their
// model errors).
//
// Off by default: on the scenario files it helps some kinds and harms
// others (docs/ACCURACY.md, "Background in the cluster solve": the
// dynamics table, the scenario scores; cost against cluster size in
// docs/BENCHMARKS.md).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "magnav/core/gradiometer.h"
#include "magnav/core/motion.h"
#include "magnav/tracker/options.h"
#include "magnav/tracker/tracker.h"

namespace magnav {
class StateWriter;
class StateReader;
}  // namespace magnav

namespace magnav::tracker {

struct ClusterBackgroundOptions {
  // Off (the default): the fixed B0 (docs/ACCURACY.md says why). The values
  // below are the option's, chosen on the tuning scenarios only.
  bool enabled = false;
  // Zero-mean prior of each offset about B0 at the start of the span it is
  // estimated over (T, 1 σ per axis): wide, so the level comes from the
  // data (a drift of 4 nT/min is 20 nT after 5 min; a far ship's B is tens
  // of nT).
  double prior_sigma_T = 100e-9;
  // Random walk of the offset between epochs (T per √s, per axis): follows
  // a far ship's tens of nT per minute, not a near vessel's hundreds of nT
  // within seconds (docs/ACCURACY.md, the dynamics table).
  double walk_T_per_sqrt_s = 0.2e-9;
  // Its rate of change as a state too (an integrated random walk: white
  // acceleration of this density, T/s per √s; the rate's prior is zero with
  // σ prior_rate_sigma_T_per_s), so that a level followed before a vessel
  // comes near is carried across the occupied samples along its trend (a
  // far ship's B changes by ~0.5 nT/s). 0: the level's random walk alone.
  double rate_walk_T_per_s_per_sqrt_s = 0.0;
  double prior_rate_sigma_T_per_s = 1e-9;
  // A sample whose residual tensor (sample minus every track's predicted
  // tensor, whitened with σ_T and the tracks' model error, ‖·‖²/9) exceeds
  // this does not enter its sensor's offset.
  double tensor_gate = 4.0;
  // In a sample's residual B, the tracks' predicted B is taken as uncertain
  // by this share of its norm (per axis: over √3), added in quadrature to
  // σ_B: near a vessel, where a track's model error is large, the offset
  // comes from the sensor's quieter samples and the random walk carries it
  // across the pass. (The window and batch solves take the other tracks'
  // fields as uncertain by MultiTrackerOptions::kOtherFieldRelativeError.)
  double track_field_share = 0.05;
  // A sample where the tracks' predicted tensor SNR (‖Σ T̂‖_F/σ_T) is at
  // least this is near a tracked vessel ("occupied"): it does not enter the
  // offset, which is carried across by its random walk from the sensor's
  // other samples (and, in the window, from the previous offset step: the
  // prior's mean). 0 = every sample enters.
  double occupied_tensor_snr = 3.0;

  bool IsValid(std::string* error) const;
};

// One sensor's residual B at one epoch: the sample minus B0 minus every
// track's predicted B (world NED, T), with its variance per axis (T²).
struct OffsetSample {
  double t_s = 0.0;
  Eigen::Vector3d r_W = Eigen::Vector3d::Zero();
  double var_T2 = 0.0;
};
// The offset's smoothed estimate at a sample's time.
struct OffsetEstimate {
  double t_s = 0.0;
  Eigen::Vector3d b_W = Eigen::Vector3d::Zero();
  double var_T2 = 0.0;
};
// The minimiser of one sensor's part of the joint cost given the tracks:
// a random-walk Kalman filter from N(0, prior_sigma_T²) at the first sample
// and the Rauch–Tung–Striebel pass back. `series` in time order; one
// estimate per sample.
// `prior_mean_W`: the prior's mean at the first sample (zero: B0).
std::vector<OffsetEstimate> SmoothOffsets(const std::vector<OffsetSample>& series,
                                          const ClusterBackgroundOptions& options,
                                          const Eigen::Vector3d& prior_mean_W = Eigen::Vector3d::Zero());

// Connected components of tracks coupled by a shared sensor: `sensors[i]`
// lists track i's sensors (any order). Each cluster is its tracks'
// indices, ascending; clusters ordered by their first track.
std::vector<std::vector<std::size_t>> TrackClusters(const std::vector<std::vector<std::uint32_t>>& sensors);

// Every sensor's offset series: zero for a sensor not estimated, the first
// estimate before the series, the newest after it (held), else the latest
// estimate at or before t_s.
class SensorOffsets {
 public:
  void Set(std::uint32_t sensor_id, std::vector<OffsetEstimate> series);
  void Clear() { series_.clear(); }
  Eigen::Vector3d At(std::uint32_t sensor_id, double t_s) const;
  bool Has(std::uint32_t sensor_id) const { return series_.count(sensor_id) != 0; }
  std::size_t num_sensors() const { return series_.size(); }
  void SaveState(StateWriter& w) const;
  void RestoreState(StateReader& r);

 private:
  std::map<std::uint32_t, std::vector<OffsetEstimate>> series_;
};

// A track as the offset step sees it: its state at a time (nullopt: no
// state then, its field is left out), its body moment and its sensors.
struct ClusterTrack {
  std::function<std::optional<CtState<double>>(double t_s)> state_at;
  Eigen::Vector3d m_B_Am2 = Eigen::Vector3d::Zero();
  std::vector<std::uint32_t> sensors;
};

// What one offset step did (for the cost table).
struct ClusterStepStats {
  std::vector<int> cluster_tracks;   // tracks per cluster
  std::vector<int> cluster_sensors;  // sensors per cluster
  int num_samples_used = 0;
  int num_samples_gated = 0;  // residual tensor above tensor_gate
  int num_samples_occupied = 0;  // a track's tensor at or above occupied_tensor_snr
};

// The offset step: every sensor of every track (`tracks[i].sensors`) gets
// the smoothed series of its residual B over `epochs` (time order), the
// fields of every track with a state at that time removed. Sensors of no
// track are not set. Replaces `offsets`' series of those sensors. `prior`
// (may be null): each sensor's prior mean is its offset there at the first
// epoch (the previous step's).
ClusterStepStats EstimateClusterOffsets(const std::vector<const Epoch*>& epochs, const std::vector<ClusterTrack>& tracks,
                                        const Eigen::Vector3d& B0_W, const TrackerOptions& track_options,
                                        const ClusterBackgroundOptions& options, const SensorOffsets* prior,
                                        SensorOffsets* offsets);

}  // namespace magnav::tracker
