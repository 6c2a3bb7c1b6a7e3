#include "magnav/tracker/background.h"

#include <cmath>

#include "magnav/core/checkpoint.h"
#include "magnav/core/option_check.h"
#include "state_io.h"

namespace magnav::tracker {

bool BackgroundOptions::IsValid(std::string* error) const {
  if (!PositiveFinite(rate_walk_T_per_s_per_sqrt_s)) return Fail(error, "background rate walk must be > 0");
  if (!(level_walk_T_per_sqrt_s >= 0.0) || !std::isfinite(level_walk_T_per_sqrt_s)) {
    return Fail(error, "background level walk must be finite and >= 0");
  }
  if (!PositiveFinite(initial_sigma_T)) return Fail(error, "background initial sigma must be > 0");
  if (!PositiveFinite(initial_rate_sigma_T_per_s)) return Fail(error, "background initial rate sigma must be > 0");
  if (!PositiveFinite(gate_chi2)) return Fail(error, "background gate_chi2 must be > 0");
  if (!PositiveFinite(occupied_tensor_chi2)) return Fail(error, "background occupied_tensor_chi2 must be > 0");
  if (!PositiveFinite(occupied_average_s)) return Fail(error, "background occupied_average_s must be > 0");
  return true;
}

SensorBackgrounds::SensorBackgrounds(const Eigen::Vector3d& B0_W, const BackgroundOptions& options)
    : B0_W_(B0_W), options_(options) {}

SensorBackgrounds::Filter SensorBackgrounds::Fresh(double t_s) const {
  Filter f;
  f.t_s = t_s;
  f.x.col(0) = B0_W_;
  f.P(0, 0) = options_.initial_sigma_T * options_.initial_sigma_T;
  f.P(1, 1) = options_.initial_rate_sigma_T_per_s * options_.initial_rate_sigma_T_per_s;
  return f;
}

void SensorBackgrounds::Propagate(Filter* f, double t_s) const {
  const double dt = t_s - f->t_s;
  if (!(dt > 0.0)) return;
  f->x.col(0) += dt * f->x.col(1);
  Eigen::Matrix2d F;
  F << 1.0, dt, 0.0, 1.0;
  const double qa = options_.rate_walk_T_per_s_per_sqrt_s * options_.rate_walk_T_per_s_per_sqrt_s;
  const double ql = options_.level_walk_T_per_sqrt_s * options_.level_walk_T_per_sqrt_s;
  Eigen::Matrix2d Q;
  Q << qa * dt * dt * dt / 3.0 + ql * dt, qa * dt * dt / 2.0, qa * dt * dt / 2.0, qa * dt;
  f->P = F * f->P * F.transpose() + Q;
  f->t_s = t_s;
}

BackgroundEstimate SensorBackgrounds::Predict(std::uint32_t sensor_id, double t_s) const {
  const auto it = filters_.find(sensor_id);
  Filter f = it == filters_.end() ? Fresh(t_s) : it->second;
  Propagate(&f, t_s);
  return {f.x.col(0), std::sqrt(std::max(f.P(0, 0), 0.0))};
}

bool SensorBackgrounds::Update(std::uint32_t sensor_id, double t_s, const Eigen::Vector3d& residual_B_W,
                               double var_T2, double residual_T_chi2_per_element) {
  auto it = filters_.find(sensor_id);
  if (it == filters_.end()) it = filters_.emplace(sensor_id, Fresh(t_s)).first;
  Filter& f = it->second;
  const double dt = std::max(t_s - f.t_s, 0.0);
  if (std::isfinite(residual_T_chi2_per_element)) {
    const double a = 1.0 - std::exp(-dt / options_.occupied_average_s);
    f.tensor_chi2 += a * (residual_T_chi2_per_element - f.tensor_chi2);
  }
  if (f.tensor_chi2 > options_.occupied_tensor_chi2) {
    // Occupied: the level is held (its rate, learnt partly from the near
    // source's approach, is not extrapolated) and its σ grows.
    ++num_occupied_;
    const Eigen::Vector3d rate = f.x.col(1);
    f.x.col(1).setZero();
    Propagate(&f, t_s);
    f.x.col(1) = rate;
    return false;
  }
  Propagate(&f, t_s);
  double S = f.P(0, 0) + var_T2;
  const Eigen::Vector3d nu = residual_B_W - f.x.col(0);
  if (!(S > 0.0) || !nu.allFinite()) return false;
  const double chi2 = nu.squaredNorm() / S;
  bool taken = true;
  if (chi2 > options_.gate_chi2) {
    // Huber-like: the measurement's variance widened until the innovation
    // is at the gate, so a near vessel moves the background by at most
    // P·gate/‖ν‖ per update (less the stronger it is).
    ++num_gated_;
    taken = false;
    S = nu.squaredNorm() / options_.gate_chi2;
  }
  const Eigen::Vector2d K = f.P.col(0) / S;
  f.x += nu * K.transpose();
  f.P -= K * K.transpose() * S;
  f.P = 0.5 * (f.P + f.P.transpose());
  return taken;
}

void SensorBackgrounds::SaveState(StateWriter& w) const {
  w.U64(filters_.size());
  for (const auto& [id, f] : filters_) {
    w.U32(id);
    w.F64(f.t_s);
    w.Matrix(f.x);
    w.Matrix(f.P);
    w.F64(f.tensor_chi2);
  }
  w.I64(num_gated_);
  w.I64(num_occupied_);
}

void SensorBackgrounds::RestoreState(StateReader& r) {
  std::map<std::uint32_t, Filter> filters;
  for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) {
    const std::uint32_t id = r.U32();
    Filter f;
    f.t_s = r.F64();
    f.x = internal::GetMatrix(r, 3, 2);
    f.P = internal::GetMatrix(r, 2, 2);
    f.tensor_chi2 = r.F64();
    filters[id] = f;
  }
  const long gated = static_cast<long>(r.I64());
  const long occupied = static_cast<long>(r.I64());
  num_occupied_ = occupied;
  filters_ = std::move(filters);
  num_gated_ = gated;
}

}  // namespace magnav::tracker
