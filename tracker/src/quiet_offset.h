// Internal: each sensor's B offset owned by the sensor and started from its
// quiet data (SensorOffsetOptions::quiet, options.h; issue 24 item 1).
//
// Per sensor, the residual B (world NED, T: sample − B0 − the live tracks'
// predicted B − the far source's) of the samples it gave while quiet (the
// caller's rule: no track's field, no untracked near source there), over the
// last span of such samples (quiet_span_s; with quiet_rate, at least
// quiet_rate_span_s). A vessel's B (hundreds of nT within seconds) is not in
// them; a drift (a few nT/min) is.
//
// Without quiet_rate the offset is their per-axis median; its σ the median's
// spread widened by a random walk at the drift-rate bound from the samples'
// median time to the time asked (session 17: stale by rate × age on a ramp).
// With quiet_rate it is a line in time, level + rate · (t − t_ref), fitted
// robustly per axis: the rate from the medians of the store's older and
// newer halves ((m₂ − m₁)/(t₂ − t₁), bounded by max_rate_T_per_s), the level
// the median of the samples with that rate taken out, at the store's median
// time t_ref; its σ² = σ_level² + (σ_rate · (t − t_ref))², from the spread of
// the detrended samples (the σ grows with the extrapolation). A store whose
// halves are less than kMinRateBaseline_s apart keeps the median and the walk.
//
// TakeOut (quiet_approach): when a track is confirmed, its back-predicted
// field at each stored sample is taken out of it — the sample dropped where the track
// would have made it not quiet (its predicted tensor SNR ≥ 3 or B ≥ 3 σ_B,
// the caller's rule), else its predicted B subtracted — so the store no
// longer holds the B of the vessel's approach before it had a track.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>

#include "magnav/tracker/options.h"

namespace magnav::tracker::internal {

// What a stored sample was taken out for (QuietOffsets::TakeOut).
struct QuietTakeOutStats {
  int dropped = 0;     // samples dropped (the track's field made them not quiet)
  int corrected = 0;   // samples whose residual B lost the track's predicted B
  double max_B_T = 0;  // the largest predicted B subtracted from a kept sample, T
};

class QuietOffsets {
 public:
  // Where the half-medians' times are less than this apart (s), no rate.
  static constexpr double kMinRateBaseline_s = 10.0;

  explicit QuietOffsets(const SensorOffsetOptions& options = {}) : options_(options) {}
  // One quiet sample's residual B at sensor_id, time t_s (samples in time
  // order), with the sensor's position (world NED, m) and σ_B, σ_T (T, T/m).
  void Add(std::uint32_t sensor_id, double t_s, const Eigen::Vector3d& r_W, const Eigen::Vector3d& p_SinW = {},
           double sigma_B_T = 0.0, double sigma_T_Tpm = 0.0);
  // The sensor's offset at t_s (world NED, T) and its σ per axis (T); false
  // (nothing set) with fewer than quiet_min_samples quiet samples.
  bool Prior(std::uint32_t sensor_id, double t_s, Eigen::Vector3d* mean_W, double* sigma_T) const;
  // The line behind Prior with quiet_rate: its rate (T/s, world NED); false
  // where no rate is fitted (off, too few samples or too short a baseline).
  bool Rate(std::uint32_t sensor_id, Eigen::Vector3d* rate_W) const;
  int num_quiet(std::uint32_t sensor_id) const;

  // A new track's field at a stored sample: its predicted B (T, world NED)
  // and whether it would have made the sample not quiet; false: no
  // prediction there (the sample kept as it is).
  using FieldAtFn = std::function<bool(std::uint32_t sensor_id, double t_s, const Eigen::Vector3d& p_SinW,
                                       double sigma_B_T, double sigma_T_Tpm, Eigen::Vector3d* B_W, bool* not_quiet)>;
  QuietTakeOutStats TakeOut(const FieldAtFn& field_at);

 private:
  struct Item {
    double t_s;
    Eigen::Vector3d r_W;
    Eigen::Vector3d p_SinW;
    double sigma_B_T;
    double sigma_T_Tpm;
  };
  struct Fit {
    bool has_rate = false;
    double t_ref_s = 0.0;
    Eigen::Vector3d level_W = Eigen::Vector3d::Zero();
    Eigen::Vector3d rate_W = Eigen::Vector3d::Zero();
    double sigma_level_T = 0.0;
    double sigma_rate_Tps = 0.0;
  };
  double SpanS() const;
  Fit FitOf(const std::deque<Item>& d) const;

  SensorOffsetOptions options_;
  std::map<std::uint32_t, std::deque<Item>> sensors_;
  mutable std::map<std::uint32_t, Fit> fits_;  // per sensor, dropped when its store changes
};

}  // namespace magnav::tracker::internal
