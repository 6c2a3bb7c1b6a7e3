#include "magnav/mapmatch/observability.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

#include <Eigen/Dense>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"

namespace magnav::mapmatch {
namespace {

Eigen::Matrix2d ToMatrix(const Cov2& c) {
  Eigen::Matrix2d m;
  m << c.lat_lat, c.lat_lon, c.lat_lon, c.lon_lon;
  return m;
}

Cov2 ToCov(const Eigen::Matrix2d& m) {
  return {m(0, 0), 0.5 * (m(0, 1) + m(1, 0)), m(1, 1)};
}

Eigen::Matrix2d Symmetric(const Eigen::Matrix2d& m) { return 0.5 * (m + m.transpose()); }

// Inverse of a symmetric positive semi-definite 2×2 (pseudo-inverse when singular).
Eigen::Matrix2d PseudoInverse(const Eigen::Matrix2d& m) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(Symmetric(m));
  const Eigen::Vector2d v = es.eigenvalues();
  const double tol = 1e-14 * std::max(std::abs(v(1)), 1e-300);
  Eigen::Vector2d inv;
  for (int i = 0; i < 2; ++i) inv(i) = v(i) > tol ? 1.0 / v(i) : 0.0;
  return es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
}

bool FiniteNonNegative(double v) { return std::isfinite(v) && v >= 0.0; }

std::string Significant(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

}  // namespace

bool InsErrorPrior::IsValid(std::string* error) const {
  if (!FiniteNonNegative(start_sd_deg) || !FiniteNonNegative(drift_sd_deg) || start_sd_deg > kMaxSdDeg ||
      drift_sd_deg > kMaxSdDeg) {
    if (error) *error = "INS error prior: start_sd_deg and drift_sd_deg must be in [0, 90] deg";
    return false;
  }
  return true;
}

bool ObservabilityOptions::IsValid(std::string* error) const {
  if (!prior.IsValid(error)) return false;
  if (!FiniteNonNegative(min_information_ratio)) {
    if (error) *error = "observability: min_information_ratio must be finite and >= 0";
    return false;
  }
  if (!(std::isfinite(min_noise_sd_nT) && min_noise_sd_nT > 0.0)) {
    if (error) *error = "observability: min_noise_sd_nT must be finite and > 0";
    return false;
  }
  return true;
}

double PathObservability::weak_bearing_deg() const {
  double b = std::atan2(weak_lon, weak_lat) * 180.0 / std::numbers::pi;
  b = std::fmod(b + 360.0, 180.0);
  return b >= 180.0 ? 0.0 : b;
}

std::string PathObservability::Summary() const {
  if (!valid) return "map information at the path's end: not computed (no prior variance)";
  return "map information at the path's end: along the least observed direction (bearing " +
         FormatNumber(std::round(weak_bearing_deg() * 10.0) / 10.0) + " deg) " + Significant(ratio_weak()) +
         " of the prior's, across it " + Significant(ratio_strong()) + " of the prior's (sigma " +
         Significant(noise_sd_nT) + " nT, " + std::to_string(points) + " points)";
}

double MatchedResidualRms(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                          const std::vector<double>& lat_deg, const std::vector<double>& lon_deg) {
  double ss = 0.0;
  int n = 0;
  for (std::size_t p = 0; p < path.size(); ++p) {
    if (!std::isfinite(path.measured_nT[p])) continue;
    const auto s = grid.Sample(layer, lat_deg[p], lon_deg[p]);
    if (!s) continue;
    const double r = s->value_nT - path.measured_nT[p];
    ss += r * r;
    ++n;
  }
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  return std::sqrt(ss / std::max(n - 2, 1));
}

double MapInformation::weak_bearing_deg() const {
  double b = std::atan2(weak_lon, weak_lat) * 180.0 / std::numbers::pi;
  b = std::fmod(b + 360.0, 180.0);
  return b >= 180.0 ? 0.0 : b;
}

ObservabilityFilter::ObservabilityFilter(const InsErrorPrior& prior) : prior_(prior) {
  prior_var_ = prior.start_sd_deg * prior.start_sd_deg;
  p_ = {prior_var_, 0.0, prior_var_};
}

void ObservabilityFilter::Predict() {
  const double q = prior_.drift_sd_deg * prior_.drift_sd_deg;
  prior_var_ += q;
  p_.lat_lat += q;
  p_.lon_lon += q;
}

void ObservabilityFilter::Update(double dvalue_dlat_nT_per_deg, double dvalue_dlon_nT_per_deg, double sigma_nT) {
  const Eigen::Vector2d g(dvalue_dlat_nT_per_deg, dvalue_dlon_nT_per_deg);
  const Eigen::Matrix2d p = ToMatrix(p_);
  const Eigen::Vector2d pg = p * g;
  const double innov = g.dot(pg) + sigma_nT * sigma_nT;
  if (!(innov > 0.0) || !std::isfinite(innov)) return;
  p_ = ToCov(Symmetric(p - pg * pg.transpose() / innov));
  ++updates_;
}

MapInformation ObservabilityFilter::Information() const {
  MapInformation m;
  if (!(prior_var_ > 0.0)) return m;
  m.prior_info = 1.0 / prior_var_;
  const Eigen::Matrix2d info = Symmetric(PseudoInverse(ToMatrix(p_)) - m.prior_info * Eigen::Matrix2d::Identity());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(info);
  m.map_info_weak = std::max(es.eigenvalues()(0), 0.0);
  m.map_info_strong = std::max(es.eigenvalues()(1), 0.0);
  m.weak_lat = es.eigenvectors()(0, 0);
  m.weak_lon = es.eigenvectors()(1, 0);
  m.valid = true;
  return m;
}

StepObservability::StepObservability(const GeoGrid& grid, std::size_t layer, const InsErrorPrior& prior,
                                     const ObservabilityOptions& options)
    : grid_(grid), layer_(layer), options_(options), filter_(prior) {
  std::string error;
  if (!options.IsValid(&error)) throw InputError(error);
  if (!prior.IsValid(&error)) throw InputError(error);
}

double StepObservability::noise_sd_nT() const {
  if (residuals_ == 0) return options_.min_noise_sd_nT;
  const double rms = std::sqrt(residual_ss_ / std::max(residuals_ - 2, 1));
  return rms >= options_.min_noise_sd_nT ? rms : options_.min_noise_sd_nT;
}

void StepObservability::Step(double lat_deg, double lon_deg, double measured_nT) {
  if (started_) filter_.Predict();
  started_ = true;
  if (!std::isfinite(measured_nT) || !std::isfinite(lat_deg) || !std::isfinite(lon_deg)) return;
  const auto s = grid_.Sample(layer_, lat_deg, lon_deg);
  if (!s) return;
  const double r = s->value_nT - measured_nT;
  residual_ss_ += r * r;
  ++residuals_;
  filter_.Update(s->dvalue_dlat_nT_per_deg, s->dvalue_dlon_nT_per_deg, noise_sd_nT());
}

bool StepObservability::partly_observable() const {
  const MapInformation m = filter_.Information();
  return m.valid && m.ratio_weak() < options_.min_information_ratio;
}

bool StepObservability::Floor(Cov2* c) const {
  return partly_observable() && FloorAlongLeastKnown(filter_.covariance(), c);
}

PathObservability ObservePath(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                              const std::vector<double>& lat_deg, const std::vector<double>& lon_deg,
                              const InsErrorPrior& prior, double noise_sd_nT) {
  PathObservability o;
  const std::size_t n = path.size();
  const double s0 = prior.start_sd_deg * prior.start_sd_deg;
  const double q = prior.drift_sd_deg * prior.drift_sd_deg;
  const double prior_end = s0 + q * static_cast<double>(n > 0 ? n - 1 : 0);
  o.noise_sd_nT = noise_sd_nT;
  if (n == 0 || !(prior_end > 0.0) || !(noise_sd_nT > 0.0)) return o;
  std::vector<Eigen::Matrix2d> pred(n), filt(n);
  ObservabilityFilter f(prior);
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) f.Predict();
    pred[i] = ToMatrix(f.covariance());
    if (std::isfinite(path.measured_nT[i])) {
      if (const auto s = grid.Sample(layer, lat_deg[i], lon_deg[i])) {
        f.Update(s->dvalue_dlat_nT_per_deg, s->dvalue_dlon_nT_per_deg, noise_sd_nT);
        ++o.points;
      }
    }
    filt[i] = ToMatrix(f.covariance());
  }
  // Rauch–Tung–Striebel: P_s,i = P_i + C (P_s,i+1 − P_pred,i+1) Cᵀ, C = P_i P_pred,i+1⁻¹.
  std::vector<Eigen::Matrix2d> smooth(n);
  smooth[n - 1] = filt[n - 1];
  for (std::size_t i = n - 1; i-- > 0;) {
    const Eigen::Matrix2d c = filt[i] * PseudoInverse(pred[i + 1]);
    smooth[i] = Symmetric(filt[i] + c * (smooth[i + 1] - pred[i + 1]) * c.transpose());
  }
  o.filtered.resize(n);
  o.smoothed.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    o.filtered[i] = ToCov(filt[i]);
    o.smoothed[i] = ToCov(smooth[i]);
  }
  // The map's information at the end: the posterior's less the prior's.
  const MapInformation m = f.Information();
  o.prior_info = m.prior_info;
  o.map_info_weak = m.map_info_weak;
  o.map_info_strong = m.map_info_strong;
  o.weak_lat = m.weak_lat;
  o.weak_lon = m.weak_lon;
  o.valid = true;
  return o;
}

bool FloorAlongLeastKnown(const Cov2& floor, Cov2* c) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(ToMatrix(floor));
  const Eigen::Vector2d e = es.eigenvectors().col(1);  // largest eigenvalue: least known
  const double target = es.eigenvalues()(1);
  const Eigen::Matrix2d m = ToMatrix(*c);
  const double have = e.dot(m * e);
  if (!(target > have)) return false;
  *c = ToCov(m + (target - have) * e * e.transpose());
  return true;
}

}  // namespace magnav::mapmatch
