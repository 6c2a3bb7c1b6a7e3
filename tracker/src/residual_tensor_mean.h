// Each sensor's residual tensor averaged over its last few seconds: the
// drift's rule against an untracked near vessel (sensor_drift.h,
// SensorDriftOptions::tensor_mean_window_s). One sample's residual tensor
// (sample minus every live track's predicted tensor) does not see a vessel
// 25–50 m from a sensor (its tensor SNR 0.1–1.8 per sample) while its B
// there, 3–30 nT, is what pulls a drift line (docs/ACCURACY.md, "The drift
// lines kept off an untracked vessel's B"); over 10 s at 10 Hz the mean's
// noise is √100 smaller, and a drift has no tensor at all.
//
// z = ‖Σ e_i‖_F² / Σ v_i / 9 over the sensor's samples i in the window:
// e_i the residual tensor (T/m), v_i its variance per element (T²/m²: σ_T²
// plus the tracks' model error); under white noise alone z ~ χ²₉/9 (mean 1).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <map>

namespace magnav::tracker::internal {

class ResidualTensorMean {
 public:
  explicit ResidualTensorMean(double window_s = 10.0) : window_s_(window_s) {}
  double window_s() const { return window_s_; }
  // Adds one sample's residual tensor at a sensor (samples in time order).
  void Add(std::uint32_t sensor_id, double t_s, const Eigen::Matrix3d& e, double var) {
    if (!(window_s_ > 0.0)) return;
    Series& s = series_[sensor_id];
    s.items.push_back({t_s, e, var});
    s.sum += e;
    s.var += var;
    while (!s.items.empty() && t_s - s.items.front().t_s > window_s_ + 1e-9) {
      s.sum -= s.items.front().e;
      s.var -= s.items.front().var;
      s.items.pop_front();
    }
  }
  // z of the sensor's window (0 with no sample, or when off).
  double Z(std::uint32_t sensor_id) const {
    const auto it = series_.find(sensor_id);
    if (it == series_.end() || it->second.items.empty() || !(it->second.var > 0.0)) return 0.0;
    return it->second.sum.squaredNorm() / it->second.var / 9.0;
  }

 private:
  struct Item {
    double t_s;
    Eigen::Matrix3d e;
    double var;
  };
  struct Series {
    std::deque<Item> items;
    Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
    double var = 0.0;
  };
  double window_s_;
  std::map<std::uint32_t, Series> series_;
};

}  // namespace magnav::tracker::internal
