#include "magnav/tracker/variance_factor.h"

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <map>

#include "magnav/core/nees.h"

namespace magnav::tracker {

namespace {
bool Fail(std::string* error, const char* why) {
  if (error != nullptr) *error = why;
  return false;
}
// Residuals per gradiometer sample in the window's measurement factor
// (MeasurementCost: B, 3, and the trace-free tensor, 5).
constexpr double kResidualsPerSample = 8.0;
}  // namespace

bool VarianceFactorOptions::IsValid(std::string* error) const {
  if (!(quantile > 0.0 && quantile < 1.0)) return Fail(error, "variance_factor.quantile must be in (0, 1)");
  if (!(max_factor >= 1.0 && std::isfinite(max_factor))) return Fail(error, "variance_factor.max_factor must be >= 1");
  return true;
}

double VarianceFactor(double chi2, double dof, const VarianceFactorOptions& options) {
  if (!options.enabled || !(dof > 0.0) || !std::isfinite(chi2) || !std::isfinite(dof)) return 1.0;
  const double s2 = chi2 / dof;
  const double bound = ChiSquareQuantile(options.quantile, dof) / dof;
  if (!(s2 > bound)) return 1.0;
  return std::min(std::max(s2, 1.0), options.max_factor);
}

double WindowVarianceFactor(const Summary& summary, const VarianceFactorOptions& options) {
  if (!summary.usable) return 1.0;
  return VarianceFactor(2.0 * summary.final_cost, kResidualsPerSample * summary.num_samples, options);
}

double WindowVarianceFactor(const WindowTracker& window, const VarianceFactorOptions& options) {
  if (!options.enabled) return 1.0;
  if (options.statistic == VarianceFactorOptions::Statistic::kResiduals) {
    return WindowVarianceFactor(window.last_summary(), options);
  }
  double chi2 = 0.0, dof = 0.0;
  window.ResidualMeansChi2(&chi2, &dof);
  return VarianceFactor(chi2, dof, options);
}

std::vector<double> SlidingVarianceFactors(const std::vector<WhitenedResidual>& residuals,
                                           const std::vector<double>& times_s, double span_s, double clip_sigma,
                                           const VarianceFactorOptions& options, double* pass_factor) {
  std::vector<double> factors(times_s.size(), 1.0);
  if (pass_factor != nullptr) *pass_factor = 1.0;
  if (!options.enabled || times_s.empty() || !(span_s > 0.0)) return factors;
  using Vec8 = Eigen::Matrix<double, 8, 1>;
  const bool means = options.statistic == VarianceFactorOptions::Statistic::kSensorMeans;
  // Per sensor, its residuals' times and prefix sums (clipped e, or clipped
  // ‖e‖² for kResiduals) in time order.
  struct Series {
    std::vector<double> t;
    std::vector<Vec8> sum{Vec8::Zero()};
    std::vector<double> sq{0.0};
  };
  std::map<std::uint32_t, Series> series;
  std::vector<const WhitenedResidual*> ordered;
  for (const WhitenedResidual& r : residuals) {
    if (r.e.allFinite() && std::isfinite(r.t_s)) ordered.push_back(&r);
  }
  std::stable_sort(ordered.begin(), ordered.end(),
                   [](const WhitenedResidual* a, const WhitenedResidual* b) { return a->t_s < b->t_s; });
  double chi2_all = 0.0, dof_all = 0.0;
  for (const WhitenedResidual* r : ordered) {
    Series& s = series[r->sensor_id];
    const double n = r->e.norm();
    const Vec8 e = n > clip_sigma ? Vec8(r->e * (clip_sigma / n)) : r->e;
    s.t.push_back(r->t_s);
    s.sum.push_back(s.sum.back() + e);
    s.sq.push_back(s.sq.back() + e.squaredNorm());
  }
  for (const auto& [id, s] : series) {
    const double n = static_cast<double>(s.t.size());
    chi2_all += means ? s.sum.back().squaredNorm() / n : s.sq.back();
    dof_all += means ? kResidualsPerSample : kResidualsPerSample * n;
  }
  for (std::size_t k = 0; k < times_s.size(); ++k) {
    double chi2 = 0.0, dof = 0.0;
    for (const auto& [id, s] : series) {
      const auto a = static_cast<std::size_t>(
          std::lower_bound(s.t.begin(), s.t.end(), times_s[k] - 0.5 * span_s) - s.t.begin());
      const auto b = static_cast<std::size_t>(
          std::upper_bound(s.t.begin(), s.t.end(), times_s[k] + 0.5 * span_s) - s.t.begin());
      if (b <= a) continue;
      const double n = static_cast<double>(b - a);
      chi2 += means ? (s.sum[b] - s.sum[a]).squaredNorm() / n : s.sq[b] - s.sq[a];
      dof += means ? kResidualsPerSample : kResidualsPerSample * n;
    }
    factors[k] = VarianceFactor(chi2, dof, options);
  }
  if (pass_factor != nullptr) *pass_factor = VarianceFactor(chi2_all, dof_all, options);
  return factors;
}

void ScaleCovariance(double factor, EpochEstimate* estimate) {
  if (estimate->has_covariance) estimate->cov_state *= factor;
}

}  // namespace magnav::tracker
