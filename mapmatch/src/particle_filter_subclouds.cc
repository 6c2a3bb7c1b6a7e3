// Independent sub-clouds (ParticleFilterOptions::subclouds; particle_filter.h
// says what and why): K filters of one kind side by side on the same map and
// readings, each with its own particles, seed, resampling, σ and detectors;
// the pooled cloud is published, and the sub-clouds' disagreement is a
// lost-track detector. particle_filter_impl.h says which file holds what.
// Units as in particle_filter.h (deg, nT, deg²).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "particle_filter_impl.h"

namespace magnav::mapmatch::internal {
namespace {

constexpr std::uint64_t kSeedStep = 0x9E3779B97F4A7C15ULL;  // 2^64 / the golden ratio

class SubClouds final : public SequentialMatcher {
 public:
  SubClouds(ParticleFilterKind kind, const GeoGrid& grid, std::size_t layer, const ParticleFilterOptions& o)
      : kind_(kind), grid_(grid), o_(o),
        converging_cov_(kind == ParticleFilterKind::kPf ? o.converging_covariance_mixture
                                                   : o.afpf_converging_covariance_mixture) {
    std::string why;
    if (!o.IsValid(&why)) throw InputError(std::string(ParticleFilterKindName(kind)) + " options: " + why);
    const int k = o.subclouds;
    ParticleFilterOptions s = o;
    s.subclouds = 1;
    for (int i = 0; i < k; ++i) {
      // Sub-cloud 0 keeps the run's seed; the others' are spread by the 64-bit golden ratio.
      s.seed = o.seed + static_cast<std::uint64_t>(i) * kSeedStep;
      subs_.push_back(std::make_unique<Filter>(kind, grid, layer, s));
    }
    evidence_.resize(subs_.size());
  }

  const StepDiagnostics& Step(double ins_lat, double ins_lon, double measured_nT) override;
  const std::vector<Particle>& particles() const override { return pooled_; }
  const FilterCounters& counters() const override { return counters_; }
  const StepDiagnostics& last() const override { return last_; }
  ParticleFilterKind kind() const override { return kind_; }

 private:
  void Pool(StepDiagnostics* d);
  void Reseed();

  ParticleFilterKind kind_;
  const GeoGrid& grid_;
  ParticleFilterOptions o_;
  std::vector<std::unique_ptr<Filter>> subs_;
  std::vector<const StepDiagnostics*> sd_;
  std::vector<Particle> pooled_;
  std::vector<long long> cells_;
  int disagree_run_ = 0;  // steps in a row with D > subcloud_chi2
  std::vector<std::deque<double>> evidence_;  // per sub-cloud: log evidence of the last subcloud_window updates
  std::uint64_t reseeds_ = 0;
  ConvergingCovariance converging_cov_;  // the pooled cloud's history (converging_covariance_mixture)
  int reinitialisations_seen_ = 0;
  FilterCounters counters_;
  StepDiagnostics last_;
};


const StepDiagnostics& SubClouds::Step(double ins_lat, double ins_lon, double measured_nT) {
  sd_.clear();
  for (auto& f : subs_) sd_.push_back(&f->Step(ins_lat, ins_lon, measured_nT));
  StepDiagnostics d;
  Pool(&d);
  // The disagreement test: the largest pairwise D, held subcloud_hold steps.
  double dmax = 0.0;
  for (std::size_t i = 0; i < sd_.size(); ++i) {
    for (std::size_t j = i + 1; j < sd_.size(); ++j) dmax = std::max(dmax, CloudDisagreement(*sd_[i], *sd_[j]));
  }
  d.subcloud_chi2 = dmax;
  d.subclouds_disagree = dmax > o_.subcloud_chi2;
  disagree_run_ = d.subclouds_disagree ? disagree_run_ + 1 : 0;
  // Each sub-cloud's log evidence of this reading (StepLogEvidence).
  for (std::size_t i = 0; i < sd_.size(); ++i) {
    evidence_[i].push_back(StepLogEvidence(*sd_[i]));
    if (static_cast<int>(evidence_[i].size()) > o_.subcloud_window) evidence_[i].pop_front();
  }
  const bool disagree = disagree_run_ >= o_.subcloud_hold;
  bool any_lost = false, all_reacquiring = true;
  for (const StepDiagnostics* s : sd_) {
    if (s->lost) any_lost = true, all_reacquiring = all_reacquiring && s->reacquiring;
  }
  d.lost = any_lost || disagree;
  d.reacquiring = d.lost && !disagree && all_reacquiring;
  // Converging (settle_updates): some sub-cloud not settled, or the pooled cloud (their disagreement
  // included) wider than settled_sigma_deg.
  bool any_converging = false;
  for (const StepDiagnostics* s : sd_) any_converging = any_converging || s->converging;
  d.converging = !d.lost && o_.settle_updates > 0 && o_.settled_sigma_deg > 0.0 &&
                 (any_converging || !(std::sqrt(d.cloud_cov_lat_lat + d.cloud_cov_lon_lon) < o_.settled_sigma_deg));
  // Counters: what the input did (steps, updates, bad readings, off map, INS jumps and glitches, outliers) is
  // sub-cloud 0's; what the filters did (resamples, re-initialisations, tempered updates, alarms) is
  // summed over the sub-clouds; lost steps are the pooled filter's.
  const FilterCounters& c0 = subs_.front()->counters();
  counters_.steps = c0.steps, counters_.updates = c0.updates, counters_.bad_measurements = c0.bad_measurements;
  counters_.all_off_map = c0.all_off_map, counters_.ins_jumps = c0.ins_jumps, counters_.outliers = c0.outliers;
  counters_.spaced = c0.spaced, counters_.ins_glitches = c0.ins_glitches;
  counters_.resamples = counters_.reinitialisations = counters_.tempered_updates = 0;
  counters_.track_check_failures = counters_.bias_test_failures = 0;
  for (const auto& f : subs_) {
    const FilterCounters& c = f->counters();
    counters_.resamples += c.resamples, counters_.reinitialisations += c.reinitialisations;
    counters_.tempered_updates += c.tempered_updates, counters_.track_check_failures += c.track_check_failures;
    counters_.bias_test_failures += c.bias_test_failures;
  }
  if (d.lost) ++counters_.lost_steps;
  if (d.converging) ++counters_.converging_steps;
  // The published covariance: the pooled cloud's, while lost at least the prior square's (as one filter's).
  d.cov_lat_lat = d.cloud_cov_lat_lat, d.cov_lat_lon = d.cloud_cov_lat_lon, d.cov_lon_lon = d.cloud_cov_lon_lon;
  FloorLostCovariance(o_, &d);
  // While converging, the recent pooled clouds' mixture (as one filter's); a re-initialisation of any
  // sub-cloud starts its history again.
  if (counters_.reinitialisations != reinitialisations_seen_) converging_cov_.Clear();
  reinitialisations_seen_ = counters_.reinitialisations;
  converging_cov_.Publish(ins_lat, ins_lon, &d);
  last_ = d;
  if (d.subclouds_disagree && o_.subcloud_reseed_nats > 0.0) Reseed();
  return last_;
}

// Re-seeding (subcloud_reseed_nats, see the header): every sub-cloud whose windowed log evidence is
// below the best one's by more than subcloud_reseed_nats becomes a copy of the best (particles, σ,
// detectors' windows, evidence window) with a fresh seed. Takes effect from the next step; this
// step's published figures are those measured above.
void SubClouds::Reseed() {
  std::vector<double> sum(subs_.size(), 0.0);
  std::size_t best = 0;
  for (std::size_t i = 0; i < subs_.size(); ++i) {
    for (double e : evidence_[i]) sum[i] += e;
    if (sum[i] > sum[best]) best = i;
  }
  for (std::size_t i = 0; i < subs_.size(); ++i) {
    if (i == best || !(sum[best] - sum[i] > o_.subcloud_reseed_nats)) continue;
    auto copy = std::make_unique<Filter>(*subs_[best]);
    ++reseeds_;
    ++counters_.subcloud_reseeds;
    copy->ReseedRandom(o_.seed + (static_cast<std::uint64_t>(o_.subclouds) + reseeds_) * kSeedStep);
    subs_[i] = std::move(copy);
    evidence_[i] = evidence_[best];
  }
}

// The pooled cloud (each sub-cloud weighted 1/K): mean of the means, the mixture covariance
// (mean within + spread of the means) in cloud_cov_*, and the per-step figures combined.
void SubClouds::Pool(StepDiagnostics* d) {
  const double k = static_cast<double>(sd_.size());
  double lat = 0.0, lon = 0.0, bias = 0.0;
  for (const StepDiagnostics* s : sd_) lat += s->lat_deg / k, lon += s->lon_deg / k, bias += s->bias_nT / k;
  double cll = 0.0, cln = 0.0, cnn = 0.0, bv = 0.0, inv_ess = 0.0;
  double nis = 0.0, sigma = 0.0, innov = 0.0, spread = 0.0;
  int n_innov = 0;
  d->likelihood_exponent = 1.0;
  for (const StepDiagnostics* s : sd_) {
    const double a = s->lat_deg - lat, b = s->lon_deg - lon;
    cll += (s->cloud_cov_lat_lat + a * a) / k;
    cln += (s->cloud_cov_lat_lon + a * b) / k;
    cnn += (s->cloud_cov_lon_lon + b * b) / k;
    bv += (s->bias_sigma_nT * s->bias_sigma_nT + (s->bias_nT - bias) * (s->bias_nT - bias)) / k;
    inv_ess += s->ess > 0.0 ? 1.0 / s->ess : 0.0;
    nis += s->nis / k, sigma += s->sigma_nT / k;
    if (std::isfinite(s->innovation_nT)) innov += s->innovation_nT, spread += s->predicted_spread_nT, ++n_innov;
    d->likelihood_exponent = std::min(d->likelihood_exponent, s->likelihood_exponent);
    d->drift_sigma_deg = std::max(d->drift_sigma_deg, s->drift_sigma_deg);  // (the same in every sub-cloud)
    d->track_check_chi2 = std::max(d->track_check_chi2, s->track_check_chi2);
    d->innovation_bias_chi2 = std::max(d->innovation_bias_chi2, s->innovation_bias_chi2);
    d->innovation_cusum = std::max(d->innovation_cusum, s->innovation_cusum);
    d->track_check_failed = d->track_check_failed || s->track_check_failed;
    d->ins_step_ratio = std::max(d->ins_step_ratio, s->ins_step_ratio);
    d->ins_glitch = d->ins_glitch || s->ins_glitch;
    d->resampled = d->resampled || s->resampled;
    d->unique_particles += s->unique_particles;
  }
  d->lat_deg = lat, d->lon_deg = lon, d->bias_nT = bias, d->bias_sigma_nT = std::sqrt(bv);
  d->cloud_cov_lat_lat = cll, d->cloud_cov_lat_lon = cln, d->cloud_cov_lon_lon = cnn;
  // The pooled weights are w/K: ESS = 1/Σ(w/K)² = K² / Σ_k (1/ESS_k).
  d->ess = inv_ess > 0.0 ? k * k / inv_ess : 0.0;
  d->nis = nis, d->sigma_nT = sigma;
  if (n_innov > 0) d->innovation_nT = innov / n_innov, d->predicted_spread_nT = spread / n_innov;
  d->ins_jump = sd_.front()->ins_jump;
  d->update = sd_.front()->update;
  d->partly_observable = false;
  pooled_.clear();
  for (const auto& f : subs_) {
    for (Particle q : f->particles()) {
      q.weight /= k;
      pooled_.push_back(q);
    }
  }
  d->particles = static_cast<int>(pooled_.size());
  // Occupied map cells of the pooled cloud (as Filter::Estimate counts them).
  d->occupied_cells = OccupiedCells(grid_, pooled_, &cells_);
}

}  // namespace

std::unique_ptr<SequentialMatcher> MakeSubClouds(ParticleFilterKind kind, const GeoGrid& grid, std::size_t layer,
                                                 const ParticleFilterOptions& options) {
  return std::make_unique<SubClouds>(kind, grid, layer, options);
}

}  // namespace magnav::mapmatch::internal
