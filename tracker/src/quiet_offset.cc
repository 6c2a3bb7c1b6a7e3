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

// The median's σ relative to the mean's for Gaussian samples, and the MAD's
// scale to σ.
constexpr double kMedianEfficiency = 1.2533;
constexpr double kMadToSigma = 1.4826;

}  // namespace

double QuietOffsets::SpanS() const {
  return options_.quiet_rate ? std::max(options_.quiet_span_s, options_.quiet_rate_span_s) : options_.quiet_span_s;
}

void QuietOffsets::Add(std::uint32_t sensor_id, double t_s, const Eigen::Vector3d& r_W, const Eigen::Vector3d& p_SinW,
                       double sigma_B_T, double sigma_T_Tpm) {
  if (!r_W.allFinite() || !std::isfinite(t_s)) return;
  std::deque<Item>& d = sensors_[sensor_id];
  d.push_back({t_s, r_W, p_SinW, sigma_B_T, sigma_T_Tpm});
  const double span = SpanS();
  while (!d.empty() && t_s - d.front().t_s > span + 1e-9) d.pop_front();
  fits_.erase(sensor_id);
}

QuietOffsets::Fit QuietOffsets::FitOf(const std::deque<Item>& d) const {
  Fit f;
  const std::size_t n = d.size();
  const std::size_t h = n / 2;
  f.t_ref_s = d[h].t_s;
  // The rate from the two halves' medians (each robust to a spoilt sample).
  const double t1 = d[h / 2].t_s, t2 = d[h + (n - h) / 2].t_s;
  f.has_rate = options_.quiet_rate && h >= 2 && t2 - t1 >= kMinRateBaseline_s;
  std::vector<double> v;
  if (f.has_rate) {
    for (int k = 0; k < 3; ++k) {
      v.clear();
      for (std::size_t i = 0; i < h; ++i) v.push_back(d[i].r_W(k));
      const double m1 = Median(&v);
      v.clear();
      for (std::size_t i = h; i < n; ++i) v.push_back(d[i].r_W(k));
      const double m2 = Median(&v);
      f.rate_W(k) = std::clamp((m2 - m1) / (t2 - t1), -options_.max_rate_T_per_s, options_.max_rate_T_per_s);
    }
  }
  // The level at t_ref: the median of the samples with the rate taken out;
  // the spread of the detrended samples (largest axis).
  double spread = 0.0;
  v.resize(n);
  for (int k = 0; k < 3; ++k) {
    for (std::size_t i = 0; i < n; ++i) v[i] = d[i].r_W(k) - f.rate_W(k) * (d[i].t_s - f.t_ref_s);
    const double med = Median(&v);
    f.level_W(k) = med;
    for (std::size_t i = 0; i < n; ++i) v[i] = std::abs(d[i].r_W(k) - f.rate_W(k) * (d[i].t_s - f.t_ref_s) - med);
    spread = std::max(spread, kMadToSigma * Median(&v));
  }
  f.sigma_level_T = kMedianEfficiency * spread / std::sqrt(static_cast<double>(n));
  if (f.has_rate) {
    // The difference of the two halves' medians over their baseline.
    const double s1 = kMedianEfficiency * spread / std::sqrt(static_cast<double>(h));
    const double s2 = kMedianEfficiency * spread / std::sqrt(static_cast<double>(n - h));
    f.sigma_rate_Tps = std::hypot(s1, s2) / (t2 - t1);
  }
  return f;
}

bool QuietOffsets::Prior(std::uint32_t sensor_id, double t_s, Eigen::Vector3d* mean_W, double* sigma_T) const {
  const auto it = sensors_.find(sensor_id);
  if (it == sensors_.end() || static_cast<int>(it->second.size()) < options_.quiet_min_samples) return false;
  auto f = fits_.find(sensor_id);
  if (f == fits_.end()) f = fits_.emplace(sensor_id, FitOf(it->second)).first;
  const Fit& fit = f->second;
  const double dt = t_s - fit.t_ref_s;
  if (fit.has_rate) {
    // The line predicted to t_s; its σ grows with the extrapolation.
    *mean_W = fit.level_W + fit.rate_W * dt;
    *sigma_T = std::max(std::hypot(fit.sigma_level_T, fit.sigma_rate_Tps * dt), 1e-12);
    return true;
  }
  // The median at the samples' median time; then the drift bound's walk to t_s.
  *mean_W = fit.level_W;
  const double walk = options_.max_rate_T_per_s * std::abs(dt);
  *sigma_T = std::max(std::hypot(fit.sigma_level_T, walk), 1e-12);
  return true;
}

bool QuietOffsets::Rate(std::uint32_t sensor_id, Eigen::Vector3d* rate_W) const {
  Eigen::Vector3d mean;
  double sigma = 0.0;
  if (!Prior(sensor_id, 0.0, &mean, &sigma)) return false;
  const Fit& fit = fits_.at(sensor_id);
  *rate_W = fit.rate_W;
  return fit.has_rate;
}

int QuietOffsets::num_quiet(std::uint32_t sensor_id) const {
  const auto it = sensors_.find(sensor_id);
  return it == sensors_.end() ? 0 : static_cast<int>(it->second.size());
}

QuietTakeOutStats QuietOffsets::TakeOut(const FieldAtFn& field_at) {
  QuietTakeOutStats stats;
  for (auto& [id, d] : sensors_) {
    std::deque<Item> kept;
    for (Item& item : d) {
      Eigen::Vector3d B = Eigen::Vector3d::Zero();
      bool not_quiet = false;
      if (field_at(id, item.t_s, item.p_SinW, item.sigma_B_T, item.sigma_T_Tpm, &B, &not_quiet) && B.allFinite()) {
        if (not_quiet) {
          ++stats.dropped;
          continue;
        }
        item.r_W -= B;
        ++stats.corrected;
        stats.max_B_T = std::max(stats.max_B_T, B.norm());
      }
      kept.push_back(item);
    }
    d = std::move(kept);
    fits_.erase(id);
  }
  return stats;
}

}  // namespace magnav::tracker::internal
