#include "magnav/inversion/particle_filter.h"


#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>

#include "magnav/core/dipole.h"
#include "magnav/core/error.h"
#include "magnav/core/option_check.h"
#include "magnav/inversion/fix_line.h"
#include "magnav/core/frames.h"
#include "magnav/core/tensor.h"

namespace magnav::inversion {
namespace {

bool FiniteNonNegative(double v) { return v >= 0.0 && std::isfinite(v); }

// Inverse standard normal CDF: Acklam's rational approximation (relative
// error < 1.2e-9) refined by one Halley step on erfc.
double NormalQuantile(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                                 1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                                 6.680131188771972e+01,  -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                                 -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                                 3.754408661907416e+00};
  double x;
  if (p < 0.02425) {
    const double q = std::sqrt(-2.0 * std::log(p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  } else if (p > 1.0 - 0.02425) {
    const double q = std::sqrt(-2.0 * std::log(1.0 - p));
    x = -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  } else {
    const double q = p - 0.5, r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
  }
  const double e = 0.5 * std::erfc(-x / std::numbers::sqrt2) - p;
  const double u = e * std::sqrt(2.0 * std::numbers::pi) * std::exp(0.5 * x * x);
  return x - u / (1.0 + 0.5 * x * u);
}

// Process noise needs thousands of normal draws per update; a table of
// 4096 equiprobable quantiles (midpoints, |x| ≤ 3.67) indexed by 12 random
// bits is a discretised normal that costs one table load per draw and fits
// in L1 cache. Its variance is 0.99968 (the tails beyond 3.67σ are cut).
constexpr int kNormalTableBits = 12;
constexpr int kNormalTableSize = 1 << kNormalTableBits;
const std::array<double, kNormalTableSize>& NormalTable() {
  static const std::array<double, kNormalTableSize> table = [] {
    std::array<double, kNormalTableSize> t{};
    for (int i = 0; i < kNormalTableSize; ++i) t[i] = NormalQuantile((i + 0.5) / kNormalTableSize);
    return t;
  }();
  return table;
}

}  // namespace

bool ParticleFilterOptions::IsValid(std::string* error) const {
  if (num_particles < 2) return Fail(error, "filter.num_particles must be >= 2");
  if (!moment_body_Am2.allFinite() || moment_body_Am2.squaredNorm() == 0.0) {
    return Fail(error, "filter.moment_body_Am2 must be finite and non-zero");
  }
  if (!FiniteNonNegative(sigma_T_fallback)) return Fail(error, "filter.sigma_T_fallback must be finite and >= 0");
  if (!FiniteNonNegative(model_error_relative)) {
    return Fail(error, "filter.model_error_relative must be finite and >= 0");
  }
  if (!FiniteNonNegative(velocity_walk_mps_per_sqrt_s)) {
    return Fail(error, "filter.velocity_walk_mps_per_sqrt_s must be finite and >= 0");
  }
  if (!FiniteNonNegative(position_walk_m_per_sqrt_s)) {
    return Fail(error, "filter.position_walk_m_per_sqrt_s must be finite and >= 0");
  }
  if (!FiniteNonNegative(depth_walk_m_per_sqrt_s)) {
    return Fail(error, "filter.depth_walk_m_per_sqrt_s must be finite and >= 0");
  }
  if (!(resample_ess_fraction > 0.0 && resample_ess_fraction <= 1.0)) {
    return Fail(error, "filter.resample_ess_fraction must be in (0, 1]");
  }
  if (!FiniteNonNegative(init_speed_max_mps)) {
    return Fail(error, "filter.init_speed_max_mps must be finite and >= 0");
  }
  return true;
}

DipoleParticleFilter::DipoleParticleFilter(const ParticleFilterOptions& options)
    : options_(options), rng_(options.seed) {
  std::string error;
  if (!options_.IsValid(&error)) throw InputError("particle filter options: " + error);
  const std::size_t n = static_cast<std::size_t>(options_.num_particles);
  for (auto* v : {&px_, &py_, &pz_, &vx_, &vy_, &w_, &logl_, &px2_, &py2_, &pz2_, &vx2_, &vy2_}) {
    v->assign(n, 0.0);
  }
  NormalTable();  // build once, outside any update
}

double DipoleParticleFilter::Uniform() {
  return static_cast<double>(rng_() >> 11) * 0x1.0p-53;
}

double DipoleParticleFilter::Normal() {
  if (normal_bits_left_ < kNormalTableBits) {
    normal_bits_ = rng_();
    normal_bits_left_ = 64;
  }
  const double x = NormalTable()[normal_bits_ & (kNormalTableSize - 1)];
  normal_bits_ >>= kNormalTableBits;
  normal_bits_left_ -= kNormalTableBits;
  return x;
}

void DipoleParticleFilter::InitializeWith(const std::function<Vec3()>& draw_position, double t_s) {
  const std::size_t n = px_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 p = draw_position();
    px_[i] = p.x();
    py_[i] = p.y();
    pz_[i] = p.z();
    const double speed = options_.init_speed_max_mps * Uniform();
    const double heading = 2.0 * std::numbers::pi * Uniform();
    vx_[i] = speed * std::cos(heading);
    vy_[i] = speed * std::sin(heading);
    w_[i] = 1.0 / static_cast<double>(n);
  }
  t_s_ = t_s;
  ess_ = static_cast<double>(n);
  estimate_valid_ = false;
  initialized_ = true;
}

void DipoleParticleFilter::InitializeAround(const Vec3& p_DinW, double position_sigma_m, double t_s) {
  InitializeWith(
      [&] {
        // Draw order x, y, z (the stream of a seed stays the same).
        const double x = p_DinW.x() + position_sigma_m * Normal();
        const double y = p_DinW.y() + position_sigma_m * Normal();
        const double z = p_DinW.z() + position_sigma_m * Normal();
        return Vec3(x, y, z);
      },
      t_s);
}

void DipoleParticleFilter::InitializeAround(const Vec3& p_DinW, double position_sigma_m,
                                            const Eigen::Vector2d& v_W, double velocity_sigma_mps,
                                            double t_s) {
  InitializeAround(p_DinW, position_sigma_m, t_s);
  for (std::size_t i = 0; i < px_.size(); ++i) {
    vx_[i] = v_W.x() + velocity_sigma_mps * Normal();
    vy_[i] = v_W.y() + velocity_sigma_mps * Normal();
  }
}

void DipoleParticleFilter::InitializeBox(const Vec3& lo_W, const Vec3& hi_W, double t_s) {
  InitializeWith(
      [&] {
        const double x = lo_W.x() + (hi_W.x() - lo_W.x()) * Uniform();
        const double y = lo_W.y() + (hi_W.y() - lo_W.y()) * Uniform();
        const double z = lo_W.z() + (hi_W.z() - lo_W.z()) * Uniform();
        return Vec3(x, y, z);
      },
      t_s);
}

void DipoleParticleFilter::Predict(double t_s) {
  const double dt = t_s - t_s_;
  if (!(dt > 0.0)) return;
  const double sa = options_.velocity_walk_mps_per_sqrt_s * std::sqrt(dt);
  const double sz = options_.depth_walk_m_per_sqrt_s * std::sqrt(dt);
  const double sp = options_.position_walk_m_per_sqrt_s * std::sqrt(dt);
  const std::size_t n = px_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const double dvx = sa * Normal(), dvy = sa * Normal();
    // Position integrates the mean velocity over the step.
    px_[i] += (vx_[i] + 0.5 * dvx) * dt + sp * Normal();
    py_[i] += (vy_[i] + 0.5 * dvy) * dt + sp * Normal();
    vx_[i] += dvx;
    vy_[i] += dvy;
    pz_[i] += sz * Normal();
  }
  t_s_ = t_s;
}

bool DipoleParticleFilter::Step(const GradiometerSample& sample) {
  if (!initialized_ || !std::isfinite(sample.t_s) || sample.t_s < t_s_) return false;
  Predict(sample.t_s);
  const double sigma_T = sample.sigma_T > 0.0 ? sample.sigma_T : options_.sigma_T_fallback;
  if (!sample.T.allFinite() || !sample.p_SinW.allFinite() || !(sigma_T > 0.0)) return false;

  const Tensor5 z = PackTensor5(sample.T);
  const double model = options_.model_error_relative * sample.T.norm();
  const double inv_var = 1.0 / (sigma_T * sigma_T + model * model);
  const Vec3& mB = options_.moment_body_Am2;
  const Vec3& pS = sample.p_SinW;
  const std::size_t n = px_.size();
  double max_ll = -std::numeric_limits<double>::infinity();
  Mat3 T;
  for (std::size_t i = 0; i < n; ++i) {
    // m_W = Rz(ψ) m_B with ψ = atan2(v_y, v_x): cos ψ, sin ψ straight from v
    // (identical to WorldMoment(m_B, atan2(v_y, v_x)); ψ = 0 when v = 0).
    const double speed = std::hypot(vx_[i], vy_[i]);
    const double c = speed > 0.0 ? vx_[i] / speed : 1.0;
    const double s = speed > 0.0 ? vy_[i] / speed : 0.0;
    const Vec3 m_W(c * mB.x() - s * mB.y(), s * mB.x() + c * mB.y(), mB.z());
    const Vec3 r(pS.x() - px_[i], pS.y() - py_[i], pS.z() - pz_[i]);
    DipoleBT(r, m_W, nullptr, &T);
    const double dxx = z[0] - T(0, 0), dxy = z[1] - T(0, 1), dxz = z[2] - T(0, 2);
    const double dyy = z[3] - T(1, 1), dyz = z[4] - T(1, 2);
    const double q = dxy * dxy + dxz * dxz + dyz * dyz + (4.0 / 3.0) * (dxx * dxx + dxx * dyy + dyy * dyy);
    const double ll = -0.5 * q * inv_var;
    logl_[i] = std::isfinite(ll) ? ll : -std::numeric_limits<double>::infinity();
    max_ll = std::max(max_ll, logl_[i]);
  }
  if (!std::isfinite(max_ll)) return false;  // no particle explains the sample (e.g. r = 0)
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    w_[i] *= std::exp(logl_[i] - max_ll);
    sum += w_[i];
  }
  if (!(sum > 0.0) || !std::isfinite(sum)) {
    // Prior weights underflowed where the likelihood lives: restart from the
    // likelihood alone.
    sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      w_[i] = std::exp(logl_[i] - max_ll);
      sum += w_[i];
    }
  }
  double sum_sq = 0.0;
  const double inv_sum = 1.0 / sum;
  for (std::size_t i = 0; i < n; ++i) {
    w_[i] *= inv_sum;
    sum_sq += w_[i] * w_[i];
  }
  ess_ = 1.0 / sum_sq;
  estimate_ = ComputeEstimate();
  estimate_valid_ = true;
  if (ess_ < options_.resample_ess_fraction * static_cast<double>(n)) Resample();
  return true;
}

void DipoleParticleFilter::Resample() {
  // Systematic resampling: one uniform offset, N evenly spaced pointers.
  const std::size_t n = px_.size();
  const double step = 1.0 / static_cast<double>(n);
  double u = Uniform() * step;
  double cumulative = w_[0];
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    while (u > cumulative && j + 1 < n) cumulative += w_[++j];
    px2_[i] = px_[j];
    py2_[i] = py_[j];
    pz2_[i] = pz_[j];
    vx2_[i] = vx_[j];
    vy2_[i] = vy_[j];
    u += step;
  }
  px_.swap(px2_);
  py_.swap(py2_);
  pz_.swap(pz2_);
  vx_.swap(vx2_);
  vy_.swap(vy2_);
  std::fill(w_.begin(), w_.end(), step);
}

ParticleEstimate DipoleParticleFilter::ComputeEstimate() const {
  ParticleEstimate e;
  e.t_s = t_s_;
  e.ess = ess_;
  Vec3 mean = Vec3::Zero();
  Eigen::Vector2d v = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < px_.size(); ++i) {
    mean += w_[i] * Vec3(px_[i], py_[i], pz_[i]);
    v += w_[i] * Eigen::Vector2d(vx_[i], vy_[i]);
  }
  Mat3 cov = Mat3::Zero();  // about the mean (no cancellation of large squares)
  for (std::size_t i = 0; i < px_.size(); ++i) {
    const Vec3 d(px_[i] - mean.x(), py_[i] - mean.y(), pz_[i] - mean.z());
    cov.noalias() += w_[i] * d * d.transpose();
  }
  e.p_DinW = mean;
  e.v_W = v;
  e.cov_p_W = cov;
  e.position_std_m = cov.diagonal().cwiseMax(0.0).cwiseSqrt();
  return e;
}

ParticleEstimate DipoleParticleFilter::Estimate() const {
  // After an update the estimate is taken before resampling (less noisy);
  // after a prediction only, from the current cloud.
  if (estimate_.t_s == t_s_ && estimate_valid_) return estimate_;
  return ComputeEstimate();
}

bool MonteCarloTrackerOptions::IsValid(std::string* error) const {
  if (!filter.IsValid(error)) return false;
  if (!init_inverter.IsValid(error)) return false;
  if (!(init_window_s > 0.0) || !std::isfinite(init_window_s)) {
    return Fail(error, "init_window_s must be finite and > 0");
  }
  if (init_min_fixes < 2) return Fail(error, "init_min_fixes must be >= 2");
  if (!FiniteNonNegative(init_velocity_sigma_mps)) {
    return Fail(error, "init_velocity_sigma_mps must be finite and >= 0");
  }
  if (!(init_position_sigma_m > 0.0) || !std::isfinite(init_position_sigma_m)) {
    return Fail(error, "init_position_sigma_m must be finite and > 0");
  }
  if (!(reinit_distance_m > 0.0)) return Fail(error, "reinit_distance_m must be > 0");
  return true;
}

MonteCarloTracker::MonteCarloTracker(const MonteCarloTrackerOptions& options) : options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw InputError("Monte-Carlo tracker options: " + error);
}

bool MonteCarloTracker::TryInitialize(Track* track, double t_s) const {
  const auto& f = track->recent;
  if (static_cast<int>(f.size()) < options_.init_min_fixes) return false;
  if (f.back().t_s - f.front().t_s < 0.5 * options_.init_window_s) return false;
  const FixLine line = FitFixLine(f);
  if (!line.has_velocity) return false;
  const Vec3& v = line.v;
  const Vec3 p_now = line.At(t_s);
  // Prior σ per axis: the option, or the newest fix's 3-D RMS σ if larger
  // (deliberately wide: √3 × its per-axis σ for an isotropic error).
  const double sigma_fix = f.back().position_sigma_3d_m;
  const double sigma_p =
      std::isfinite(sigma_fix) ? std::max(options_.init_position_sigma_m, sigma_fix) : options_.init_position_sigma_m;
  track->filter.InitializeAround(p_now, sigma_p, v.head<2>(),
                                 options_.init_velocity_sigma_mps, t_s);
  return true;
}

DipoleFix MonteCarloTracker::Process(const GradiometerSample& sample) {
  DipoleFix fix;
  fix.sensor_id = sample.sensor_id;
  fix.t_s = sample.t_s;
  // The door: a bad sample reaches neither the initialiser nor the filter.
  if (const SampleDefect defect = CheckSample(sample); defect != SampleDefect::kNone) {
    fix.reason = defect == SampleDefect::kZeroTensor   ? RejectReason::kZeroTensor
                 : defect == SampleDefect::kOutOfRange ? RejectReason::kOutOfRange
                                                       : RejectReason::kNonFinite;
    return fix;
  }
  auto it = tracks_.find(sample.sensor_id);
  if (it == tracks_.end()) {
    ParticleFilterOptions filter_options = options_.filter;
    filter_options.seed += sample.sensor_id;  // independent streams per sensor
    it = tracks_
             .emplace(sample.sensor_id,
                      Track{DipoleParticleFilter(filter_options), Inverter(options_.init_inverter), {}})
             .first;
  }
  Track& track = it->second;
  fix.cond = SortedEigenDecomposition(sample.T).ConditionNumber();
  const DipoleFix analytic = track.inverter.Process(sample);
  fix.snr = analytic.snr;
  DipoleParticleFilter& pf = track.filter;
  if (analytic.valid) {
    track.recent.push_back(analytic);
    const double t_min = sample.t_s - options_.init_window_s;
    track.recent.erase(std::remove_if(track.recent.begin(), track.recent.end(),
                                      [t_min](const DipoleFix& f) { return f.t_s < t_min; }),
                       track.recent.end());
    const bool lost = pf.initialized() &&
                      (analytic.p_DinW - pf.Estimate().p_DinW).norm() > options_.reinit_distance_m;
    if (!pf.initialized() || lost) TryInitialize(&track, sample.t_s);
  }
  if (!pf.initialized()) {
    fix.reason = RejectReason::kNotInitialized;
    return fix;
  }
  const bool sigma_known = sample.sigma_T > 0.0 || options_.filter.sigma_T_fallback > 0.0;
  const bool updated = sigma_known && pf.Step(sample);
  if (!updated) pf.Predict(sample.t_s);
  const ParticleEstimate e = pf.Estimate();
  fix.p_DinW = e.p_DinW;
  fix.r_DtoS = sample.p_SinW - e.p_DinW;
  fix.cov_p_DinW = e.cov_p_W;
  fix.position_sigma_3d_m = std::sqrt(e.cov_p_W.trace());
  if (!updated) {
    fix.reason = sigma_known ? RejectReason::kSolverFailed : RejectReason::kUnknownSigma;
    return fix;
  }
  fix.valid = true;
  fix.m_W = WorldMoment(options_.filter.moment_body_Am2, std::atan2(e.v_W.y(), e.v_W.x()));
  fix.has_moment = true;
  return fix;
}

}  // namespace magnav::inversion
