// The particle filters' private class (mapmatch/src only): one Filter runs
// the PF or the AFPF (particle_filter.h). Its member functions are split by
// role over
//   particle_filter.cc              options, the step (prior, prediction,
//                                   update), the factory
//   particle_filter_likelihood.cc   the measurement model: log-likelihood and
//                                   the (adaptive) likelihood σ
//   particle_filter_pf.cc           the PF strategy: tempering, resampling,
//                                   regularisation
//   particle_filter_afpf.cc         the AFPF strategy: fission, selection,
//                                   adaptive count
//   particle_filter_diagnostics.cc  estimate, ESS, lost-track detection,
//                                   the run's status (MatchParticleFilter)
//   particle_filter_subclouds.cc    K independent sub-clouds pooled, their
//                                   disagreement test (MakeSubClouds)
//   particle_filter_ensemble.cc     shadow clouds during acquisition, their
//                                   disagreement flag (MakeAcquisitionEnsemble)
//   particle_filter_slide.cc        the offset-slide status rule of
//                                   MatchParticleFilter (particle_filter_slide.h)
// Units and frames as in particle_filter.h (deg, nT, deg²).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "magnav/core/error.h"
#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/particle_filter.h"

namespace magnav::mapmatch::internal {

// How far apart two clouds' means are in their own spreads: (m_a − m_b)ᵀ (C_a + C_b)⁻¹ (m_a − m_b) with
// the clouds' own covariances (cloud_cov_*: a lost cloud's published one is the prior's floor); a
// degenerate sum (every particle of both on one point) gets 1e-14 deg² (≈ 1 cm²). The sub-clouds' D
// (particle_filter_subclouds.cc) and the acquisition ensemble's E (particle_filter_ensemble.cc).
double CloudDisagreement(const StepDiagnostics& a, const StepDiagnostics& b);

// A step's log evidence of its reading, log Σ w N(z; m(x), σ²) = −NIS/2 − ln σ − ln √(2π) (NIS =
// −2 ln Σ w exp(−r²/2σ²); the constant dropped): 0 when no reading was weighed. The sub-clouds' re-seeding
// and the acquisition ensemble's evidence check sum it over their windows.
double StepLogEvidence(const StepDiagnostics& s);

// A mixture's covariance (deg²) published in place of the step's if it is finite and wider (its trace
// larger): the converging episode's mixture and the acquisition shadows' never narrow what the filter says.
void PublishIfWider(double ll, double ln, double nn, StepDiagnostics* d);

// A lost step's published covariance (ParticleFilterOptions::lost_covariance_is_prior): at least the
// prior square's, a uniform over ±prior_half_width_deg (h²/3 deg² per axis), when the cloud's own
// (cloud_cov_*) is narrower: a lost filter does not know where it is within the region it would search.
// Nothing changes while the step is not lost or the option is off. The filter's step, the pooled
// sub-clouds' and the acquisition ensemble's lost flag all publish through it.
void FloorLostCovariance(const ParticleFilterOptions& o, StepDiagnostics* d);

// The published covariance while converging (ParticleFilterOptions::converging_covariance_mixture,
// particle_filter_diagnostics.cc): running sums over the converging episode's clouds (the cloud of the
// step before it, then every converging step's), as offsets from their INS positions o_i (deg) with
// their covariances C_i (deg²): n, Σ C_i, Σ o_i, Σ o_i o_iᵀ.
class ConvergingCovariance {
 public:
  explicit ConvergingCovariance(bool on) : on_(on) {}
  void Clear() { n_ = 0, c_ = {}, o_ = {}, oo_ = {}; }
  // A step not converging (or lost) ends the episode and is kept as the next one's start; a
  // converging one joins the episode (the first one after that start) and widens d->cov_* to the
  // mixture's covariance about the current mean when its trace is larger. Uses d->lat_deg/lon_deg
  // and d->cloud_cov_*.
  void Publish(double ins_lat, double ins_lon, StepDiagnostics* d);

 private:
  void Add(const std::array<double, 5>& h);  // (offset lat, lon, cloud cov lat-lat, lat-lon, lon-lon)
  bool on_;
  bool has_prev_ = false;
  std::array<double, 5> prev_{};  // the last step not converging: its cloud, the next episode's start
  long long n_ = 0;
  std::array<double, 3> c_{}, oo_{};  // Σ C_i and Σ o_i o_iᵀ (lat-lat, lat-lon, lon-lon)
  std::array<double, 2> o_{};         // Σ o_i
};

class Filter final : public SequentialMatcher {
 public:
  Filter(ParticleFilterKind kind, const GeoGrid& grid, std::size_t layer, const ParticleFilterOptions& o)
      : kind_(kind), grid_(grid), layer_(layer), o_(o), rng_(o.seed),
        converging_cov_(kind == ParticleFilterKind::kPf ? o.converging_covariance_mixture
                                                   : o.afpf_converging_covariance_mixture) {
    if (layer >= grid.layer_names().size()) throw InputError(std::string(Name()) + ": layer index not in the map");
    std::string why;
    if (!o.IsValid(&why)) throw InputError(std::string(Name()) + " options: " + why);
    inv_two_var_ = 1.0 / (2.0 * o.measurement_sigma_nT * o.measurement_sigma_nT);
    off_map_loglik_ = -0.5 * o.off_map_sigmas * o.off_map_sigmas;
    adaptive_ = kind == ParticleFilterKind::kPf ? o.adaptive_sigma : o.afpf_sigma_factor > 0.0;
    drift_sd_deg_ = o.drift_sigma_deg;
  }


  const StepDiagnostics& Step(double ins_lat, double ins_lon, double measured_nT) override;
  const std::vector<Particle>& particles() const override { return p_; }
  const FilterCounters& counters() const override { return counters_; }
  const StepDiagnostics& last() const override { return last_; }
  ParticleFilterKind kind() const override { return kind_; }
  // Sub-clouds (particle_filter_subclouds.cc): a copy of a filter re-seeded from another takes a fresh seed.
  void ReseedRandom(std::uint64_t seed) { rng_.seed(seed); }

 private:
  const char* Name() const { return ParticleFilterKindName(kind_); }

  // particle_filter.cc: the step.
  void SpreadPrior(double lat, double lon);
  bool Predict(double lat, double lon);
  void Normalise();
  void Update(double z, StepDiagnostics* d);
  void SkipUpdate(StepUpdate why, StepDiagnostics* d);

  // particle_filter_likelihood.cc: the measurement model.
  double LogLik(double lat, double lon, double z, double bias_var, bool* on_map, double* residual = nullptr) const;
  static void UpdateBias(Particle* q, double r, double noise_var);
  double CurrentSigma() const;

  // particle_filter_pf.cc: the PF strategy.
  double PfTemperedExponent();
  void PfResample(StepDiagnostics* d);
  double EssWith(double beta) const;
  void Resample();
  void Regularise();

  // particle_filter_afpf.cc: the AFPF strategy.
  void Fission(double z);
  void KeepHeaviest(std::size_t n);
  void AdaptCount(const StepDiagnostics& d);

  // particle_filter_diagnostics.cc: estimate and lost-track detection.
  void Estimate(StepDiagnostics* d);
  double Ess() const;
  bool Lost() const;
  bool Diverged() const;
  double NoiseSigma() const;
  void RecordInnovation(double r, double spread2, StepDiagnostics* d);
  double AcquisitionThreshold() const;
  void CheckAcquisitionBias(StepDiagnostics* d);
  void RecordCusum(double r, double spread2, StepDiagnostics* d);
  double CusumThreshold() const;
  void CheckTrack(double ins_lat, double ins_lon, double z, StepDiagnostics* d);
  void PublishCovariance(StepDiagnostics* d) const;
  void CheckInsGlitch(double dn_m, double de_m, StepDiagnostics* d);

  ParticleFilterKind kind_;
  const GeoGrid& grid_;
  std::size_t layer_;
  ParticleFilterOptions o_;
  std::mt19937_64 rng_;
  double inv_two_var_ = 0.0, off_map_loglik_ = 0.0;
  bool initialised_ = false;
  int consecutive_outliers_ = 0;  // readings skipped in a row by the outlier gate
  double prev_lat_ = 0.0, prev_lon_ = 0.0;
  // The INS steps' running mean length (m; exponential, gain kStepMeanGain ≈ 20 steps; < 0 before the
  // first step) and the drift per step it gives (DriftSigmaPerStep).
  static constexpr double kStepMeanGain = 0.05;
  double mean_step_m_ = -1.0;
  double drift_sd_deg_ = 0.0;
  // INS glitch test (ins_glitch_ratio, particle_filter_diagnostics.cc): the running mean increment
  // (m, north/east), mean step length (m) and mean square departure (m²); steps left lost after a glitch.
  bool glitch_init_ = false;
  double glitch_dn_ = 0.0, glitch_de_ = 0.0, glitch_len_ = 0.0, glitch_dev2_ = 0.0;
  int glitch_left_ = 0;
  bool glitch_pending_ = false;  // the last increment departed; the next one says whether it was a jump
  double glitch_pending_dn_ = 0.0, glitch_pending_de_ = 0.0;
  // The acquisition phase (acquisition_bias_test_chi2): the step at which the cloud first settled (−1: not yet).
  long long settled_at_ = -1;
  double update_lat_ = 0.0, update_lon_ = 0.0;  // INS position of the last reading used (min_update_spacing_m)
  std::vector<Particle> p_;
  std::vector<double> logw_, loglik_;
  std::vector<double> resid_;  // estimate_bias: each particle's residual z − b − m(x) (NaN off the map)
  std::vector<Particle> pool_;
  std::vector<double> pool_logw_;
  std::vector<std::size_t> order_;
  std::vector<long long> cells_;
  std::deque<double> nis_window_;
  std::deque<std::pair<double, double>> bias_window_;  // innovation-bias test: (r, σ_n² + V) per update
  bool bias_failed_ = false;                          // the bias test fired at this update
  // The bias test during acquisition (CheckAcquisitionBias): (r, σ_n² + V, the cloud's 1-σ spread after that
  // update, deg) per update; whether this step's update recorded one; whether the test fired at this step.
  std::deque<std::array<double, 3>> acq_window_;
  bool acq_recorded_ = false;
  bool acq_failed_ = false;
  std::deque<double> cusum_hist_;  // innovation CUSUM: r² − V per update (window + delay)
  double cusum_g_ = 0.0;           // its statistic g
  bool reacquiring_ = false;                          // re-initialised and not settled yet
  int reacquiring_steps_ = 0;                         // steps since that re-initialisation
  int settle_count_ = 0;  // the converging status: updates in a row with the cloud settled (settle_updates)
  std::deque<std::array<double, 3>> track_;  // track check: (INS lat, lon, reading) per update
  int since_check_ = 0;
  bool track_lost_ = false;  // the last track check's verdict (held until the next check)
  std::deque<std::pair<double, double>> innov_;  // adaptive σ: (z − m̄)², Var(m) per update
  double sigma_ = 0.0;
  bool adaptive_ = false;  // PF: adaptive_sigma; AFPF: afpf_sigma_factor > 0
  int unique_ = 0;
  ConvergingCovariance converging_cov_;
  FilterCounters counters_;
  StepDiagnostics last_;
};

// How many map cells the particles occupy (cells outside the map counted too); `scratch` is reused storage.
// particle_filter_diagnostics.cc.
int OccupiedCells(const GeoGrid& grid, const std::vector<Particle>& particles, std::vector<long long>* scratch);

// particle_filter_subclouds.cc: K = options.subclouds independent filters pooled (particle_filter.h).
std::unique_ptr<SequentialMatcher> MakeSubClouds(ParticleFilterKind kind, const GeoGrid& grid, std::size_t layer,
                                                 const ParticleFilterOptions& options);

// particle_filter_ensemble.cc: the filter and acquisition_ensemble − 1 shadows during acquisition (particle_filter.h).
std::unique_ptr<SequentialMatcher> MakeAcquisitionEnsemble(ParticleFilterKind kind, const GeoGrid& grid,
                                                           std::size_t layer, const ParticleFilterOptions& options);

}  // namespace magnav::mapmatch::internal
