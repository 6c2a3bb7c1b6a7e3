// Monte-Carlo inversion (paper §3.3): a particle filter that tracks a dipole
// of KNOWN body moment from gradient-tensor samples alone (no B, so no
// regional field B0 is needed).
//
// Frames and units: world NED, metres, seconds, T/m, A·m².
// State per particle: x = [p_x, p_y, p_z, v_x, v_y] — dipole position p_DinW
// (m) and horizontal velocity (m/s); constant velocity, constant depth.
// Process model over Δt: v += a Δt, p_xy += v Δt, p_z += w_z, with white
// horizontal acceleration a ~ N(0, accel_sigma_mps2²) and a depth random walk
// w_z ~ N(0, depth_sigma_m_per_sqrt_s² Δt).
// Measurement: the five independent tensor components z = [Txx, Txy, Txz,
// Tyy, Tyz] (core PackTensor5) of the dipole with world moment
// m_W = Rz(ψ) m_B, ψ = atan2(v_y, v_x) (core WorldMoment), at r = p_S − p_D.
// Likelihood: Gaussian with the noise structure of a symmetric trace-free
// tensor — off-diagonals independent σ², diagonals Txx, Tyy with variance σ²
// and correlation −1/2 — where σ² = σ_T² + (model_error_relative ‖T‖_F)².
// Systematic resampling when the effective sample size drops below
// resample_ess_fraction · N. The estimate is the weighted mean.
#pragma once

#include <cstdint>
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
  // Relative model error added to σ_T in the likelihood (keeps a very sharp
  // SQUID likelihood from collapsing the particle cloud onto one particle).
  double model_error_relative = 0.0;
  double accel_sigma_mps2 = 0.05;             // horizontal acceleration noise
  double depth_sigma_m_per_sqrt_s = 0.02;     // depth random walk
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
  double ess = 0.0;                        // effective sample size after the update
};

class DipoleParticleFilter {
 public:
  // Throws InputError if the options are invalid.
  explicit DipoleParticleFilter(const ParticleFilterOptions& options);

  // Prior: Gaussian around p_DinW (σ per axis, m) at time t_s.
  void InitializeAround(const Vec3& p_DinW, double position_sigma_m, double t_s);
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
// filter per sensor_id, initialised around the first TED+EGT fix that passes
// the inverter's gates (which needs B0 for that fix only), and re-initialised
// when a later accepted fix lies more than reinit_distance_m from the filter
// estimate.
struct MonteCarloTrackerOptions {
  ParticleFilterOptions filter;
  InverterOptions init_inverter;      // method and gates for the initialising fixes
  double init_position_sigma_m = 2.0; // prior σ around the initialising fix
  double reinit_distance_m = 10.0;    // infinity disables re-initialisation

  bool IsValid(std::string* error) const;
};

class MonteCarloTracker {
 public:
  explicit MonteCarloTracker(const MonteCarloTrackerOptions& options);
  // Samples of one sensor must come in time order. The returned fix is valid
  // once the sensor's filter is initialised (reason kNotInitialized before);
  // it carries the filter's mean position, the sample's cond(T) and no moment.
  DipoleFix Process(const GradiometerSample& sample);

 private:
  struct Track {
    DipoleParticleFilter filter;
    Inverter inverter;
  };
  MonteCarloTrackerOptions options_;
  std::unordered_map<std::uint32_t, Track> tracks_;
};

}  // namespace magnav::inversion
