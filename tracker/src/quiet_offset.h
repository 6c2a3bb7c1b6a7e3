// Internal: each sensor's B offset owned by the sensor and started from its
// quiet data (SensorOffsetOptions::quiet, options.h; issue 24 item 1).
//
// Per sensor, the residual B (world NED, T: sample − B0 − the live tracks'
// predicted B − the far source's) of the samples it gave while quiet (the
// caller's rule: no track's field, no untracked near source there), over the
// last span_s of such samples. The offset is their per-axis median; its σ
// the median's spread widened by a random walk at the drift-rate bound from
// the samples' median time to the time asked. A vessel's B (hundreds of nT
// within seconds) is not in them; a drift (a few nT/min) is.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <map>

#include "magnav/tracker/options.h"

namespace magnav::tracker::internal {

class QuietOffsets {
 public:
  explicit QuietOffsets(const SensorOffsetOptions& options = {}) : options_(options) {}
  // One quiet sample's residual B at sensor_id, time t_s (samples in time order).
  void Add(std::uint32_t sensor_id, double t_s, const Eigen::Vector3d& r_W);
  // The sensor's offset at t_s (world NED, T) and its σ per axis (T); false
  // (nothing set) with fewer than quiet_min_samples quiet samples.
  bool Prior(std::uint32_t sensor_id, double t_s, Eigen::Vector3d* mean_W, double* sigma_T) const;
  int num_quiet(std::uint32_t sensor_id) const;

 private:
  struct Item {
    double t_s;
    Eigen::Vector3d r_W;
  };
  SensorOffsetOptions options_;
  std::map<std::uint32_t, std::deque<Item>> sensors_;
};

}  // namespace magnav::tracker::internal
