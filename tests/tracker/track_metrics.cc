#include "track_metrics.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>

#include <gtest/gtest.h>

namespace magnav::testing {
namespace {

double IntegratedAutocorrelationTime(const std::vector<double>& x) {
  const std::size_t n = x.size();
  if (n < 2) return 1.0;
  double mean = 0.0;
  for (double v : x) mean += v / static_cast<double>(n);
  auto cov = [&](std::size_t lag) {
    double c = 0.0;
    for (std::size_t i = 0; i + lag < n; ++i) c += (x[i] - mean) * (x[i + lag] - mean);
    return c / static_cast<double>(n);
  };
  const double c0 = cov(0);
  if (!(c0 > 0.0)) return 1.0;
  double tau = 1.0;
  for (std::size_t lag = 1; lag < n / 2; ++lag) {
    const double rho = cov(lag) / c0;
    if (rho <= 0.0) break;
    tau += 2.0 * rho;
  }
  return tau;
}

// Chi-square quantile by the Wilson–Hilferty approximation (relative error
// < 1 % for k ≥ 10 at these z), z the standard-normal quantile.
double ChiSquareQuantile(double k, double z) {
  const double a = 2.0 / (9.0 * k);
  return k * std::pow(1.0 - a + z * std::sqrt(a), 3);
}

}  // namespace

TrackMetrics ScoreTrack(const std::vector<tracker::EpochEstimate>& est,
                        const std::vector<GradiometerSample>& samples, const TruthTrack& truth) {
  std::vector<Eigen::Vector3d> sensors;
  for (const auto& s : samples) {
    if (std::none_of(sensors.begin(), sensors.end(), [&](const Eigen::Vector3d& p) { return p == s.p_SinW; })) {
      sensors.push_back(s.p_SinW);
    }
  }
  TrackMetrics m;
  double se = 0.0, nees = 0.0;
  std::vector<double> per_epoch;
  for (const auto& e : est) {
    const auto it = std::lower_bound(truth.t.begin(), truth.t.end(), e.t_s - 1e-6);
    if (it == truth.t.end() || std::abs(*it - e.t_s) > 1e-6) continue;
    const Eigen::Vector3d& p = truth.p[static_cast<std::size_t>(it - truth.t.begin())];
    double range = 1e300;
    for (const auto& s : sensors) range = std::min(range, (p - s).head<2>().norm());
    if (range > kEvalRangeM) continue;
    const Eigen::Vector3d d = e.p_VinW - p;
    se += d.squaredNorm();
    m.max = std::max(m.max, d.norm());
    const double q =
        e.has_covariance ? d.dot(e.cov_p_W().ldlt().solve(d)) : std::numeric_limits<double>::infinity();
    nees += q;
    per_epoch.push_back(q);
    ++m.n;
  }
  m.rms = std::sqrt(se / m.n);
  m.nees = nees / m.n;
  m.nees_tau = IntegratedAutocorrelationTime(per_epoch);
  return m;
}

double NeesUpperBound(const TrackMetrics& m) {
  const double n_eff = m.n / std::max(1.0, m.nees_tau);
  return ChiSquareQuantile(3.0 * n_eff, 2.576) / n_eff;
}

void ExpectHonestNees(const TrackMetrics& m, double documented, const std::string& what) {
  const double hi = NeesUpperBound(m);
  std::cout << what << ": NEES " << m.nees << ", n_eff " << m.n / std::max(1.0, m.nees_tau)
            << ", chi-square bound " << hi << "\n";
  // Errors correlated over more than 15 s would make the bound meaningless.
  EXPECT_LE(m.nees_tau, 150.0) << what;
  EXPECT_LE(m.nees, hi) << what << ": covariance overconfident";
  ExpectErrorFigure(m.nees, documented, what + " NEES");
  ExpectCountFigure(m.nees, documented, what + " NEES");
}

}  // namespace magnav::testing
