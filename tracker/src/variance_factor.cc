#include "magnav/tracker/variance_factor.h"

#include <algorithm>
#include <cmath>

#include <boost/math/distributions/chi_squared.hpp>

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
  const double bound = boost::math::quantile(boost::math::chi_squared(dof), options.quantile) / dof;
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

void ScaleCovariance(double factor, EpochEstimate* estimate) {
  if (estimate->has_covariance) estimate->cov_state *= factor;
}

}  // namespace magnav::tracker
