#include "magnav/core/regional_field.h"

#include <cmath>

#include "magnav/core/error.h"
#include "magnav/core/option_check.h"

namespace magnav {

namespace {
bool FinitePositive(double v) { return std::isfinite(v) && v > 0.0; }
}  // namespace

bool RegionalFieldOptions::IsValid(std::string* error) const {
  if (!FinitePositive(window_s)) return Fail(error, "window_s must be finite and > 0");
  if (min_samples < 2) return Fail(error, "min_samples must be >= 2");
  if (!FinitePositive(max_tensor_rms_sigmas)) return Fail(error, "max_tensor_rms_sigmas must be finite and > 0");
  if (!FinitePositive(max_field_std_sigmas)) return Fail(error, "max_field_std_sigmas must be finite and > 0");
  if (!(refresh_after_s >= 0.0)) return Fail(error, "refresh_after_s must be >= 0");
  if (!FinitePositive(max_drift_sigmas)) return Fail(error, "max_drift_sigmas must be finite and > 0");
  if (!(sigma_B_fallback >= 0.0) || !std::isfinite(sigma_B_fallback)) {
    return Fail(error, "sigma_B_fallback must be finite and >= 0");
  }
  if (!(sigma_T_fallback >= 0.0) || !std::isfinite(sigma_T_fallback)) {
    return Fail(error, "sigma_T_fallback must be finite and >= 0");
  }
  return true;
}

RegionalFieldEstimator::RegionalFieldEstimator(const RegionalFieldOptions& options) : options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw InputError("regional field options: " + error);
}

RegionalFieldEstimator::Status RegionalFieldEstimator::Add(const GradiometerSample& s) {
  if (CheckSample(s) != SampleDefect::kNone) return Status::kBadSample;
  const double sigma_B = s.sigma_B > 0.0 ? s.sigma_B : options_.sigma_B_fallback;
  const double sigma_T = s.sigma_T > 0.0 ? s.sigma_T : options_.sigma_T_fallback;
  Sensor& sensor = sensors_[s.sensor_id];
  if (!(sigma_B > 0.0) || !(sigma_T > 0.0)) return Status::kUnknownSigma;
  const Status idle = sensor.B0 ? Status::kReady : Status::kNotReady;
  if (sensor.B0 && s.t_s - sensor.t_estimate_s < options_.refresh_after_s && s.t_s >= sensor.t_estimate_s) {
    return idle;  // not due for a refresh: nothing to judge
  }

  auto& w = sensor.window;
  if (!w.empty() && s.t_s < w.back().t_s) w.clear();  // time went back: start afresh
  w.push_back({s.t_s, s.B, s.T.squaredNorm()});
  while (s.t_s - w.front().t_s > options_.window_s) w.pop_front();
  const int n = static_cast<int>(w.size());
  // A stretch is judged once it spans (almost) the whole window.
  if (n < options_.min_samples || s.t_s - w.front().t_s < 0.9 * options_.window_s) return idle;

  double t_sq = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Entry& e : w) {
    t_sq += e.t_norm_sq;
    mean += e.B;
  }
  mean /= n;
  const double limit_T = options_.max_tensor_rms_sigmas * sigma_T;
  if (t_sq / n > limit_T * limit_T) return idle;
  // Second pass about the mean (B ≫ σ_B: no sum of squares).
  Eigen::Vector3d var = Eigen::Vector3d::Zero(), first_half = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d d = w[i].B - mean;
    var += d.cwiseAbs2();
    if (i < n / 2) first_half += d;
  }
  var /= (n - 1);
  const double limit_B = options_.max_field_std_sigmas * sigma_B;
  if (var.maxCoeff() > limit_B * limit_B) return idle;
  // Drift: mean of the first half minus the second, from the deviations
  // (they sum to zero over the stretch).
  const double h1 = n / 2, h2 = n - n / 2;
  const Eigen::Vector3d drift = first_half / h1 + first_half / h2;
  if (drift.cwiseAbs().maxCoeff() > options_.max_drift_sigmas * sigma_B * std::sqrt(1.0 / h1 + 1.0 / h2)) {
    return idle;
  }

  const bool first = !sensor.B0.has_value();
  sensor.B0 = mean;
  sensor.t_estimate_s = s.t_s;
  sensor.n = n;
  return first ? Status::kBecameReady : Status::kReady;
}

std::optional<Eigen::Vector3d> RegionalFieldEstimator::B0(std::uint32_t sensor_id) const {
  const auto it = sensors_.find(sensor_id);
  if (it == sensors_.end()) return std::nullopt;
  return it->second.B0;
}

int RegionalFieldEstimator::num_samples(std::uint32_t sensor_id) const {
  const auto it = sensors_.find(sensor_id);
  return it == sensors_.end() ? 0 : it->second.n;
}

}  // namespace magnav
