#include "magnav/mapmatch/particle_filter.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <numbers>
#include <numeric>
#include <utility>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/option_check.h"
#include "match_common.h"

namespace magnav::mapmatch {

const char* ParticleFilterKindName(ParticleFilterKind kind) {
  return kind == ParticleFilterKind::kPf ? "pf" : "afpf";
}

bool ParticleFilterOptions::IsValid(std::string* error) const {
  if (num_particles < 1) return Fail(error, "num_particles must be >= 1");
  if (!PositiveFinite(measurement_sigma_nT)) return Fail(error, "measurement_sigma_nT must be finite and > 0");
  if (!(std::isfinite(drift_sigma_deg) && drift_sigma_deg >= 0.0)) {
    return Fail(error, "drift_sigma_deg must be finite and >= 0");
  }
  if (!PositiveFinite(prior_half_width_deg)) return Fail(error, "prior_half_width_deg must be finite and > 0");
  if (!(resample_ess_fraction >= 0.0 && resample_ess_fraction <= 1.0)) {
    return Fail(error, "resample_ess_fraction must be in [0, 1]");
  }
  if (!(outlier_sigmas == 0.0 || (std::isfinite(outlier_sigmas) && outlier_sigmas >= 2.0))) {
    return Fail(error, "outlier_sigmas must be 0 (off) or finite and >= 2");
  }
  if (max_consecutive_outliers < 0) return Fail(error, "max_consecutive_outliers must be >= 0");
  if (!(std::isfinite(off_map_sigmas) && off_map_sigmas >= 0.0)) {
    return Fail(error, "off_map_sigmas must be finite and >= 0");
  }
  if (!PositiveFinite(max_step_deg)) return Fail(error, "max_step_deg must be finite and > 0");
  if (divergence_window < 1) return Fail(error, "divergence_window must be >= 1");
  if (track_check_window < 0) return Fail(error, "track_check_window must be >= 0 (0 = off)");
  if (track_check_every < 1) return Fail(error, "track_check_every must be >= 1");
  if (!PositiveFinite(track_check_chi2)) return Fail(error, "track_check_chi2 must be finite and > 0");
  if (!PositiveFinite(track_check_step_deg)) return Fail(error, "track_check_step_deg must be finite and > 0");
  if (!PositiveFinite(divergence_nis)) return Fail(error, "divergence_nis must be finite and > 0");
  if (!(std::isfinite(min_measurement_sigma_nT) && min_measurement_sigma_nT > 0.0 &&
        min_measurement_sigma_nT <= measurement_sigma_nT)) {
    return Fail(error, "min_measurement_sigma_nT must be finite, > 0 and <= measurement_sigma_nT");
  }
  if (sigma_window < 1) return Fail(error, "sigma_window must be >= 1");
  if (!(std::isfinite(afpf_sigma_factor) && afpf_sigma_factor >= 0.0)) {
    return Fail(error, "afpf_sigma_factor must be finite and >= 0 (0 = a fixed sigma)");
  }
  if (!(std::isfinite(afpf_max_sigma_nT) && afpf_max_sigma_nT >= measurement_sigma_nT)) {
    return Fail(error, "afpf_max_sigma_nT must be finite and >= measurement_sigma_nT");
  }
  if (!(min_update_ess_fraction >= 0.0 && min_update_ess_fraction <= 1.0)) {
    return Fail(error, "min_update_ess_fraction must be in [0, 1]");
  }
  if (!(std::isfinite(regularization_bandwidth) && regularization_bandwidth >= 0.0)) {
    return Fail(error, "regularization_bandwidth must be finite and >= 0");
  }
  if (!PositiveFinite(fission_lambda)) return Fail(error, "fission_lambda must be finite and > 0");
  if (!PositiveFinite(fission_mu_deg2)) return Fail(error, "fission_mu_deg2 must be finite and > 0");
  if (max_particles < num_particles) return Fail(error, "max_particles must be >= num_particles");
  if (!PositiveFinite(particles_per_cell)) return Fail(error, "particles_per_cell must be finite and > 0");
  if (!(std::isfinite(bias_prior_sigma_nT) && bias_prior_sigma_nT >= 0.0)) {
    return Fail(error, "bias_prior_sigma_nT must be finite and >= 0");
  }
  if (!(std::isfinite(bias_drift_sigma_nT) && bias_drift_sigma_nT >= 0.0)) {
    return Fail(error, "bias_drift_sigma_nT must be finite and >= 0");
  }
  return true;
}

namespace {

class Filter final : public SequentialMatcher {
 public:
  Filter(ParticleFilterKind kind, const GeoGrid& grid, std::size_t layer, const ParticleFilterOptions& o)
      : kind_(kind), grid_(grid), layer_(layer), o_(o), rng_(o.seed) {
    if (layer >= grid.layer_names().size()) throw InputError(std::string(Name()) + ": layer index not in the map");
    std::string why;
    if (!o.IsValid(&why)) throw InputError(std::string(Name()) + " options: " + why);
    inv_two_var_ = 1.0 / (2.0 * o.measurement_sigma_nT * o.measurement_sigma_nT);
    off_map_loglik_ = -0.5 * o.off_map_sigmas * o.off_map_sigmas;
    adaptive_ = kind == ParticleFilterKind::kPf ? o.adaptive_sigma : o.afpf_sigma_factor > 0.0;
  }

  const StepDiagnostics& Step(double ins_lat, double ins_lon, double measured_nT) override {
    StepDiagnostics d;
    ++counters_.steps;
    if (!initialised_) {
      if (!std::isfinite(ins_lat) || !std::isfinite(ins_lon)) {
        throw InputError(std::string(Name()) + ": the first INS position is not finite");
      }
      SpreadPrior(ins_lat, ins_lon);
      prev_lat_ = ins_lat;
      prev_lon_ = ins_lon;
      initialised_ = true;
    } else {
      d.ins_jump = Predict(ins_lat, ins_lon);
    }
    Update(measured_nT, &d);
    Estimate(&d);
    if (o_.track_check_window > 0) CheckTrack(measured_nT, &d);
    if (kind_ == ParticleFilterKind::kAfpf) AdaptCount(d);
    d.particles = static_cast<int>(p_.size());
    d.unique_particles = std::min(d.unique_particles, d.particles);  // after the AFPF's trim
    if (d.lost) {
      ++counters_.lost_steps;
      if (o_.reinitialize_when_lost && std::isfinite(ins_lat) && std::isfinite(ins_lon)) {
        SpreadPrior(ins_lat, ins_lon);
        nis_window_.clear();
        innov_.clear();
        track_.clear();
        sigma_ = 0.0;  // starts again at measurement_sigma_nT
        ++counters_.reinitialisations;
      }
    }
    last_ = d;
    return last_;
  }

  const std::vector<Particle>& particles() const override { return p_; }
  const FilterCounters& counters() const override { return counters_; }
  const StepDiagnostics& last() const override { return last_; }
  ParticleFilterKind kind() const override { return kind_; }

 private:
  const char* Name() const { return ParticleFilterKindName(kind_); }

  // Log-likelihood of a measurement at a point (the off-map floor outside).
  double LogLik(double lat, double lon, double z, bool* on_map, double* residual = nullptr) const {
    const auto s = grid_.Sample(layer_, lat, lon);
    *on_map = s.has_value();
    if (!s) return off_map_loglik_;
    const double r = z - s->value_nT;
    if (residual != nullptr) *residual = r;
    return -r * r * inv_two_var_;
  }

  // The likelihood σ for this update (adaptive_sigma: from the innovations of
  // the last sigma_window updates, see the header).
  // AFPF (afpf_sigma_factor > 0): afpf_sigma_factor × that estimate in
  // [measurement_sigma_nT, afpf_max_sigma_nT], afpf_max_sigma_nT until the window is full.
  double CurrentSigma() const {
    const bool afpf = kind_ == ParticleFilterKind::kAfpf;
    const double hi = afpf && adaptive_ ? o_.afpf_max_sigma_nT : o_.measurement_sigma_nT;
    if (!adaptive_ || static_cast<int>(innov_.size()) < o_.sigma_window) return hi;
    double r2 = 0.0, spread = 0.0;
    for (const auto& [a, b] : innov_) r2 += a, spread += b;
    const double sd = std::sqrt(std::max((r2 - spread) / static_cast<double>(innov_.size()), 0.0));
    if (afpf) return std::clamp(o_.afpf_sigma_factor * sd, o_.measurement_sigma_nT, hi);
    return std::clamp(sd, o_.min_measurement_sigma_nT, hi);
  }

  void SpreadPrior(double lat, double lon) {
    const double h = o_.prior_half_width_deg;
    const double lat0 = std::max(lat - h, grid_.lat().first_deg), lat1 = std::min(lat + h, grid_.lat().last_deg());
    const double lon0 = std::max(lon - h, grid_.lon().first_deg), lon1 = std::min(lon + h, grid_.lon().last_deg());
    if (!(lat0 < lat1 && lon0 < lon1)) {
      throw InputError(std::string(Name()) + ": the prior square (±" + FormatNumber(h) + " deg around " +
                       FormatNumber(lat) + ", " + FormatNumber(lon) + ") does not overlap the map");
    }
    const int n = kind_ == ParticleFilterKind::kAfpf ? o_.max_particles : o_.num_particles;
    std::uniform_real_distribution<double> ulat(lat0, lat1), ulon(lon0, lon1);
    p_.assign(static_cast<std::size_t>(n), Particle{});
    logw_.assign(p_.size(), 0.0);
    for (Particle& q : p_) {
      q.lat_deg = ulat(rng_);
      q.lon_deg = ulon(rng_);
      q.weight = 1.0 / n;
    }
    if (o_.estimate_bias) {
      std::normal_distribution<double> b(0.0, o_.bias_prior_sigma_nT);
      for (Particle& q : p_) q.bias_nT = b(rng_);
    }
  }

  // Moves every particle by the INS increment plus drift noise; true if the
  // increment was a jump (not applied).
  bool Predict(double lat, double lon) {
    double dlat = lat - prev_lat_, dlon = lon - prev_lon_;
    bool jump = false;
    if (!std::isfinite(lat) || !std::isfinite(lon)) {
      jump = true;  // the last finite INS position stays the reference
    } else {
      jump = std::hypot(dlat, dlon) > o_.max_step_deg;
      prev_lat_ = lat;
      prev_lon_ = lon;
    }
    if (jump) {
      dlat = dlon = 0.0;
      ++counters_.ins_jumps;
    }
    std::normal_distribution<double> n(0.0, o_.drift_sigma_deg);
    for (Particle& q : p_) {
      q.lat_deg += dlat + n(rng_);
      q.lon_deg += dlon + n(rng_);
    }
    if (o_.estimate_bias) {
      std::normal_distribution<double> b(0.0, o_.bias_drift_sigma_nT);
      for (Particle& q : p_) q.bias_nT += b(rng_);
    }
    return jump;
  }

  void Normalise() {
    const double mx = *std::max_element(logw_.begin(), logw_.end());
    double sum = 0.0;
    for (std::size_t i = 0; i < p_.size(); ++i) {
      logw_[i] -= mx;
      p_[i].weight = std::exp(logw_[i]);
      sum += p_[i].weight;
    }
    const double lsum = std::log(sum);
    for (std::size_t i = 0; i < p_.size(); ++i) {
      p_[i].weight /= sum;
      logw_[i] -= lsum;
    }
  }

  void Update(double z, StepDiagnostics* d) {
    unique_ = static_cast<int>(p_.size());
    if (!std::isfinite(z)) {
      d->update = StepUpdate::kBadMeasurement;
      ++counters_.bad_measurements;
      d->ess = Ess();
      d->lost = Lost();
      return;
    }
    const std::size_t n = p_.size();
    loglik_.resize(n);
    bool any_on = false;
    double evidence = 0.0;  // Σ w_(k−1) p(z|x)
    // σ rises at once (the safe side) but falls by at most a factor
    // (1 − 1/sigma_window) per update: the cloud's spread V lags σ, and a
    // sudden small σ collapses a cloud that has not yet tightened.
    const double prev_sigma = sigma_ > 0.0                                       ? sigma_
                              : kind_ == ParticleFilterKind::kAfpf && adaptive_ ? o_.afpf_max_sigma_nT
                                                                                : o_.measurement_sigma_nT;
    sigma_ = std::max(CurrentSigma(), prev_sigma * (1.0 - 1.0 / o_.sigma_window));
    inv_two_var_ = 1.0 / (2.0 * sigma_ * sigma_);
    d->sigma_nT = sigma_;
    double w_on = 0.0, r1 = 0.0, r2 = 0.0;  // predicted residual moments over the particles on the map
    for (std::size_t i = 0; i < n; ++i) {
      bool on = false;
      double r = 0.0;
      loglik_[i] = LogLik(p_[i].lat_deg, p_[i].lon_deg, z - p_[i].bias_nT, &on, &r);
      any_on = any_on || on;
      evidence += p_[i].weight * std::exp(loglik_[i]);
      if (on) w_on += p_[i].weight, r1 += p_[i].weight * r, r2 += p_[i].weight * r * r;
    }
    // The outlier gate (see outlier_sigmas): a reading no particle's prediction explains is skipped.
    if (o_.outlier_sigmas > 0.0 && w_on > 0.5 && consecutive_outliers_ < o_.max_consecutive_outliers) {
      const double mean = r1 / w_on, spread = std::max(r2 / w_on - mean * mean, 0.0);
      if (mean * mean > o_.outlier_sigmas * o_.outlier_sigmas * (sigma_ * sigma_ + spread)) {
        d->update = StepUpdate::kOutlier;
        ++counters_.outliers;
        ++consecutive_outliers_;
        // The divergence rule still hears of it, as a residual of outlier_sigmas: one spike
        // cannot make the filter lost (25 against a mean of 9 over 10 updates), a run of
        // "outliers" (a lost filter, not a spike) does within 4 steps.
        d->nis = evidence > 0.0 ? -2.0 * std::log(evidence) : std::numeric_limits<double>::infinity();
        nis_window_.push_back(std::min(d->nis, o_.outlier_sigmas * o_.outlier_sigmas));
        if (static_cast<int>(nis_window_.size()) > o_.divergence_window) nis_window_.pop_front();
        d->ess = Ess();
        d->lost = Lost();
        return;
      }
    }
    consecutive_outliers_ = 0;
    if (adaptive_ && w_on > 0.5) {
      // (mean residual)² and the cloud's spread of predicted map values:
      // E[(z − m̄)²] = σ² + Var(m) for a consistent filter.
      const double mean = r1 / w_on, spread = std::max(r2 / w_on - mean * mean, 0.0);
      // (the AFPF: compact against its largest σ, since its own σ starts there)
      const double compact = kind_ == ParticleFilterKind::kAfpf ? o_.afpf_max_sigma_nT : o_.measurement_sigma_nT;
      if (spread <= compact * compact) {
        innov_.emplace_back(mean * mean, spread);
        if (static_cast<int>(innov_.size()) > o_.sigma_window) innov_.pop_front();
      } else {
        innov_.clear();  // a spread (acquiring, multimodal) cloud: its mean residual says nothing of σ
      }
    }
    if (!any_on) {
      d->update = StepUpdate::kAllOffMap;
      ++counters_.all_off_map;
      d->ess = Ess();
      d->lost = Lost();
      return;
    }
    ++counters_.updates;
    d->nis = evidence > 0.0 ? -2.0 * std::log(evidence) : std::numeric_limits<double>::infinity();
    nis_window_.push_back(d->nis);
    if (static_cast<int>(nis_window_.size()) > o_.divergence_window) nis_window_.pop_front();
    double beta = 1.0;
    const double floor_ess = o_.min_update_ess_fraction * static_cast<double>(n);
    if (kind_ == ParticleFilterKind::kPf && floor_ess > 0.0 && EssWith(1.0) < floor_ess) {
      // Tempered update (see the header): the largest β with ESS(β) ≥ the floor, by bisection.
      double lo = 0.0, hi = 1.0;
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (lo + hi);
        (EssWith(mid) >= floor_ess ? lo : hi) = mid;
      }
      beta = lo;
      ++counters_.tempered_updates;
    }
    d->likelihood_exponent = beta;
    for (std::size_t i = 0; i < n; ++i) logw_[i] += beta * loglik_[i];
    Normalise();
    d->ess = Ess();
    if (kind_ == ParticleFilterKind::kPf) {
      if (d->ess < o_.resample_ess_fraction * static_cast<double>(n)) {
        Resample();
        if (o_.regularization_bandwidth > 0.0) Regularise();
        d->resampled = true;
        ++counters_.resamples;
      }
    } else {
      Fission(z);
    }
    d->lost = Lost();
  }

  // ESS of the weights w_i ∝ exp(logw_i + β loglik_i) (before they are applied).
  double EssWith(double beta) const {
    double mx = -std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < p_.size(); ++i) mx = std::max(mx, logw_[i] + beta * loglik_[i]);
    double s1 = 0.0, s2 = 0.0;
    for (std::size_t i = 0; i < p_.size(); ++i) {
      const double w = std::exp(logw_[i] + beta * loglik_[i] - mx);
      s1 += w, s2 += w * w;
    }
    return s2 > 0.0 ? s1 * s1 / s2 : 0.0;
  }

  double Ess() const {
    double s = 0.0;
    for (const Particle& q : p_) s += q.weight * q.weight;
    return s > 0.0 ? 1.0 / s : 0.0;
  }

  bool Lost() const {
    if (static_cast<int>(nis_window_.size()) < o_.divergence_window) return false;
    const double mean = std::accumulate(nis_window_.begin(), nis_window_.end(), 0.0) / nis_window_.size();
    return mean > o_.divergence_nis;
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
  void CheckTrack(double z, StepDiagnostics* d) {
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

  // Systematic resampling: one uniform offset, N evenly spaced pointers.
  void Resample() {
    const std::size_t n = p_.size();
    const double step = 1.0 / static_cast<double>(n);
    std::uniform_real_distribution<double> u(0.0, step);
    double pointer = u(rng_), cum = p_[0].weight;
    std::vector<Particle> out(n);
    std::size_t j = 0;
    int unique = 0;
    std::size_t last_j = n;
    for (std::size_t i = 0; i < n; ++i) {
      while (pointer > cum && j + 1 < n) cum += p_[++j].weight;
      out[i] = p_[j];
      out[i].weight = step;
      if (j != last_j) ++unique, last_j = j;
      pointer += step;
    }
    p_.swap(out);
    std::fill(logw_.begin(), logw_.end(), std::log(step));
    unique_ = unique;
  }

  // Regularised PF (Musso, Oudjane & Le Gland 2001): after resampling every
  // particle moves by h·L·ε, ε ~ N(0, I₂), L Lᵀ = the cloud's covariance
  // (now equal-weighted, i.e. that of the weighted cloud before resampling),
  // h = bandwidth · h_opt, h_opt = (4 / ((d + 2) N))^(1/(d + 4)) = N^(−1/6) for
  // d = 2 (the Gaussian kernel's optimal width for a Gaussian density). The
  // copies that resampling made become distinct, near where the evidence put
  // them; the cloud's variance grows by h² (≈ 7 % at N = 3000).
  void Regularise() {
    const std::size_t n = p_.size();
    double mlat = 0.0, mlon = 0.0;
    for (const Particle& q : p_) mlat += q.lat_deg, mlon += q.lon_deg;
    mlat /= static_cast<double>(n);
    mlon /= static_cast<double>(n);
    double a = 0.0, b = 0.0, c = 0.0;
    for (const Particle& q : p_) {
      const double x = q.lat_deg - mlat, y = q.lon_deg - mlon;
      a += x * x, b += x * y, c += y * y;
    }
    a /= static_cast<double>(n), b /= static_cast<double>(n), c /= static_cast<double>(n);
    // Cholesky of [[a, b], [b, c]] (a degenerate cloud gets no jitter along its null direction).
    const double l11 = std::sqrt(std::max(a, 0.0));
    const double l21 = l11 > 0.0 ? b / l11 : 0.0;
    const double l22 = std::sqrt(std::max(c - l21 * l21, 0.0));
    const double h = o_.regularization_bandwidth * std::pow(static_cast<double>(n), -1.0 / 6.0);
    std::normal_distribution<double> unit(0.0, 1.0);
    for (Particle& q : p_) {
      const double e1 = unit(rng_), e2 = unit(rng_);
      q.lat_deg += h * l11 * e1;
      q.lon_deg += h * (l21 * e1 + l22 * e2);
    }
    unique_ = static_cast<int>(n);
  }

  // The paper's fission, pooling and selection of the heaviest current-count particles.
  void Fission(double z) {
    const std::size_t n = p_.size();
    double w_max = 0.0;
    for (const Particle& q : p_) w_max = std::max(w_max, q.weight);
    const double w_avg = 1.0 / static_cast<double>(n);
    const double spread = w_max - w_avg;
    pool_.assign(p_.begin(), p_.end());
    pool_logw_.assign(logw_.begin(), logw_.end());
    std::normal_distribution<double> unit(0.0, 1.0);
    const double penalty = o_.fission_motion_penalty && o_.drift_sigma_deg > 0.0
                               ? 0.5 / (o_.drift_sigma_deg * o_.drift_sigma_deg)
                               : 0.0;
    std::normal_distribution<double> bias_spread(0.0, o_.bias_drift_sigma_nT);
    for (std::size_t i = 0; i < n; ++i) {
      const double wi = p_[i].weight;
      const double a = spread > 1e-15 * w_avg ? 1.0 / (1.0 + std::exp((wi - w_avg) / spread)) : 0.5;
      const double sd = std::sqrt(o_.fission_lambda * o_.fission_mu_deg2 * a);
      const long m = std::lround(static_cast<double>(n) * wi) + 2;
      for (long j = 0; j < m; ++j) {
        Particle c;
        c.lat_deg = p_[i].lat_deg + sd * unit(rng_);
        c.lon_deg = p_[i].lon_deg + sd * unit(rng_);
        c.bias_nT = p_[i].bias_nT + (o_.estimate_bias ? bias_spread(rng_) : 0.0);
        bool on = false;
        // The parent's prior weight times the offspring's likelihood, with the
        // parents' normaliser: logw_i − loglik_i + loglik(offspring).
        double lw = logw_[i] - loglik_[i] + LogLik(c.lat_deg, c.lon_deg, z - c.bias_nT, &on);
        if (penalty > 0.0) {
          const double dl = c.lat_deg - p_[i].lat_deg, dn = c.lon_deg - p_[i].lon_deg;
          lw -= penalty * (dl * dl + dn * dn);
        }
        pool_logw_.push_back(lw);
        pool_.push_back(c);
      }
    }
    KeepHeaviest(n);
  }

  // Keeps the `n` heaviest of pool_ (descending weight) in p_, renormalised.
  void KeepHeaviest(std::size_t n) {
    order_.resize(pool_.size());
    std::iota(order_.begin(), order_.end(), std::size_t{0});
    auto heavier = [this](std::size_t a, std::size_t b) {
      return pool_logw_[a] > pool_logw_[b] || (pool_logw_[a] == pool_logw_[b] && a < b);
    };
    n = std::min(n, order_.size());
    std::nth_element(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(n), order_.end(), heavier);
    std::sort(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(n), heavier);
    p_.resize(n);
    logw_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      p_[i] = pool_[order_[i]];
      logw_[i] = pool_logw_[order_[i]];
    }
    Normalise();
    unique_ = static_cast<int>(n);
  }

  void Estimate(StepDiagnostics* d) {
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

  // The AFPF's count for the next step from this step's spread (occupied map
  // cells); trims the lightest particles (p_ is sorted heaviest first after
  // KeepHeaviest).
  void AdaptCount(const StepDiagnostics& d) {
    const double want = std::ceil(o_.particles_per_cell * d.occupied_cells);
    const std::size_t n = static_cast<std::size_t>(
        std::clamp(want, static_cast<double>(o_.num_particles), static_cast<double>(o_.max_particles)));
    if (n >= p_.size() || d.update != StepUpdate::kUpdated) return;
    p_.resize(n);
    logw_.resize(n);
    Normalise();
  }

  ParticleFilterKind kind_;
  const GeoGrid& grid_;
  std::size_t layer_;
  ParticleFilterOptions o_;
  std::mt19937_64 rng_;
  double inv_two_var_ = 0.0, off_map_loglik_ = 0.0;
  bool initialised_ = false;
  int consecutive_outliers_ = 0;  // readings skipped in a row by the outlier gate
  double prev_lat_ = 0.0, prev_lon_ = 0.0;
  std::vector<Particle> p_;
  std::vector<double> logw_, loglik_;
  std::vector<Particle> pool_;
  std::vector<double> pool_logw_;
  std::vector<std::size_t> order_;
  std::vector<long long> cells_;
  std::deque<double> nis_window_;
  std::deque<std::array<double, 3>> track_;  // track check: (estimate lat, lon, reading) per update
  int since_check_ = 0;
  std::deque<std::pair<double, double>> innov_;  // adaptive σ: (z − m̄)², Var(m) per update
  double sigma_ = 0.0;
  bool adaptive_ = false;  // PF: adaptive_sigma; AFPF: afpf_sigma_factor > 0
  int unique_ = 0;
  FilterCounters counters_;
  StepDiagnostics last_;
};

}  // namespace

std::unique_ptr<SequentialMatcher> MakeParticleFilter(ParticleFilterKind kind, const GeoGrid& grid,
                                                      std::size_t layer, const ParticleFilterOptions& options) {
  return std::make_unique<Filter>(kind, grid, layer, options);
}

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
    r.reason = "lost (mean NIS over the last " + std::to_string(options.divergence_window) + " updates > " +
               FormatNumber(options.divergence_nis) +
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
            ", lost steps " + std::to_string(c.lost_steps) +
            ", reinitialisations " + std::to_string(c.reinitialisations) +
            (kind == ParticleFilterKind::kPf ? ", tempered updates " + std::to_string(c.tempered_updates) : "");
  return r;
}

}  // namespace magnav::mapmatch
