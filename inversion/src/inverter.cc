#include "magnav/inversion/inverter.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "magnav/core/dipole.h"
#include "magnav/core/error.h"
#include "magnav/core/option_check.h"

namespace magnav::inversion {

const char* MethodName(Method method) {
  switch (method) {
    case Method::kTed:
      return "ted";
    case Method::kTedEgt:
      return "ted-egt";
    case Method::kEgt:
      return "egt";
  }
  return "?";
}

bool ParseMethod(const std::string& name, Method* method) {
  for (const Method m : {Method::kTed, Method::kTedEgt, Method::kEgt}) {
    if (name == MethodName(m)) {
      *method = m;
      return true;
    }
  }
  return false;
}

const char* RejectReasonName(RejectReason reason) {
  switch (reason) {
    case RejectReason::kNone:
      return "";
    case RejectReason::kNonFinite:
      return "non_finite";
    case RejectReason::kZeroTensor:
      return "zero_tensor";
    case RejectReason::kWeakSignal:
      return "weak_signal";
    case RejectReason::kAsymmetric:
      return "asymmetric";
    case RejectReason::kNotTraceFree:
      return "not_trace_free";
    case RejectReason::kIllConditioned:
      return "ill_conditioned";
    case RejectReason::kUncertain:
      return "uncertain";
    case RejectReason::kInfeasibleSpeed:
      return "infeasible_speed";
    case RejectReason::kSolverFailed:
      return "solver_failed";
    case RejectReason::kNotInitialized:
      return "not_initialized";
    case RejectReason::kUnknownSigma:
      return "unknown_sigma";
    case RejectReason::kNoRegionalField:
      return "no_b0";
    case RejectReason::kOutOfRange:
      return "out_of_range";
  }
  return "unknown";
}

namespace {

bool PositiveOrInf(double v) { return v > 0.0; }  // false for NaN
// A limit that 0 or ∞ switches off.
bool LimitOrOff(double v) { return v >= 0.0; }  // false for NaN
bool LimitOn(double v) { return v > 0.0 && std::isfinite(v); }

}  // namespace

bool GateOptions::IsValid(std::string* error) const {
  if (!(min_snr >= 0.0) || !std::isfinite(min_snr)) return Fail(error, "gates.min_snr must be finite and >= 0");
  if (!(max_relative_defect > 0.0)) return Fail(error, "gates.max_relative_defect must be > 0");
  if (!(noise_k >= 0.0) || !std::isfinite(noise_k)) return Fail(error, "gates.noise_k must be finite and >= 0");
  if (!(max_cond_ted >= 1.0)) return Fail(error, "gates.max_cond_ted must be >= 1");
  if (!(max_cond_ted_egt >= 1.0)) return Fail(error, "gates.max_cond_ted_egt must be >= 1");
  if (!(max_cond_egt >= 1.0)) return Fail(error, "gates.max_cond_egt must be >= 1");
  if (!LimitOrOff(max_relative_sigma)) return Fail(error, "gates.max_relative_sigma must be >= 0 (0 = off)");
  if (!LimitOrOff(max_position_sigma_3d_m)) {
    return Fail(error, "gates.max_position_sigma_3d_m must be >= 0 (0 = off)");
  }
  if (!PositiveOrInf(max_speed_mps)) return Fail(error, "gates.max_speed_mps must be > 0");
  if (!(speed_slack_m >= 0.0) || !std::isfinite(speed_slack_m)) {
    return Fail(error, "gates.speed_slack_m must be finite and >= 0");
  }
  if (!PositiveOrInf(reference_timeout_s)) return Fail(error, "gates.reference_timeout_s must be > 0");
  return true;
}

bool InverterOptions::IsValid(std::string* error) const {
  if (!B0_W.allFinite()) return Fail(error, "B0_W must be finite");
  if (!(egt_row_weight >= 0.0) || !std::isfinite(egt_row_weight)) {
    return Fail(error, "egt_row_weight must be finite and >= 0");
  }
  if (!(sigma_B_fallback >= 0.0) || !std::isfinite(sigma_B_fallback)) {
    return Fail(error, "sigma_B_fallback must be finite and >= 0");
  }
  if (!(sigma_T_fallback >= 0.0) || !std::isfinite(sigma_T_fallback)) {
    return Fail(error, "sigma_T_fallback must be finite and >= 0");
  }
  return gates.IsValid(error);
}

DipoleFix InvertSample(const GradiometerSample& sample, const InverterOptions& options) {
  DipoleFix fix;
  fix.sensor_id = sample.sensor_id;
  fix.t_s = sample.t_s;
  const GateOptions& g = options.gates;
  auto reject = [&fix](RejectReason r) {
    fix.valid = false;
    fix.reason = r;
    return fix;
  };

  // 1–2. The door check every consumer applies (core CheckSample).
  switch (CheckSample(sample)) {
    case SampleDefect::kNone:
      break;
    case SampleDefect::kZeroTensor:  // dead sensor, or no signal at all
      return reject(RejectReason::kZeroTensor);
    case SampleDefect::kOutOfRange:  // 1e308, or nT given as T
      return reject(RejectReason::kOutOfRange);
    default:  // non-finite time, B, T, position, or σ
      return reject(RejectReason::kNonFinite);
  }
  if (!options.B0_W.allFinite()) return reject(RejectReason::kNonFinite);
  const double sigma_B = sample.sigma_B > 0.0 ? sample.sigma_B : options.sigma_B_fallback;
  const double sigma_T = sample.sigma_T > 0.0 ? sample.sigma_T : options.sigma_T_fallback;
  const double t_norm = sample.T.norm();
  // 3. Weak signal.
  if (sigma_T > 0.0) {
    fix.snr = t_norm / sigma_T;
    if (fix.snr < g.min_snr) return reject(RejectReason::kWeakSignal);
  }
  // 4. Symmetric and trace-free within tolerance.
  const double defect_limit = std::max(g.max_relative_defect * t_norm, g.noise_k * sigma_T);
  if ((sample.T - sample.T.transpose()).norm() > defect_limit) return reject(RejectReason::kAsymmetric);
  if (std::abs(sample.T.trace()) > defect_limit) return reject(RejectReason::kNotTraceFree);

  // Solve.
  const Vec3 dB = sample.B - options.B0_W;
  const NoiseSigmas noise{sigma_B, sigma_T};
  AnalyticSolution sol;
  sol.cond = std::numeric_limits<double>::quiet_NaN();
  bool ok = false;
  double max_cond = 0.0;
  switch (options.method) {
    case Method::kTed:
      ok = SolveTed(sample.T, dB, noise, &sol);
      max_cond = g.max_cond_ted;
      break;
    case Method::kTedEgt:
      ok = SolveTedEgt(sample.T, dB, options.egt_row_weight, noise, &sol);
      max_cond = g.max_cond_ted_egt;
      break;
    case Method::kEgt:
      ok = SolveEgt(sample.T, dB, noise, &sol);
      max_cond = g.max_cond_egt;
      break;
  }
  fix.cond = sol.cond;
  if (!ok) {
    // A singular system (cond = ∞) is the condition gate's business.
    return reject(sol.cond > max_cond ? RejectReason::kIllConditioned : RejectReason::kSolverFailed);
  }
  fix.r_DtoS = sol.r_DtoS;
  fix.p_DinW = sample.p_SinW - sol.r_DtoS;
  fix.cov_p_DinW = sol.cov_r;  // p_D = p_S − r: same covariance
  fix.position_sigma_3d_m = sol.position_sigma_3d_m;
  // 5. Condition number.
  if (!(sol.cond <= max_cond)) return reject(RejectReason::kIllConditioned);
  // 6. Predicted position error, relative to the range and absolute (a NaN
  // σ — no noise known — passes both).
  if (LimitOn(g.max_relative_sigma) && sol.position_sigma_3d_m > g.max_relative_sigma * sol.r_DtoS.norm()) {
    return reject(RejectReason::kUncertain);
  }
  if (LimitOn(g.max_position_sigma_3d_m) && sol.position_sigma_3d_m > g.max_position_sigma_3d_m) {
    return reject(RejectReason::kUncertain);
  }
  // Moment of an accepted fix: closed form (EGT) or weighted least squares.
  if (sol.has_moment) {
    fix.m_W = sol.m_W;
    fix.has_moment = true;
  } else if (options.estimate_moment) {
    Vec3 m;
    if (FitDipoleMoment(sol.r_DtoS, dB, sample.T, sigma_B, sigma_T, &m)) {
      fix.m_W = m;
      fix.has_moment = true;
    }
  }
  fix.valid = true;
  fix.reason = RejectReason::kNone;
  return fix;
}

Inverter::Inverter(const InverterOptions& options) : options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw InputError("inverter options: " + error);
}

DipoleFix Inverter::Process(const GradiometerSample& sample) {
  DipoleFix fix = InvertSample(sample, options_);
  if (!fix.valid) return fix;
  const GateOptions& g = options_.gates;
  if (g.enable_speed_gate) {
    const auto it = last_accepted_.find(sample.sensor_id);
    if (it != last_accepted_.end()) {
      const double dt = sample.t_s - it->second.t_s;
      if (dt > 0.0 && dt <= g.reference_timeout_s) {
        const double step = (fix.p_DinW - it->second.p_DinW).norm();
        if (step > g.max_speed_mps * dt + g.speed_slack_m) {
          fix.valid = false;
          fix.reason = RejectReason::kInfeasibleSpeed;
          return fix;
        }
      }
    }
  }
  // Keep the newest accepted fix as the reference (an out-of-order sample
  // does not replace a later one).
  auto [it, inserted] = last_accepted_.try_emplace(sample.sensor_id, Reference{fix.p_DinW, sample.t_s});
  if (!inserted && sample.t_s >= it->second.t_s) it->second = Reference{fix.p_DinW, sample.t_s};
  return fix;
}

void Inverter::Reset(std::uint32_t sensor_id) { last_accepted_.erase(sensor_id); }
void Inverter::ResetAll() { last_accepted_.clear(); }

}  // namespace magnav::inversion
