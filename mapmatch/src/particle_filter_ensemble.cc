// Ensemble disagreement during acquisition (ParticleFilterOptions::acquisition_ensemble;
// particle_filter.h says what and why): the filter runs as it would alone, and K − 1 shadow filters
// of its kind, independently seeded, run beside it on the same readings while it acquires. Their
// means settling apart beyond their clouds' covariances flags the step lost (acquisition_ensemble_flag),
// and their spread widens the published covariance of a converging or ok step (acquisition_ensemble_covariance).
// The filter's estimate, cloud and own flags are published unchanged. Units as in particle_filter.h (deg, nT, deg²).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "particle_filter_impl.h"

namespace magnav::mapmatch::internal {
namespace {

constexpr std::uint64_t kSeedStep = 0x9E3779B97F4A7C15ULL;  // 2^64 / the golden ratio (as the sub-clouds')

class AcquisitionEnsemble final : public SequentialMatcher {
 public:
  AcquisitionEnsemble(ParticleFilterKind kind, const GeoGrid& grid, std::size_t layer, const ParticleFilterOptions& o)
      : kind_(kind), grid_(grid), layer_(layer), o_(o) {
    std::string why;
    if (!o.IsValid(&why)) throw InputError(std::string(ParticleFilterKindName(kind)) + " options: " + why);
    ParticleFilterOptions s = o;
    s.acquisition_ensemble = 1;
    s.acquisition_ensemble_covariance = ParticleFilterOptions::EnsembleCovariance::kOff;
    s.acquisition_ensemble_isotropic = false;
    main_ = std::make_unique<Filter>(kind, grid, layer, s);
    StartShadows();
  }

  const StepDiagnostics& Step(double ins_lat, double ins_lon, double measured_nT) override;
  const std::vector<Particle>& particles() const override { return main_->particles(); }
  const FilterCounters& counters() const override { return counters_; }
  const StepDiagnostics& last() const override { return last_; }
  ParticleFilterKind kind() const override { return kind_; }

 private:
  void StartShadows();
  void Record(std::deque<double>* window, const StepDiagnostics& s) const;
  static double Sum(const std::deque<double>& window);
  void PublishMixtureCovariance(StepDiagnostics* d) const;

  ParticleFilterKind kind_;
  const GeoGrid& grid_;
  std::size_t layer_;
  ParticleFilterOptions o_;
  std::unique_ptr<Filter> main_;
  std::vector<std::unique_ptr<Filter>> shadows_;  // empty once the acquisition is over
  // Log evidence of the last acquisition_ensemble_window readings: the filter's, each shadow's.
  std::deque<double> main_evidence_;
  std::vector<std::deque<double>> shadow_evidence_;
  std::vector<StepDiagnostics> shadow_steps_;     // the shadows' diagnostics of this step (empty: not run)
  std::uint64_t starts_ = 0;                      // shadow sets started (their seeds)
  long long step_ = -1;                           // this step's index
  long long first_ok_at_ = -1;                    // the filter's first ok step since the shadows started
  int disagree_run_ = 0;                          // steps in a row with E > acquisition_ensemble_chi2
  int reinitialisations_seen_ = 0;
  int extra_lost_ = 0, fewer_converging_ = 0;     // the counters' changes by the ensemble's flag
  FilterCounters counters_;
  StepDiagnostics last_;
};

// K − 1 fresh shadows (their first step spreads their prior around that step's INS position, as the
// filter's first step and a re-initialisation do).
void AcquisitionEnsemble::StartShadows() {
  ParticleFilterOptions s = o_;
  s.acquisition_ensemble = 1;
  s.acquisition_ensemble_covariance = ParticleFilterOptions::EnsembleCovariance::kOff;
  s.acquisition_ensemble_isotropic = false;
  shadows_.clear();
  main_evidence_.clear();
  shadow_evidence_.assign(static_cast<std::size_t>(o_.acquisition_ensemble - 1), {});
  for (int i = 1; i < o_.acquisition_ensemble; ++i) {
    s.seed = o_.seed + (starts_ * static_cast<std::uint64_t>(o_.acquisition_ensemble) + static_cast<std::uint64_t>(i)) *
                           kSeedStep;
    shadows_.push_back(std::make_unique<Filter>(kind_, grid_, layer_, s));
  }
  ++starts_;
  first_ok_at_ = -1;
  disagree_run_ = 0;
}

// The window of a cloud's log evidence (StepLogEvidence), at most acquisition_ensemble_window steps.
void AcquisitionEnsemble::Record(std::deque<double>* window, const StepDiagnostics& s) const {
  window->push_back(StepLogEvidence(s));
  if (static_cast<int>(window->size()) > o_.acquisition_ensemble_window) window->pop_front();
}

double AcquisitionEnsemble::Sum(const std::deque<double>& window) {
  double sum = 0.0;
  for (double e : window) sum += e;
  return sum;
}

const StepDiagnostics& AcquisitionEnsemble::Step(double ins_lat, double ins_lon, double measured_nT) {
  ++step_;
  StepDiagnostics d = main_->Step(ins_lat, ins_lon, measured_nT);
  // A re-initialised filter acquires again: so do fresh shadows (from the next step).
  const bool reinitialised = main_->counters().reinitialisations != reinitialisations_seen_;
  reinitialisations_seen_ = main_->counters().reinitialisations;
  bool flag = false;
  shadow_steps_.clear();
  if (!shadows_.empty()) {
    // The shadow furthest from the filter (largest E): its separation, and its windowed log evidence less
    // the filter's (> 0: the readings favour the shadow).
    Record(&main_evidence_, d);
    double e = -1.0, sep = 0.0, gap = 0.0;
    for (std::size_t i = 0; i < shadows_.size(); ++i) {
      const StepDiagnostics& s = shadows_[i]->Step(ins_lat, ins_lon, measured_nT);
      Record(&shadow_evidence_[i], s);
      shadow_steps_.push_back(s);
      const double ei = CloudDisagreement(d, s);
      if (ei > e) {
        e = ei;
        sep = std::hypot(d.lat_deg - s.lat_deg, d.lon_deg - s.lon_deg);
        gap = Sum(shadow_evidence_[i]) - Sum(main_evidence_);
      }
    }
    d.ensemble_chi2 = e, d.ensemble_separation_deg = sep, d.ensemble_evidence_nats = gap;
    d.ensemble_disagree = e > o_.acquisition_ensemble_chi2 && gap > -o_.acquisition_ensemble_nats;
    disagree_run_ = d.ensemble_disagree ? disagree_run_ + 1 : 0;
    flag = o_.acquisition_ensemble_flag && disagree_run_ >= o_.acquisition_ensemble_hold;
    if (first_ok_at_ < 0 && !d.lost && !d.converging) first_ok_at_ = step_;
    if (first_ok_at_ >= 0 && step_ >= first_ok_at_ + o_.acquisition_steps) shadows_.clear();  // acquired
  }
  if (flag && !d.lost) {
    d.lost = true;
    ++extra_lost_;
    if (d.converging) ++fewer_converging_;
    d.converging = false;
    // The published covariance of a lost step, as the filter's own; the cloud's stays in cloud_cov_*.
    FloorLostCovariance(o_, &d);
  }
  if (!shadow_steps_.empty() && !d.lost) PublishMixtureCovariance(&d);
  if (reinitialised) StartShadows();
  counters_ = main_->counters();
  counters_.lost_steps += extra_lost_;
  counters_.converging_steps -= fewer_converging_;
  counters_.ensemble_lost_steps = extra_lost_;
  last_ = d;
  return last_;
}

// acquisition_ensemble_covariance: the mixture of the filter's published distribution (d on entry) and
// the shadows' of this step, about the filter's mean, when its trace exceeds the published one.
void AcquisitionEnsemble::PublishMixtureCovariance(StepDiagnostics* d) const {
  using Mode = ParticleFilterOptions::EnsembleCovariance;
  if (o_.acquisition_ensemble_covariance == Mode::kOff) return;
  const std::size_t k = shadow_steps_.size() + 1;
  // Weights: equal, or ∝ exp(windowed log evidence) (shifted by the largest for the exponentials).
  std::vector<double> w(k, 1.0);
  if (o_.acquisition_ensemble_covariance == Mode::kEvidence) {
    std::vector<double> ev(k);
    ev[0] = Sum(main_evidence_);
    for (std::size_t i = 1; i < k; ++i) ev[i] = Sum(shadow_evidence_[i - 1]);
    const double top = *std::max_element(ev.begin(), ev.end());
    if (std::isfinite(top)) {  // else every cloud's is non-finite: equal weights
      for (std::size_t i = 0; i < k; ++i) w[i] = std::isfinite(ev[i]) ? std::exp(ev[i] - top) : 0.0;
    }
  }
  double wsum = 0.0;
  for (double x : w) wsum += x;
  double ll = 0.0, ln = 0.0, nn = 0.0;
  for (std::size_t i = 0; i < k; ++i) {
    // A lost shadow's published covariance is the prior square's floor, not its cloud's: its cloud's.
    const StepDiagnostics& c = i == 0 ? *d : shadow_steps_[i - 1];
    const bool own = i > 0 && c.lost;
    const double a = w[i] / wsum, dl = c.lat_deg - d->lat_deg, dn = c.lon_deg - d->lon_deg;
    ll += a * (own ? c.cloud_cov_lat_lat : c.cov_lat_lat);
    ln += a * (own ? c.cloud_cov_lat_lon : c.cov_lat_lon);
    nn += a * (own ? c.cloud_cov_lon_lon : c.cov_lon_lon);
    if (o_.acquisition_ensemble_isotropic) {  // the offsets' spread, half on each axis
      ll += a * 0.5 * (dl * dl + dn * dn);
      nn += a * 0.5 * (dl * dl + dn * dn);
    } else {
      ll += a * dl * dl, ln += a * dl * dn, nn += a * dn * dn;
    }
  }
  PublishIfWider(ll, ln, nn, d);
}

}  // namespace

std::unique_ptr<SequentialMatcher> MakeAcquisitionEnsemble(ParticleFilterKind kind, const GeoGrid& grid,
                                                           std::size_t layer, const ParticleFilterOptions& options) {
  return std::make_unique<AcquisitionEnsemble>(kind, grid, layer, options);
}

}  // namespace magnav::mapmatch::internal
