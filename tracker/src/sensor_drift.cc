#include "magnav/tracker/sensor_drift.h"

#include "magnav/core/checkpoint.h"
#include "state_io.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace magnav::tracker {
namespace {

bool Fail(std::string* error, const std::string& why) {
  if (error != nullptr) *error = "sensor_drift: " + why;
  return false;
}

// Reweighted least-squares passes of the Huber loss from the median start.
constexpr int kHuberPasses = 8;

}  // namespace

bool SensorDriftOptions::IsValid(std::string* error) const {
  if (!(rate_prior_sigma_T_per_s > 0.0) || !(rate_prior_sigma_T_per_s <= 1.0)) {
    return Fail(error, "rate_prior_sigma_T_per_s must be in (0, 1] T/s");
  }
  if (!(huber_sigmas > 0.0) || !std::isfinite(huber_sigmas)) return Fail(error, "huber_sigmas must be > 0");
  if (!(reject_sigmas >= huber_sigmas) || std::isnan(reject_sigmas)) {
    return Fail(error, "reject_sigmas must be >= huber_sigmas");
  }
  if (min_samples < 2) return Fail(error, "min_samples must be >= 2");
  if (!(max_rate_T_per_s > 0.0)) return Fail(error, "max_rate_T_per_s must be > 0");
  if (!(occupied_B_sigmas > 0.0)) return Fail(error, "occupied_B_sigmas must be > 0");
  if (!(tensor_mean_window_s >= 0.0) || !std::isfinite(tensor_mean_window_s)) {
    return Fail(error, "tensor_mean_window_s must be >= 0 (0 = off)");
  }
  if (!(tensor_mean_gate > 0.0)) return Fail(error, "tensor_mean_gate must be > 0");
  if (!(window_s > 0.0) || !std::isfinite(window_s)) return Fail(error, "window_s must be > 0");
  if (!(sample_interval_s >= 0.0) || !std::isfinite(sample_interval_s)) {
    return Fail(error, "sample_interval_s must be >= 0");
  }
  if (!(min_span_s >= 0.0) || !std::isfinite(min_span_s)) return Fail(error, "min_span_s must be >= 0");
  if (!(confirm_min_rate_T_per_s >= 0.0) || !std::isfinite(confirm_min_rate_T_per_s)) {
    return Fail(error, "confirm_min_rate_T_per_s must be >= 0");
  }
  if (!(confirm_rate_sigmas >= 0.0) || !std::isfinite(confirm_rate_sigmas)) {
    return Fail(error, "confirm_rate_sigmas must be >= 0");
  }
  return true;
}

bool DriftLine::Confirmed(const SensorDriftOptions& options) const {
  const double r = rate_W.norm();
  return r >= options.confirm_min_rate_T_per_s && r >= options.confirm_rate_sigmas * std::sqrt(std::max(0.0, var_rate));
}

double DriftLine::SigmaAt(double t_s) const {
  const double dt = t_s - t_ref_s;
  return std::sqrt(std::max(0.0, var_offset + 2.0 * dt * cov_offset_rate + dt * dt * var_rate));
}

bool FitDriftLine(const std::vector<DriftSample>& samples, const SensorDriftOptions& options, DriftLine* line,
                  const DriftLine* warm) {
  if (static_cast<int>(samples.size()) < options.min_samples) return false;
  double t0 = samples.front().t_s, t1 = t0;
  for (const DriftSample& s : samples) {
    t0 = std::min(t0, s.t_s);
    t1 = std::max(t1, s.t_s);
  }
  if (t1 - t0 < options.min_span_s) return false;
  const double t_ref = t1;
  const double prior_w = 1.0 / (options.rate_prior_sigma_T_per_s * options.rate_prior_sigma_T_per_s);
  // The start: the previous line (warm), else each axis' median and no rate
  // (a bell of a near vessel is a minority of the window's samples; least
  // squares would start inside it).
  Eigen::Matrix<double, 2, 3> x = Eigen::Matrix<double, 2, 3>::Zero();  // rows: offset, rate; columns: axes
  if (warm != nullptr) {
    x.row(0) = warm->At(t_ref).transpose();
    x.row(1) = warm->rate_W.transpose();
  } else {
    std::vector<double> v(samples.size());
    for (int a = 0; a < 3; ++a) {
      for (std::size_t i = 0; i < samples.size(); ++i) v[i] = samples[i].r_W(a);
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      x(0, a) = v[v.size() / 2];
    }
  }
  std::vector<double> w(samples.size(), 1.0);
  Eigen::Matrix2d N;
  for (int pass = 0; pass <= kHuberPasses; ++pass) {
    // Huber weights on the whitened residual's norm per axis.
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const DriftSample& s = samples[i];
      const Eigen::Vector3d e = s.r_W - (x.row(0) + x.row(1) * (s.t_s - t_ref)).transpose();
      const double z = e.norm() / s.sigma_T / std::sqrt(3.0);
      w[i] = z <= options.huber_sigmas ? 1.0 : options.huber_sigmas / z;
      // Rejected outright beyond reject_sigmas once the line is a line (from
      // a warm start at once, from the median's after half the passes).
      if (z > options.reject_sigmas && (warm != nullptr || pass >= kHuberPasses / 2)) w[i] = 0.0;
    }
    N.setZero();
    N(1, 1) = prior_w;
    Eigen::Matrix<double, 2, 3> b = Eigen::Matrix<double, 2, 3>::Zero();
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const DriftSample& s = samples[i];
      const double dt = s.t_s - t_ref;
      const double wi = w[i] / (s.sigma_T * s.sigma_T);
      const Eigen::Vector2d h(1.0, dt);
      N += wi * h * h.transpose();
      b += wi * h * s.r_W.transpose();
    }
    const Eigen::LDLT<Eigen::Matrix2d> ldlt(N);
    if (ldlt.info() != Eigen::Success) return false;
    x = ldlt.solve(b);
    if (!x.allFinite()) return false;
  }
  int kept = 0;
  for (double wi : w) kept += wi > 0.0 ? 1 : 0;
  if (kept < options.min_samples) {
    // Most samples rejected: the warm line no longer fits (or nothing is
    // quiet): again from the median.
    return warm != nullptr && FitDriftLine(samples, options, line, nullptr);
  }
  if (!(x.row(1).norm() <= options.max_rate_T_per_s)) return false;
  const Eigen::Matrix2d C = N.inverse();
  line->t_ref_s = t_ref;
  line->offset_W = x.row(0).transpose();
  line->rate_W = x.row(1).transpose();
  line->var_offset = C(0, 0);
  line->cov_offset_rate = C(0, 1);
  line->var_rate = C(1, 1);
  line->num_samples = static_cast<int>(samples.size());
  return true;
}

void SensorDrift::Fit(const std::vector<DriftSample>& samples) {
  if (!options_.enabled) return;
  std::map<std::uint32_t, std::vector<DriftSample>> by_sensor;
  for (const DriftSample& s : samples) by_sensor[s.sensor_id].push_back(s);
  for (const auto& [id, series] : by_sensor) {
    DriftLine line;
    const auto it = lines_.find(id);
    // From the median, not from the previous line: a line once pulled by a
    // vessel's B, warm-started, keeps the samples that agree with it and
    // rejects the newer ones (docs/ACCURACY.md, "The drift lines kept off an
    // untracked vessel's B").
    const DriftLine* warm = options_.warm_start && it != lines_.end() ? &it->second : nullptr;
    if (FitDriftLine(series, options_, &line, warm)) lines_[id] = line;
  }
}

Eigen::Vector3d SensorDrift::At(std::uint32_t sensor_id, double t_s, double* sigma_T) const {
  if (sigma_T != nullptr) *sigma_T = 0.0;
  const auto it = lines_.find(sensor_id);
  if (!options_.enabled || it == lines_.end() || !it->second.Confirmed(options_)) return Eigen::Vector3d::Zero();
  if (sigma_T != nullptr) *sigma_T = it->second.SigmaAt(t_s);
  return it->second.At(t_s);
}

void SensorDrift::SaveState(StateWriter& w) const {
  w.U64(lines_.size());
  for (const auto& [id, l] : lines_) {
    w.U32(id);
    w.F64(l.t_ref_s);
    w.Matrix(l.offset_W);
    w.Matrix(l.rate_W);
    for (double v : {l.var_offset, l.cov_offset_rate, l.var_rate}) w.F64(v);
    w.I64(l.num_samples);
  }
}

void SensorDrift::RestoreState(StateReader& r) {
  std::map<std::uint32_t, DriftLine> lines;
  for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) {
    const std::uint32_t id = r.U32();
    DriftLine l;
    l.t_ref_s = r.F64();
    l.offset_W = internal::GetMatrix(r, 3, 1);
    l.rate_W = internal::GetMatrix(r, 3, 1);
    l.var_offset = r.F64();
    l.cov_offset_rate = r.F64();
    l.var_rate = r.F64();
    l.num_samples = static_cast<int>(r.I64());
    lines[id] = l;
  }
  lines_ = std::move(lines);
}

}  // namespace magnav::tracker
