#include "quiet_offset.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace magnav::tracker::internal {

namespace {

double Median(std::vector<double>* v) {
  const std::size_t n = v->size();
  std::nth_element(v->begin(), v->begin() + n / 2, v->end());
  const double hi = (*v)[n / 2];
  if (n % 2 == 1) return hi;
  return 0.5 * (hi + *std::max_element(v->begin(), v->begin() + n / 2));
}

}  // namespace

void QuietOffsets::Add(std::uint32_t sensor_id, double t_s, const Eigen::Vector3d& r_W) {
  if (!r_W.allFinite() || !std::isfinite(t_s)) return;
  std::deque<Item>& d = sensors_[sensor_id];
  d.push_back({t_s, r_W});
  while (!d.empty() && t_s - d.front().t_s > options_.quiet_span_s + 1e-9) d.pop_front();
}

bool QuietOffsets::Prior(std::uint32_t sensor_id, double t_s, Eigen::Vector3d* mean_W, double* sigma_T) const {
  const auto it = sensors_.find(sensor_id);
  if (it == sensors_.end() || static_cast<int>(it->second.size()) < options_.quiet_min_samples) return false;
  const std::deque<Item>& d = it->second;
  const std::size_t n = d.size();
  std::vector<double> v(n);
  double spread = 0.0;
  for (int k = 0; k < 3; ++k) {
    for (std::size_t i = 0; i < n; ++i) v[i] = d[i].r_W(k);
    const double med = Median(&v);
    (*mean_W)(k) = med;
    for (std::size_t i = 0; i < n; ++i) v[i] = std::abs(d[i].r_W(k) - med);
    spread = std::max(spread, 1.4826 * Median(&v));
  }
  // The median's σ (1.2533 × the mean's for Gaussian samples), at the
  // samples' median time; then the drift bound's walk to t_s.
  const double t_mid = d[n / 2].t_s;
  const double sigma_median = 1.2533 * spread / std::sqrt(static_cast<double>(n));
  const double walk = options_.max_rate_T_per_s * std::abs(t_s - t_mid);
  *sigma_T = std::max(std::hypot(sigma_median, walk), 1e-12);
  return true;
}

int QuietOffsets::num_quiet(std::uint32_t sensor_id) const {
  const auto it = sensors_.find(sensor_id);
  return it == sensors_.end() ? 0 : static_cast<int>(it->second.size());
}

}  // namespace magnav::tracker::internal
