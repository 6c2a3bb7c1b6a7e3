// The particle filters' diagnostics: the estimate and its covariance, the
// ESS, lost-track detection, and a run's status and summary
// (MatchParticleFilter); particle_filter_impl.h says which file holds what.
#include "particle_filter_impl.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "magnav/core/csv.h"
#include "match_common.h"

namespace magnav::mapmatch {
namespace internal {

void Filter::Estimate(StepDiagnostics* d) {
  double lat = 0.0, lon = 0.0, bias = 0.0;
  for (const Particle& q : p_) {
    lat += q.weight * q.lat_deg;
    lon += q.weight * q.lon_deg;
    bias += q.weight * q.bias_nT;
  }
  double bias_var = 0.0;
  for (const Particle& q : p_) bias_var += q.weight * (q.bias_nT - bias) * (q.bias_nT - bias);
  d->bias_nT = bias;
  d->bias_sigma_nT = std::sqrt(bias_var);
  double cll = 0.0, cln = 0.0, cnn = 0.0;
  for (const Particle& q : p_) {
    const double a = q.lat_deg - lat, b = q.lon_deg - lon;
    cll += q.weight * a * a;
    cln += q.weight * a * b;
    cnn += q.weight * b * b;
  }
  d->lat_deg = lat;
  d->lon_deg = lon;
  d->cov_lat_lat = cll;
  d->cov_lat_lon = cln;
  d->cov_lon_lon = cnn;
  d->unique_particles = unique_;
  // Occupied map cells (cells outside the map counted too).
  cells_.resize(p_.size());
  const double la0 = grid_.lat().first_deg, lo0 = grid_.lon().first_deg;
  const double ila = 1.0 / grid_.lat().step_deg, ilo = 1.0 / grid_.lon().step_deg;
  for (std::size_t i = 0; i < p_.size(); ++i) {
    const auto a = static_cast<long long>(std::floor((p_[i].lat_deg - la0) * ila));
    const auto b = static_cast<long long>(std::floor((p_[i].lon_deg - lo0) * ilo));
    cells_[i] = a * 1000003LL + b;
  }
  std::sort(cells_.begin(), cells_.end());
  d->occupied_cells = static_cast<int>(std::unique(cells_.begin(), cells_.end()) - cells_.begin());
}

double Filter::Ess() const {
  double s = 0.0;
  for (const Particle& q : p_) s += q.weight * q.weight;
  return s > 0.0 ? 1.0 / s : 0.0;
}

// Lost: the divergence rule (mean NIS over divergence_window updates) or the
// innovation-bias test (RecordInnovation, this update).
bool Filter::Lost() const { return bias_failed_ || Diverged(); }

// The divergence rule: mean NIS over the last divergence_window updates > divergence_nis.
bool Filter::Diverged() const {
  if (static_cast<int>(nis_window_.size()) < o_.divergence_window) return false;
  const double mean = std::accumulate(nis_window_.begin(), nis_window_.end(), 0.0) / nis_window_.size();
  return mean > o_.divergence_nis;
}

// The noise the filter sees (nT): the PF's likelihood σ; the AFPF's σ over
// afpf_sigma_factor (its σ is that multiple of the innovations' estimate);
// at least 0.5 nT.
double Filter::NoiseSigma() const {
  double sn = sigma_ > 0.0 ? sigma_ : o_.measurement_sigma_nT;
  if (kind_ == ParticleFilterKind::kAfpf && adaptive_) sn /= o_.afpf_sigma_factor;
  return std::max(sn, 0.5);
}

// The innovation-bias test (bias_test_window, see the header): this update's
// innovation r = z − m̄ and the cloud's spread V of predicted map values (nT²)
// join the window; B = (Σ r)² / Σ (σ_n² + V) once it is full.
void Filter::RecordInnovation(double r, double spread2, StepDiagnostics* d) {
  bias_failed_ = false;
  const double threshold = kind_ == ParticleFilterKind::kAfpf ? o_.afpf_bias_test_chi2 : o_.bias_test_chi2;
  if (o_.bias_test_window == 0 || threshold == 0.0 || !std::isfinite(r)) return;
  const double sn = NoiseSigma();
  bias_window_.emplace_back(r, sn * sn + spread2);
  if (static_cast<int>(bias_window_.size()) > o_.bias_test_window) bias_window_.pop_front();
  if (static_cast<int>(bias_window_.size()) < o_.bias_test_window) return;
  double sum_r = 0.0, sum_var = 0.0;
  for (const auto& [a, v] : bias_window_) sum_r += a, sum_var += v;
  d->innovation_bias_chi2 = sum_var > 0.0 ? sum_r * sum_r / sum_var : 0.0;
  bias_failed_ = d->innovation_bias_chi2 > threshold;
}

// The track check (track_check_window, see the header): does the estimated
// track of the last W updates, shifted as a whole by some offset o within
// the prior's half-width, fit its readings much better than where the filter
// has it? SSE(o) = Σ (z_j − m(x̂_j + o))² over the readings; o on a coarse
// grid, the best few refined. Lost when (SSE(0) − min SSE) / σ_n² exceeds
// track_check_chi2 × max(σ_n², SSE(best)/W) and the best o lies beyond 3 σ
// of the filter's own covariance (plus the refined grid's step). σ_n: the
// noise the filter sees (the PF's σ; the AFPF's σ / afpf_sigma_factor), at
// least 0.5 nT.
void Filter::CheckTrack(double z, StepDiagnostics* d) {
  if (d->update != StepUpdate::kUpdated || !std::isfinite(z)) return;
  track_.push_back({d->lat_deg, d->lon_deg, z});
  if (static_cast<int>(track_.size()) > o_.track_check_window) track_.pop_front();
  if (static_cast<int>(track_.size()) < o_.track_check_window) return;
  if (++since_check_ < o_.track_check_every) return;
  // Only a settled filter is checked (its 1-σ spread within the coarse grid's step): an acquiring,
  // spread cloud's mean lies between its basins, and any shift fits better than it.
  if (d->cov_lat_lat + d->cov_lon_lon > o_.track_check_step_deg * o_.track_check_step_deg) return;
  since_check_ = 0;
  auto sse = [this](double dlat, double dlon) {
    double s = 0.0;
    for (const auto& t : track_) {
      const auto m = grid_.Sample(layer_, t[0] + dlat, t[1] + dlon);
      if (!m) return std::numeric_limits<double>::infinity();  // the whole window must be on the map
      const double r = t[2] - m->value_nT;
      s += r * r;
    }
    return s;
  };
  const double here = sse(0.0, 0.0);
  if (!std::isfinite(here)) return;
  const double h = o_.prior_half_width_deg, coarse = o_.track_check_step_deg;
  const int nc = static_cast<int>(std::floor(h / coarse));
  std::vector<std::array<double, 3>> best;  // (sse, dlat, dlon), the 5 best coarse offsets
  for (int i = -nc; i <= nc; ++i) {
    for (int j = -nc; j <= nc; ++j) {
      const double v = sse(i * coarse, j * coarse);
      if (!std::isfinite(v)) continue;
      if (best.size() < 5 || v < best.back()[0]) {
        if (best.size() == 5) best.pop_back();
        best.push_back({v, i * coarse, j * coarse});
        std::sort(best.begin(), best.end());
      }
    }
  }
  const double fine = coarse / 5.0;
  std::array<double, 3> top = {here, 0.0, 0.0};
  for (const auto& b : best) {
    for (int i = -5; i <= 5; ++i) {
      for (int j = -5; j <= 5; ++j) {
        const double v = sse(b[1] + i * fine, b[2] + j * fine);
        if (v < top[0]) top = {v, b[1] + i * fine, b[2] + j * fine};
      }
    }
  }
  double sn = d->sigma_nT > 0.0 ? d->sigma_nT : o_.measurement_sigma_nT;
  if (kind_ == ParticleFilterKind::kAfpf && adaptive_) sn /= o_.afpf_sigma_factor;
  sn = std::max(sn, 0.5);
  // The scale: the larger of σ_n² and the residual variance at the best offset (the noise as the
  // best fit sees it: a track estimated step by step carries its own jitter, which no shift removes).
  d->track_check_chi2 = (here - top[0]) / std::max(sn * sn, top[0] / static_cast<double>(track_.size()));
  const double dist2 = top[1] * top[1] + top[2] * top[2];
  const double reach2 = 9.0 * (d->cov_lat_lat + d->cov_lon_lon) + fine * fine;
  if (d->track_check_chi2 > o_.track_check_chi2 && dist2 > reach2) {
    d->lost = true;
    d->track_check_failed = true;
    ++counters_.track_check_failures;
  }
}

}  // namespace internal

MatchResult MatchParticleFilter(ParticleFilterKind kind, const GeoGrid& grid, std::size_t layer,
                                const MatchPath& path, const ParticleFilterOptions& options,
                                std::vector<StepDiagnostics>* steps) {
  internal::CheckInputs(grid, layer, path, options, ParticleFilterKindName(kind));
  MatchResult r = internal::StartResult(ParticleFilterKindName(kind), "mean effective sample size", path);
  auto filter = MakeParticleFilter(kind, grid, layer, options);
  if (steps != nullptr) steps->clear();
  double ess_sum = 0.0, last_sigma = options.measurement_sigma_nT;
  long long first_lost = -1, last_lost = -1;
  std::size_t last_lost_step = 0, off_at_end = 0;  // off_at_end: trailing all-off-map steps
  for (std::size_t p = 0; p < path.size(); ++p) {
    const StepDiagnostics& d = filter->Step(path.lat_deg[p], path.lon_deg[p], path.measured_nT[p]);
    r.lat_deg[p] = d.lat_deg;
    r.lon_deg[p] = d.lon_deg;
    ess_sum += d.ess;
    if (d.sigma_nT > 0.0) last_sigma = d.sigma_nT;
    if (d.lost && first_lost < 0) first_lost = path.k[p];
    if (d.lost) last_lost = path.k[p], last_lost_step = p;
    off_at_end = d.update == StepUpdate::kAllOffMap ? off_at_end + 1 : 0;
    if (steps != nullptr) steps->push_back(d);
  }
  const FilterCounters& c = filter->counters();
  r.iterations = c.steps;
  r.score = ess_sum / static_cast<double>(path.size());
  r.points_used = c.updates;
  r.points_off_map = c.all_off_map;
  r.points_bad_measurement = c.bad_measurements;
  r.points_outlier = c.outliers;
  // Status (issue 25: no "converged" that is not): lost at the last step, or a re-initialisation
  // that has not had 2 divergence windows to settle, is not converged. A run that was lost and has
  // been quiet since says only that: a filter settled in a wrong basin can be quiet too.
  const std::size_t settle = 2 * static_cast<std::size_t>(options.divergence_window);
  const bool unsettled = last_lost >= 0 && path.size() - 1 - last_lost_step < settle;
  // A cloud entirely off the map at the end dead-reckons on the INS: no reading checks it.
  r.converged = !filter->lost() && !unsettled && off_at_end == 0;
  if (off_at_end > 0 && !filter->lost()) {
    r.reason = "off the map at the end: every particle off the map for the last " +
               std::to_string(off_at_end) + " step(s)" +
               " (dead-reckoning on the INS)" + (first_lost >= 0 ? "; lost at k = " + std::to_string(last_lost) : "");
  } else if (filter->lost()) {
    r.reason = filter->last().reacquiring
                   ? std::string("lost: re-initialised, the cloud not settled by the end")
                   : "lost (mean NIS over the last " + std::to_string(options.divergence_window) + " updates > " +
                         FormatNumber(options.divergence_nis) +
                         (options.bias_test_window > 0 &&
                                  (kind == ParticleFilterKind::kAfpf ? options.afpf_bias_test_chi2
                                                                     : options.bias_test_chi2) > 0.0
                              ? ", or the innovation-bias test"
                              : "") +
                         (options.track_check_window > 0 ? ", or the track check" : "") + ")";
  } else if (unsettled) {
    r.reason = "lost at k = " + std::to_string(last_lost) + (options.reinitialize_when_lost ? ", re-initialised" : "") +
               ", not settled by the end (fewer than " + std::to_string(settle) + " steps since)";
  } else if (first_lost >= 0) {
    r.reason = "lost from k = " + std::to_string(first_lost) + ", last at k = " + std::to_string(last_lost) +
               "; no lost-track alarm in the " + std::to_string(path.size() - 1 - last_lost_step) +
               " steps since (not a proof of being on the track)";
  }
  r.notes = "particles " + std::to_string(filter->particles().size()) + " at the end, seed " +
            std::to_string(options.seed) + ", sigma " +
            (kind == ParticleFilterKind::kPf && options.adaptive_sigma
                 ? "adaptive in [" + FormatNumber(options.min_measurement_sigma_nT) + ", " +
                       FormatNumber(options.measurement_sigma_nT) + "] nT, last " +
                       FormatNumber(last_sigma)
             : kind == ParticleFilterKind::kAfpf && options.afpf_sigma_factor > 0.0
                 ? FormatNumber(options.afpf_sigma_factor) + " x the innovations' in [" +
                       FormatNumber(options.measurement_sigma_nT) + ", " + FormatNumber(options.afpf_max_sigma_nT) +
                       "] nT, last " + FormatNumber(last_sigma)
                 : FormatNumber(options.measurement_sigma_nT)) +
            " nT, resamples " + std::to_string(c.resamples) + ", INS jumps " + std::to_string(c.ins_jumps) +
            ", lost steps " + std::to_string(c.lost_steps) + ", bias-test alarms " +
            std::to_string(c.bias_test_failures) +
            ", reinitialisations " + std::to_string(c.reinitialisations) +
            (kind == ParticleFilterKind::kPf ? ", tempered updates " + std::to_string(c.tempered_updates) : "");
  return r;
}

}  // namespace magnav::mapmatch
