#include "magnav/tracker/options.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "magnav/core/option_check.h"

namespace magnav::tracker {

bool ParseInitSource(const std::string& name, InitSource* source) {
  if (name == "samples") {
    *source = InitSource::kSamples;
  } else if (name == "dipole_fix") {
    *source = InitSource::kExternal;
  } else if (name == "auto") {
    *source = InitSource::kAuto;
  } else {
    return false;
  }
  return true;
}

const char* InitSourceName(InitSource source) {
  switch (source) {
    case InitSource::kSamples:
      return "samples";
    case InitSource::kExternal:
      return "dipole_fix";
    case InitSource::kAuto:
      return "auto";
  }
  return "?";
}

bool ProcessNoise::IsValid(std::string* error) const {
  if (!PositiveFinite(position_m_per_sqrt_s)) return Fail(error, "process.position_m_per_sqrt_s must be > 0");
  if (!PositiveFinite(depth_m_per_sqrt_s)) return Fail(error, "process.depth_m_per_sqrt_s must be > 0");
  if (!(depth_weak_m_per_sqrt_s >= 0.0 && std::isfinite(depth_weak_m_per_sqrt_s)))
    return Fail(error, "process.depth_weak_m_per_sqrt_s must be >= 0 (0 = off)");
  if (!PositiveFinite(depth_weak_tensor_snr)) return Fail(error, "process.depth_weak_tensor_snr must be > 0");
  if (!PositiveFinite(speed_mps_per_sqrt_s)) return Fail(error, "process.speed_mps_per_sqrt_s must be > 0");
  if (!PositiveFinite(heading_rad_per_sqrt_s))
    return Fail(error, "process.heading_rad_per_sqrt_s must be > 0");
  if (!PositiveFinite(turn_rate_radps_per_sqrt_s)) {
    return Fail(error, "process.turn_rate_radps_per_sqrt_s must be > 0");
  }
  if (!PositiveFinite(turn_rate_loss_scale_sigma)) {
    return Fail(error, "process.turn_rate_loss_scale_sigma must be > 0");
  }
  if (!PositiveFinite(window_turn_rate_radps_per_sqrt_s)) {
    return Fail(error, "process.window_turn_rate_radps_per_sqrt_s must be > 0");
  }
  if (!std::isfinite(turn_rate_warmup_radps_per_sqrt_s) || turn_rate_warmup_radps_per_sqrt_s < 0.0) {
    return Fail(error, "process.turn_rate_warmup_radps_per_sqrt_s must be >= 0");
  }
  return true;
}

bool InitOptions::IsValid(std::string* error) const {
  if (!PositiveFinite(min_tensor_snr)) return Fail(error, "init.min_tensor_snr must be > 0");
  if (min_fixes < 3) return Fail(error, "init.min_fixes must be >= 3");
  if (!std::isfinite(min_span_s) || min_span_s < 0.0) return Fail(error, "init.min_span_s must be >= 0");
  if (!PositiveFinite(span_s) || span_s < min_span_s) return Fail(error, "init.span_s must be >= min_span_s");
  if (!PositiveFinite(outlier_threshold_mad)) return Fail(error, "init.outlier_threshold_mad must be > 0");
  if (!(cluster_gate_m >= 0.0) || !std::isfinite(cluster_gate_m)) {
    return Fail(error, "init.cluster_gate_m must be finite and >= 0");
  }
  if (!(max_dipole_misfit >= 0.0) || !std::isfinite(max_dipole_misfit)) {
    return Fail(error, "init.max_dipole_misfit must be finite and >= 0");
  }
  if (!(fix_sigma_B_allowance_T >= 0.0) || !std::isfinite(fix_sigma_B_allowance_T)) {
    return Fail(error, "init.fix_sigma_B_allowance_T must be finite and >= 0");
  }
  return true;
}

double SensorOffsetOptions::PriorSigma(double t_s) const {
  const double drift = max_rate_T_per_s * std::max(0.0, t_s - b0_time_s);
  return std::sqrt(floor_T * floor_T + drift * drift);
}

double SensorOffsetOptions::StepSigma() const { return std::max(max_rate_T_per_s * segment_s, 0.1 * floor_T); }

bool SensorOffsetOptions::IsValid(std::string* error) const {
  if (!(max_rate_T_per_s >= 0.0) || !std::isfinite(max_rate_T_per_s)) {
    return Fail(error, "sensor_offset.max_rate_T_per_s must be finite and >= 0");
  }
  if (!PositiveFinite(floor_T)) return Fail(error, "sensor_offset.floor_T must be > 0");
  if (!std::isfinite(b0_time_s)) return Fail(error, "sensor_offset.b0_time_s must be finite");
  if (!PositiveFinite(segment_s)) return Fail(error, "sensor_offset.segment_s must be > 0");
  if (passes < 1 || batch_passes < 1) return Fail(error, "sensor_offset.passes and batch_passes must be >= 1");
  if (carry && !window) return Fail(error, "sensor_offset.carry needs sensor_offset.window");
  if (quiet && !window) return Fail(error, "sensor_offset.quiet needs sensor_offset.window");
  if (!PositiveFinite(quiet_span_s)) return Fail(error, "sensor_offset.quiet_span_s must be > 0");
  if (quiet_min_samples < 1) return Fail(error, "sensor_offset.quiet_min_samples must be >= 1");
  if (!(quiet_tensor_mean_s >= 0.0) || !std::isfinite(quiet_tensor_mean_s)) {
    return Fail(error, "sensor_offset.quiet_tensor_mean_s must be finite and >= 0");
  }
  if (quiet_rate && !quiet) return Fail(error, "sensor_offset.quiet_rate needs sensor_offset.quiet");
  if (quiet_approach && !quiet) return Fail(error, "sensor_offset.quiet_approach needs sensor_offset.quiet");
  if (!PositiveFinite(quiet_rate_span_s)) return Fail(error, "sensor_offset.quiet_rate_span_s must be > 0");
  if (window_score_test && !WindowOffsets()) {
    return Fail(error, "sensor_offset.window_score_test needs sensor_offset.window or window_lines");
  }
  if (!(window_score_persist_s >= 0.0) || !std::isfinite(window_score_persist_s)) {
    return Fail(error, "sensor_offset.window_score_persist_s must be finite and >= 0");
  }
  if (window_score_persist_s > 0.0 && !window_score_test) {
    return Fail(error, "sensor_offset.window_score_persist_s needs sensor_offset.window_score_test");
  }
  if (window_lines && carry) return Fail(error, "sensor_offset.window_lines is not with sensor_offset.carry");
  if (window_lines && quiet) return Fail(error, "sensor_offset.window_lines is not with sensor_offset.quiet");
  if (!PositiveFinite(line_rate_sigma_T_per_s)) {
    return Fail(error, "sensor_offset.line_rate_sigma_T_per_s must be > 0");
  }
  if (!(min_tensor_snr >= 0.0) || !std::isfinite(min_tensor_snr)) {
    return Fail(error, "sensor_offset.min_tensor_snr must be finite and >= 0");
  }
  if (!(tolerance_T >= 0.0) || !std::isfinite(tolerance_T)) {
    return Fail(error, "sensor_offset.tolerance_T must be finite and >= 0");
  }
  return true;
}

bool TrackerOptions::IsValid(std::string* error) const {
  if (!PositiveFinite(default_sigma_B_T)) return Fail(error, "default_sigma_B_T must be > 0");
  if (!PositiveFinite(default_sigma_T_Tpm)) return Fail(error, "default_sigma_T_Tpm must be > 0");
  if (!PositiveFinite(measurement_loss_scale_sigma))
    return Fail(error, "measurement_loss_scale_sigma must be > 0");
  if (!process.IsValid(error) || !init.IsValid(error)) return false;
  if (!sensor_offset.IsValid(error)) return false;
  if (!batch_variance_factor.IsValid(error)) return false;
  if (!PositiveFinite(batch_variance_factor_span_s)) return Fail(error, "batch_variance_factor_span_s must be > 0");
  if (!std::isfinite(epoch_tolerance_s) || epoch_tolerance_s < 0.0) {
    return Fail(error, "epoch_tolerance_s must be >= 0");
  }
  if (max_num_iterations < 1) return Fail(error, "max_num_iterations must be >= 1");
  if (window_max_num_iterations < 1) return Fail(error, "window_max_num_iterations must be >= 1");
  const auto tolerance_ok = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!tolerance_ok(function_tolerance) || !tolerance_ok(gradient_tolerance) || !tolerance_ok(parameter_tolerance)) {
    return Fail(error, "solver tolerances must be finite and >= 0");
  }
  if (!tolerance_ok(intermediate_function_tolerance)) {
    return Fail(error, "intermediate_function_tolerance must be finite and >= 0");
  }
  if (!tolerance_ok(window_function_tolerance)) return Fail(error, "window_function_tolerance must be finite and >= 0");
  if (num_threads < 1) return Fail(error, "num_threads must be >= 1");
  if (!(batch_growth_factor > 1.0) || !std::isfinite(batch_growth_factor)) {
    return Fail(error, "batch_growth_factor must be > 1");
  }
  if (batch_turn_change_points < 0 || batch_turn_change_points > kMaxBatchTurnChangePoints) {
    return Fail(error, "batch_turn_change_points must be in [0, " + std::to_string(kMaxBatchTurnChangePoints) + "]");
  }
  if (!PositiveFinite(window_turn_onset_grid_s)) return Fail(error, "window_turn_onset_grid_s must be > 0");
  if (!(window_turn_onset_bic_params >= 0.0) || !std::isfinite(window_turn_onset_bic_params)) {
    return Fail(error, "window_turn_onset_bic_params must be finite and >= 0");
  }
  if (window_turn_onset_iterations < 1) return Fail(error, "window_turn_onset_iterations must be >= 1");
  if (!(window_turn_onset_trigger_sigmas >= 0.0) || !std::isfinite(window_turn_onset_trigger_sigmas)) {
    return Fail(error, "window_turn_onset_trigger_sigmas must be finite and >= 0");
  }
  if (!PositiveFinite(window_turn_onset_coarse_grid_s)) return Fail(error, "window_turn_onset_coarse_grid_s must be > 0");
  if (!(window_turn_onset_jump_sigmas >= 0.0) || !std::isfinite(window_turn_onset_jump_sigmas)) {
    return Fail(error, "window_turn_onset_jump_sigmas must be finite and >= 0");
  }
  if (!(window_turn_onset_trigger_noise_sigmas >= 0.0) || !std::isfinite(window_turn_onset_trigger_noise_sigmas)) {
    return Fail(error, "window_turn_onset_trigger_noise_sigmas must be finite and >= 0");
  }
  if (!PositiveFinite(window_s)) return Fail(error, "window_s must be > 0");
  if (!(window_solve_interval_s >= 0.0) || !(window_solve_interval_s < window_s)) {
    return Fail(error, "window_solve_interval_s must be >= 0 and < window_s");
  }
  return true;
}

std::string Summary::BriefReport() const {
  std::ostringstream o;
  o << "tracker: " << (initialized ? "initialised" : "not initialised") << ", " << num_epochs << " epochs, "
    << num_samples << " samples, " << num_init_fixes
    << (init_from_external_fixes ? " external" : "") << " init fixes, " << iterations << " iterations, cost "
    << initial_cost << " -> " << final_cost << ", solve " << solve_time_s << " s, covariance "
    << covariance_time_s << " s (" << (covariance_ok ? "ok" : "none") << "), total " << total_time_s << " s"
    << (converged ? ", converged" : ", not converged");
  if (num_rejected_samples > 0) o << ", " << num_rejected_samples << " bad samples left out";
  if (num_dropped_factors > 0) o << ", " << num_dropped_factors << " factors left out of marginalisation";
  if (num_variance_factor_epochs > 0) {
    o << ", covariance scaled by the residuals at " << num_variance_factor_epochs << " epochs (factor up to "
      << max_variance_factor << ")";
  }
  if (offset_score_dof > 0 || offsets_solved) {
    o << ", sensor offsets " << (offsets_solved ? "solved" : "not solved");
    if (offset_score_dof > 0) {
      o << " (B residual means chi2 " << offset_score_chi2 << " on " << offset_score_dof << " dof)";
    }
  }
  o << "; " << message;
  return o.str();
}

}  // namespace magnav::tracker
