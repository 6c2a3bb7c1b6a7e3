#include "magnav/localizer/options.h"

#include <cmath>
#include <string>

#include "magnav/core/option_check.h"

namespace magnav::localizer {

bool LocalizerProcessNoise::IsValid(std::string* error) const {
  if (!PositiveFinite(position_m_per_sqrt_s)) return Fail(error, "process.position_m_per_sqrt_s must be > 0");
  if (!PositiveFinite(speed_mps_per_sqrt_s)) return Fail(error, "process.speed_mps_per_sqrt_s must be > 0");
  if (!PositiveFinite(heading_rad_per_sqrt_s)) return Fail(error, "process.heading_rad_per_sqrt_s must be > 0");
  if (!PositiveFinite(turn_rate_radps_per_sqrt_s)) {
    return Fail(error, "process.turn_rate_radps_per_sqrt_s must be > 0");
  }
  return true;
}

bool InitialVesselSigma::IsValid(std::string* error) const {
  if (!PositiveFinite(position_m)) return Fail(error, "initial.position_m must be > 0");
  if (!PositiveFinite(speed_mps)) return Fail(error, "initial.speed_mps must be > 0");
  if (!PositiveFinite(heading_rad)) return Fail(error, "initial.heading_rad must be > 0");
  if (!PositiveFinite(turn_rate_radps)) return Fail(error, "initial.turn_rate_radps must be > 0");
  return true;
}

bool LocalizerOptions::IsValid(std::string* error) const {
  if (!process.IsValid(error) || !initial.IsValid(error)) return false;
  if (vessel_start && !vessel_start->allFinite()) return Fail(error, "vessel_start must be finite");
  if (!PositiveFinite(sigma_B_T)) return Fail(error, "sigma_B_T must be > 0");
  if (!(gnss_sigma_m >= 0.0) || !std::isfinite(gnss_sigma_m)) return Fail(error, "gnss_sigma_m must be >= 0");
  if (magnetometer_loss != LossType::kTrivial && !PositiveFinite(magnetometer_loss_scale_sigma)) {
    return Fail(error, "magnetometer_loss_scale_sigma must be > 0");
  }
  if (gnss_loss != LossType::kTrivial && !PositiveFinite(gnss_loss_scale_sigma)) {
    return Fail(error, "gnss_loss_scale_sigma must be > 0");
  }
  if (!(gate_probability > 0.0 && gate_probability <= 1.0)) {
    return Fail(error, "gate_probability must be in (0, 1] (1 = no gate)");
  }
  if (gate_release_after < 0) return Fail(error, "gate_release_after must be >= 0 (0 = never)");
  if (magnetometer_iterations < 1 || magnetometer_iterations > kMaxMagnetometerIterations) {
    return Fail(error, "magnetometer_iterations must be in [1, " + std::to_string(kMaxMagnetometerIterations) + "]");
  }
  if (max_num_iterations < 1) return Fail(error, "max_num_iterations must be >= 1");
  if (!(function_tolerance >= 0.0) || !(gradient_tolerance >= 0.0) || !(parameter_tolerance >= 0.0)) {
    return Fail(error, "solver tolerances must be >= 0");
  }
  if (num_threads < 1) return Fail(error, "num_threads must be >= 1");
  if (!(epoch_tolerance_s >= 0.0) || !std::isfinite(epoch_tolerance_s)) {
    return Fail(error, "epoch_tolerance_s must be >= 0");
  }
  return true;
}

}  // namespace magnav::localizer
