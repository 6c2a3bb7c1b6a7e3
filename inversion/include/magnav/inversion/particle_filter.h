// Monte-Carlo inversion (paper §3.3): a particle filter that tracks a dipole
// of KNOWN body moment from gradient-tensor samples alone (no B, so no
// regional field B0 is needed).
//
// Frames and units: world NED, metres, seconds, T/m, A·m².
// State per particle: x = [p_x, p_y, p_z, v_x, v_y] — dipole position p_DinW
// (m) and horizontal velocity (m/s); constant velocity, constant depth.
// Process model over Δt (continuous white noise, so independent of the
// sample rate): v += δv, p_xy += (v + δv/2) Δt + w_xy, p_z += w_z with
// δv ~ N(0, velocity_walk² Δt) (white acceleration of PSD velocity_walk²),
// w_xy ~ N(0, position_walk² Δt) and w_z ~ N(0, depth_walk² Δt).
// Measurement: the five independent tensor components z = [Txx, Txy, Txz,
// Tyy, Tyz] (core PackTensor5) of the dipole with world moment
// m_W = Rz(ψ) m_B, ψ = atan2(v_y, v_x) (core WorldMoment), at r = p_S − p_D.
// Likelihood: Gaussian with the noise structure of a symmetric trace-free
// tensor — off-diagonals independent σ², diagonals Txx, Tyy with variance σ²
// and correlation −1/2 — where σ² = σ_T² + (model_error_relative ‖T‖_F)².
// Systematic resampling when the effective sample size drops below
// resample_ess_fraction · N. The estimate is the weighted mean.
// Cost: no allocation after construction; process-noise normals come from a
// 4096-entry table of normal quantiles (|x| ≤ 3.67σ) indexed by random bits.
#pragma once

#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "magnav/core/gradiometer.h"
#include "magnav/inversion/inverter.h"

namespace magnav::inversion {

struct ParticleFilterOptions {
  int num_particles = 600;
  std::uint64_t seed = 42;  // std::mt19937_64 seed: runs are reproducible
  Vec3 moment_body_Am2 = Vec3::Zero();  // known body moment (body x fwd, y stbd, z down); must be set
  double sigma_T_fallback = 0.0;        // T/m, used when a sample's sigma_T is 0
  // Relative model error added to σ_T in the likelihood: a real vessel is
  // not a perfect dipole, and a likelihood sharper than the particle spacing
  // (SQUID, close range) collapses the cloud onto a few particles that then
  // cannot follow. 1 % caps the effective SNR at 100 (sweep in
  // docs/ACCURACY.md).
  double model_error_relative = 0.01;
  // Velocity random walk (white horizontal acceleration), m/s per √s. The
  // passes turn at 0.02 rad/s × 1 m/s = 0.02 m/s²; 0.1 also lets a cloud
  // with a wrong initial heading turn to the right one within a few seconds
  // (sweep in docs/ACCURACY.md).
  double velocity_walk_mps_per_sqrt_s = 0.1;
  // Horizontal position random walk on top of the constant-velocity motion;
  // keeps the cloud wide enough to follow when the likelihood is sharp.
  double position_walk_m_per_sqrt_s = 0.1;
  double depth_walk_m_per_sqrt_s = 0.02;      // depth random walk
  double resample_ess_fraction = 0.5;         // resample when ESS < fraction · N
  // Prior around a position (InitializeAround): isotropic Gaussian position,
  // speed uniform in [0, init_speed_max_mps], heading uniform.
  double init_speed_max_mps = 3.0;

  bool IsValid(std::string* error) const;
};

struct ParticleEstimate {
  double t_s = 0.0;
  Vec3 p_DinW = Vec3::Zero();              // weighted mean position, m
  Eigen::Vector2d v_W = Eigen::Vector2d::Zero();  // weighted mean horizontal velocity, m/s
  Vec3 position_std_m = Vec3::Zero();      // weighted std per axis, m
  Mat3 cov_p_W = Mat3::Zero();             // weighted covariance of the position, m²
  double ess = 0.0;                        // effective sample size after the update
};

class DipoleParticleFilter {
 public:
  // Throws InputError if the options are invalid.
  explicit DipoleParticleFilter(const ParticleFilterOptions& options);

  // Prior: Gaussian around p_DinW (σ per axis, m) at time t_s, velocity
  // uniform (speed in [0, init_speed_max_mps], any heading).
  void InitializeAround(const Vec3& p_DinW, double position_sigma_m, double t_s);
  // Prior: Gaussian around p_DinW and around a horizontal velocity v_W (m/s).
  void InitializeAround(const Vec3& p_DinW, double position_sigma_m, const Eigen::Vector2d& v_W,
                        double velocity_sigma_mps, double t_s);
  // Prior: uniform position in the box [lo, hi] (m) at time t_s.
  void InitializeBox(const Vec3& lo_W, const Vec3& hi_W, double t_s);
  bool initialized() const { return initialized_; }

  // Propagates to sample.t_s and weighs by the sample's tensor. Returns false
  // (state unchanged apart from the prediction) if the sample is unusable
  // (non-finite tensor or position, unknown σ_T, or t_s before the filter time).
  bool Step(const GradiometerSample& sample);
  // Prediction only (e.g. for a rejected sample); dt ≥ 0.
  void Predict(double t_s);

  ParticleEstimate Estimate() const;
  double time() const { return t_s_; }
  const ParticleFilterOptions& options() const { return options_; }

 private:
  // Draws every particle's position with draw_position, a random velocity
  // (speed ≤ init_speed_max_mps, any heading) and equal weights.
  void InitializeWith(const std::function<Vec3()>& draw_position, double t_s);
  void Resample();
  ParticleEstimate ComputeEstimate() const;
  double Normal();   // standard normal (tabulated quantiles, see .cc)
  double Uniform();  // [0, 1)

  ParticleFilterOptions options_;
  std::mt19937_64 rng_;
  std::uint64_t normal_bits_ = 0;
  int normal_bits_left_ = 0;
  bool initialized_ = false;
  double t_s_ = 0.0;
  double ess_ = 0.0;
  ParticleEstimate estimate_;  // from the last update, before resampling
  bool estimate_valid_ = false;
  // Structure of arrays; scratch buffers are swapped in by Resample.
  std::vector<double> px_, py_, pz_, vx_, vy_, w_, logl_;
  std::vector<double> px2_, py2_, pz2_, vx2_, vy2_;
};

// Per-sensor Monte-Carlo tracking for a service or the CLI: one particle
// filter per sensor_id. The prior comes from the analytic fixes (TED+EGT with
// the inverter's gates; they need B0, the filter itself does not): once the
// accepted fixes of the last init_window_s seconds number at least
// init_min_fixes and span at least half the window, the filter starts around
// the newest fix with the velocity of a least-squares line through them. It
// restarts the same way when an accepted fix lies more than
// reinit_distance_m from the filter estimate (lost track).
struct MonteCarloTrackerOptions {
  ParticleFilterOptions filter;
  // Method and gates for the initialising fixes. The prior σ follows each
  // fix's predicted σ, so these take an absolute 1 m σ gate of their own
  // and the weak-signal floor SNR 100 (tuned with the MC noise settings on
  // the reference passes; the inverter's defaults are 0.4 m and 20).
  InverterOptions init_inverter = [] {
    InverterOptions o;
    o.gates.min_snr = 100.0;
    o.gates.max_relative_sigma = 0.0;
    o.gates.max_position_sigma_3d_m = 1.0;
    return o;
  }();
  double init_window_s = 1.0;               // s
  int init_min_fixes = 5;
  double init_position_sigma_m = 0.5;       // prior σ around the newest fix, m
  double init_velocity_sigma_mps = 0.3;     // prior σ around the fitted velocity, m/s
  double reinit_distance_m = 3.0;           // infinity disables re-initialisation

  bool IsValid(std::string* error) const;
};

class MonteCarloTracker {
 public:
  explicit MonteCarloTracker(const MonteCarloTrackerOptions& options);
  // Samples of one sensor must come in time order. The returned fix is valid
  // only when the sample updated the sensor's filter: not before the filter
  // is initialised (kNotInitialized), not for a sample that fails core's
  // CheckSample (kNonFinite, kZeroTensor: the filter does not see it), not
  // when σ_T is unknown (kUnknownSigma) nor when the filter refused the
  // sample (out of time order, no particle explains it: kSolverFailed); those
  // carry the filter's prediction for diagnostics. A valid fix carries the
  // filter's mean position, cov_p_DinW = the particles' weighted covariance
  // (position_sigma_3d_m its trace's root), the world moment at the mean
  // velocity's heading and the sample's cond(T).
  DipoleFix Process(const GradiometerSample& sample);

 private:
  struct Track {
    DipoleParticleFilter filter;
    Inverter inverter;
    std::vector<DipoleFix> recent;  // accepted analytic fixes within init_window_s
  };
  // Starts the filter from the recent fixes; false if there are too few.
  bool TryInitialize(Track* track, double t_s) const;
  MonteCarloTrackerOptions options_;
  std::unordered_map<std::uint32_t, Track> tracks_;
};

}  // namespace magnav::inversion
