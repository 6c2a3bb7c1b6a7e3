#include "magnav/tracker/cluster_background.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>
#include <numeric>
#include <set>

#include "magnav/core/checkpoint.h"
#include "magnav/core/option_check.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/multi_tracker.h"
#include "quiet_sample.h"
#include "state_io.h"

namespace magnav::tracker {

bool ClusterBackgroundOptions::IsValid(std::string* error) const {
  // Upper bounds: their squares are variances (1e308 would overflow them to
  // inf and the smoother to NaN); 1 T is the door's B limit (core/limits.h).
  const auto in = [](double x, double hi) { return std::isfinite(x) && x > 0.0 && x <= hi; };
  if (!in(prior_sigma_T, 1.0)) return Fail(error, "cluster background prior sigma must be in (0, 1] T");
  if (!in(walk_T_per_sqrt_s, 1.0)) return Fail(error, "cluster background walk must be in (0, 1] T/sqrt(s)");
  if (!(rate_walk_T_per_s_per_sqrt_s >= 0.0 && rate_walk_T_per_s_per_sqrt_s <= 1.0)) {
    return Fail(error, "cluster background rate walk must be in [0, 1] T/s/sqrt(s)");
  }
  if (!in(prior_rate_sigma_T_per_s, 1.0)) return Fail(error, "cluster background rate prior sigma must be in (0, 1] T/s");
  if (!PositiveFinite(tensor_gate)) return Fail(error, "cluster background tensor gate must be > 0");
  if (!in(track_field_share, 100.0)) return Fail(error, "cluster background track field share must be in (0, 100]");
  if (!(occupied_tensor_snr >= 0.0) || !std::isfinite(occupied_tensor_snr)) {
    return Fail(error, "cluster background occupied tensor SNR must be finite and >= 0");
  }
  return true;
}

std::vector<OffsetEstimate> SmoothOffsets(const std::vector<OffsetSample>& series,
                                          const ClusterBackgroundOptions& options, const Eigen::Vector3d& prior_mean_W) {
  const std::size_t n = series.size();
  std::vector<OffsetEstimate> out(n);
  if (n == 0) return out;
  // State per axis [b, ḃ] (the three axes share the 2×2 covariance): a level
  // random walk q_l and, if rate_walk > 0, a white acceleration q_a.
  // Without a rate walk the rate stays zero (a pure level walk).
  using M2 = Eigen::Matrix2d;
  using X = Eigen::Matrix<double, 3, 2>;  // columns: level, rate
  const double ql = options.walk_T_per_sqrt_s * options.walk_T_per_sqrt_s;
  const double qa = options.rate_walk_T_per_s_per_sqrt_s * options.rate_walk_T_per_s_per_sqrt_s;
  const bool with_rate = qa > 0.0;
  std::vector<X> xf(n), xp(n);
  std::vector<M2> Pf(n), Pp(n), F(n);
  X x = X::Zero();
  x.col(0) = prior_mean_W;
  M2 P = M2::Zero();
  P(0, 0) = options.prior_sigma_T * options.prior_sigma_T;
  P(1, 1) = with_rate ? options.prior_rate_sigma_T_per_s * options.prior_rate_sigma_T_per_s : 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double dt = k > 0 ? std::max(series[k].t_s - series[k - 1].t_s, 0.0) : 0.0;
    M2 Fk = M2::Identity();
    Fk(0, 1) = with_rate ? dt : 0.0;
    M2 Q;
    Q << qa * dt * dt * dt / 3.0 + ql * dt, qa * dt * dt / 2.0, qa * dt * dt / 2.0, qa * dt;
    if (k > 0) {
      x = x * Fk.transpose();
      P = Fk * P * Fk.transpose() + Q;
    }
    F[k] = Fk;
    xp[k] = x;
    Pp[k] = P;
    const double R = series[k].var_T2;
    if (std::isfinite(R) && R > 0.0 && series[k].r_W.allFinite()) {
      const double S = P(0, 0) + R;
      const Eigen::Vector2d K = P.col(0) / S;
      x += (series[k].r_W - x.col(0)) * K.transpose();
      P -= K * K.transpose() * S;
      P = 0.5 * (P + P.transpose());
    }
    xf[k] = x;
    Pf[k] = P;
  }
  // Backward (RTS): C_k = P_f,k F_{k+1}ᵀ P_p,k+1⁻¹.
  X xs = xf[n - 1];
  M2 Ps = Pf[n - 1];
  out[n - 1] = {series[n - 1].t_s, xs.col(0), Ps(0, 0)};
  for (std::size_t k = n - 1; k-- > 0;) {
    M2 C = M2::Zero();
    if (with_rate) {
      C = Pf[k] * F[k + 1].transpose() * Pp[k + 1].inverse();
    } else if (Pp[k + 1](0, 0) > 0.0) {
      C(0, 0) = Pf[k](0, 0) / Pp[k + 1](0, 0);
    }
    xs = xf[k] + (xs - xp[k + 1]) * C.transpose();
    Ps = Pf[k] + C * (Ps - Pp[k + 1]) * C.transpose();
    out[k] = {series[k].t_s, xs.col(0), Ps(0, 0)};
  }
  return out;
}

std::vector<std::vector<std::size_t>> TrackClusters(const std::vector<std::vector<std::uint32_t>>& sensors) {
  const std::size_t n = sensors.size();
  std::vector<std::size_t> parent(n);
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  const auto find = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::map<std::uint32_t, std::size_t> owner;  // a sensor's first track
  for (std::size_t i = 0; i < n; ++i) {
    for (std::uint32_t s : sensors[i]) {
      const auto [it, fresh] = owner.emplace(s, i);
      if (!fresh) {
        const std::size_t a = find(i), b = find(it->second);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    }
  }
  std::map<std::size_t, std::vector<std::size_t>> by_root;
  for (std::size_t i = 0; i < n; ++i) by_root[find(i)].push_back(i);
  std::vector<std::vector<std::size_t>> out;
  for (auto& [root, members] : by_root) out.push_back(std::move(members));
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.front() < b.front(); });
  return out;
}

void SensorOffsets::Set(std::uint32_t sensor_id, std::vector<OffsetEstimate> series) {
  if (series.empty()) {
    series_.erase(sensor_id);
  } else {
    series_[sensor_id] = std::move(series);
  }
}

Eigen::Vector3d SensorOffsets::At(std::uint32_t sensor_id, double t_s) const {
  const auto it = series_.find(sensor_id);
  if (it == series_.end()) return Eigen::Vector3d::Zero();
  const std::vector<OffsetEstimate>& s = it->second;
  const auto after = std::upper_bound(s.begin(), s.end(), t_s,
                                      [](double t, const OffsetEstimate& e) { return t < e.t_s; });
  return after == s.begin() ? s.front().b_W : std::prev(after)->b_W;
}

void SensorOffsets::SaveState(StateWriter& w) const {
  w.U64(series_.size());
  for (const auto& [id, s] : series_) {
    w.U32(id);
    w.U64(s.size());
    for (const OffsetEstimate& e : s) {
      w.F64(e.t_s);
      w.Matrix(e.b_W);
      w.F64(e.var_T2);
    }
  }
}

void SensorOffsets::RestoreState(StateReader& r) {
  std::map<std::uint32_t, std::vector<OffsetEstimate>> series;
  for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) {
    const std::uint32_t id = r.U32();
    std::vector<OffsetEstimate>& s = series[id];
    for (std::size_t k = r.Count(internal::kMaxStateCount); k > 0; --k) {
      OffsetEstimate e;
      e.t_s = r.F64();
      e.b_W = internal::GetMatrix(r, 3, 1);
      e.var_T2 = r.F64();
      s.push_back(e);
    }
  }
  series_ = std::move(series);
}

ClusterStepStats EstimateClusterOffsets(const std::vector<const Epoch*>& epochs, const std::vector<ClusterTrack>& tracks,
                                        const Eigen::Vector3d& B0_W, const TrackerOptions& track_options,
                                        const ClusterBackgroundOptions& options, const SensorOffsets* prior,
                                        SensorOffsets* offsets) {
  ClusterStepStats stats;
  std::vector<std::vector<std::uint32_t>> sensors(tracks.size());
  std::set<std::uint32_t> wanted;
  for (std::size_t i = 0; i < tracks.size(); ++i) {
    sensors[i] = tracks[i].sensors;
    wanted.insert(sensors[i].begin(), sensors[i].end());
  }
  for (const auto& c : TrackClusters(sensors)) {
    std::set<std::uint32_t> s;
    for (std::size_t i : c) s.insert(sensors[i].begin(), sensors[i].end());
    stats.cluster_tracks.push_back(static_cast<int>(c.size()));
    stats.cluster_sensors.push_back(static_cast<int>(s.size()));
  }
  if (wanted.empty()) return stats;
  const internal::QuietRule rule{options.occupied_tensor_snr, options.tensor_gate, options.track_field_share};
  std::map<std::uint32_t, std::vector<OffsetSample>> series;
  std::vector<std::optional<CtState<double>>> at(tracks.size());
  for (const Epoch* e : epochs) {
    bool any = false;
    for (const auto& smp : e->samples) any = any || wanted.count(smp.sensor_id) != 0;
    if (!any) continue;
    for (std::size_t i = 0; i < tracks.size(); ++i) at[i] = tracks[i].state_at(e->t_s);
    for (const auto& smp : e->samples) {
      if (wanted.count(smp.sensor_id) == 0) continue;
      Eigen::Vector3d B_tracks = Eigen::Vector3d::Zero();
      Eigen::Matrix3d T_tracks = Eigen::Matrix3d::Zero();
      for (std::size_t i = 0; i < tracks.size(); ++i) {
        if (!at[i]) continue;
        Eigen::Vector3d B;
        Eigen::Matrix3d T;
        PredictedField(*at[i], tracks[i].m_B_Am2, smp.p_SinW, &B, &T);
        B_tracks += B;
        T_tracks += T;
      }
      const internal::QuietSample q = internal::QuietResidual(smp, B_tracks, T_tracks, B0_W, track_options, rule);
      if (q.use != internal::QuietUse::kUsed) {
        ++(q.use == internal::QuietUse::kOccupied ? stats.num_samples_occupied : stats.num_samples_gated);
        series[smp.sensor_id].push_back({e->t_s, Eigen::Vector3d::Zero(), 0.0});  // no measurement
        continue;
      }
      ++stats.num_samples_used;
      series[smp.sensor_id].push_back({e->t_s, q.r_W, q.var_T2});
    }
  }
  for (auto& [id, s] : series) {
    const Eigen::Vector3d mean =
        prior != nullptr && prior->Has(id) ? prior->At(id, s.front().t_s) : Eigen::Vector3d::Zero();
    offsets->Set(id, SmoothOffsets(s, options, mean));
  }
  return stats;
}

}  // namespace magnav::tracker
