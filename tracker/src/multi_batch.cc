// SolveBatchMulti: the window tracker finds the vessels, SolveBatch refines
// each over its own samples.
#include <algorithm>
#include <cmath>
#include <map>

#include "magnav/core/error.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/multi_tracker.h"
#include "other_fields.h"

namespace magnav::tracker {

namespace {

// σ_B of a sample whose B is not to be used (its weight 1e-12 of a normal one).
constexpr double kUnusedSigmaFactor = 1e6;

// A track's estimates as a function of time (nearest estimate, propagated).
struct TrackPath {
  std::vector<EpochEstimate> epochs;  // time-ordered
  Eigen::Vector3d m_B = Eigen::Vector3d::Zero();

  // State at t_s, from the nearest estimate no farther than max_gap_s.
  std::optional<CtState<double>> At(double t_s, double max_gap_s) const {
    if (epochs.empty()) return std::nullopt;
    auto it = std::lower_bound(epochs.begin(), epochs.end(), t_s,
                               [](const EpochEstimate& e, double t) { return e.t_s < t; });
    if (it == epochs.end() || (it != epochs.begin() && t_s - std::prev(it)->t_s < it->t_s - t_s)) --it;
    if (std::abs(it->t_s - t_s) > max_gap_s) return std::nullopt;
    const CtState<double> s{it->p_VinW.x(), it->p_VinW.y(), it->p_VinW.z(), it->speed_mps, it->heading_rad,
                            it->turn_rate_radps};
    return PropagateCoordinatedTurn(s, t_s - it->t_s);
  }
};

}  // namespace

std::vector<MultiTrackEstimate> SolveBatchMulti(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                                const MultiTrackerOptions& options,
                                                const std::vector<DipoleFix>* fixes,
                                                const BatchProgress& progress) {
  std::string why;
  if (!options.IsValid(&why)) throw InputError("multi-tracker options: " + why);
  // 1. The causal pass finds the vessels.
  MultiTracker finder(B0_W, options);
  std::map<std::uint32_t, TrackPath> paths;
  std::size_t next_fix = 0;
  const auto take = [&](const std::vector<TrackOutput>& out) {
    for (const auto& o : out) {
      if (o.estimate.usable) paths[o.track_id].epochs.push_back(o.estimate);
    }
  };
  // Each sample's background prior from the finder (background.h), taken
  // out of the samples the refinement gets.
  std::vector<std::vector<BackgroundEstimate>> background(options.background.enabled ? epochs.size() : 0);
  for (const Epoch& e : epochs) {
    for (const auto& s : e.samples) {
      if (options.background.enabled) background[&e - epochs.data()].push_back(finder.Background(s.sensor_id, e.t_s));
    }
    while (fixes != nullptr && next_fix < fixes->size() && (*fixes)[next_fix].t_s <= e.t_s) {
      finder.AddFix((*fixes)[next_fix++]);
    }
    take(finder.AddEpoch(e));
    if (progress) progress("finding tracks", static_cast<std::size_t>(&e - epochs.data()) + 1, epochs.size());
  }
  take(finder.Flush());
  std::vector<MultiTrackEstimate> result;
  // Each track's span: its window estimates' plus the margin; a track that
  // ended because its sensors stopped fitting it (an untracked vessel came,
  // or it was lost) ends at its last detection in the first round.
  std::vector<std::pair<double, double>> spans;
  std::vector<double> extend;  // a missed track's end once the others are known
  std::vector<double> b_only_until;  // past this, the extension: tensor only
  const double margin = options.batch_margin_s;
  for (const TrackRecord& r : finder.Tracks()) {
    auto it = paths.find(r.track_id);
    if (it == paths.end() || it->second.epochs.empty()) continue;
    it->second.m_B = r.m_B_Am2;
    MultiTrackEstimate m;
    m.track_id = r.track_id;
    m.track.epochs = it->second.epochs;
    m.track.m_B_Am2 = r.m_B_Am2;
    m.track.cov_m_B = r.cov_m_B;
    m.track.summary.initialized = true;
    m.track.summary.usable = true;
    m.track.summary.message = "window estimates (batch refinement not run)";
    const bool cut = r.end_reason == "missed" || r.end_reason == "unusable" || r.end_reason == "duplicate";
    spans.emplace_back(m.track.epochs.front().t_s - margin,
                       cut ? r.t_last_detection_s : m.track.epochs.back().t_s + margin);
    extend.push_back(r.end_reason == "missed" ? r.t_last_detection_s + margin : spans.back().second);
    b_only_until.push_back(spans.back().second);
    result.push_back(std::move(m));
  }
  // 2. Rounds of refinement, each track over its own samples with the other
  // tracks' fields (from the previous round) removed.
  const double max_gap = margin + options.track.window_s;
  const double gate = options.management.gate_snr;
  TrackerOptions topt = options.track;
  if (topt.init.source == InitSource::kExternal) topt.init.source = InitSource::kAuto;
  for (int round = 0; round < options.batch_rounds; ++round) {
    // From the second round on, the other tracks' fields are those of their
    // own batch solves: a track ended by misses (most often an untracked
    // vessel dominating its sensors before that vessel had a track) is taken
    // on for the margin past its last detection, with those fields removed.
    if (round > 0) {
      for (std::size_t i = 0; i < spans.size(); ++i) spans[i].second = extend[i];
    }
    std::vector<TrackPath> now(result.size());
    for (std::size_t i = 0; i < result.size(); ++i) {
      now[i].epochs = result[i].track.epochs;
      now[i].m_B = result[i].track.m_B_Am2;
    }
    for (std::size_t i = 0; i < result.size(); ++i) {
      if (progress) {
        progress("refining track " + std::to_string(result[i].track_id) + ", round " + std::to_string(round + 1) +
                     " of " + std::to_string(options.batch_rounds),
                 0, 0);
      }
      const auto [t0, t1] = spans[i];
      std::vector<Epoch> mine;
      std::vector<DipoleFix> track_fixes;
      for (const Epoch& e : epochs) {
        if (e.t_s < t0 || e.t_s > t1) continue;
        const auto s_i = now[i].At(e.t_s, max_gap);
        if (!s_i) continue;
        std::vector<std::optional<CtState<double>>> others(result.size());
        for (std::size_t k = 0; k < result.size(); ++k) {
          // Another track's field only within its own span: before its
          // vessel came its extrapolation is no field at all.
          if (k != i && e.t_s >= spans[k].first && e.t_s <= spans[k].second) others[k] = now[k].At(e.t_s, max_gap);
        }
        Epoch k_epoch{e.t_s, {}};
        for (std::size_t j = 0; j < e.samples.size(); ++j) {
          GradiometerSample s0 = e.samples[j];
          if (CheckSample(s0) != SampleDefect::kNone) continue;
          if (options.background.enabled) {
            const BackgroundEstimate& bg = background[&e - epochs.data()][j];
            s0.sigma_B = std::hypot(SigmaB(s0, topt), bg.sigma_T);
            s0.B -= bg.B_W - B0_W;
          }
          Eigen::Vector3d B;
          Eigen::Matrix3d T;
          PredictedField(*s_i, now[i].m_B, s0.p_SinW, &B, &T);
          const double sb = SigmaB(s0, topt), st = SigmaT(s0, topt);
          const double snr = std::sqrt(B.squaredNorm() / (sb * sb) + T.squaredNorm() / (st * st));
          if (!(snr >= gate)) continue;
          GradiometerSample s = s0;
          Eigen::Vector3d B_others = Eigen::Vector3d::Zero();
          Eigen::Matrix3d T_others = Eigen::Matrix3d::Zero();
          for (std::size_t k = 0; k < result.size(); ++k) {
            if (!others[k]) continue;
            PredictedField(*others[k], now[k].m_B, s.p_SinW, &B, &T);
            B_others += B;
            T_others += T;
          }
          RemoveOtherFields(B_others, T_others, sb, st, &s);
          // Past its last detection a missed track's B is an untracked
          // vessel's far field as much as its own: only its tensor (which
          // falls off faster) is used there.
          if (e.t_s > b_only_until[i]) s.sigma_B = kUnusedSigmaFactor * sb;
          k_epoch.samples.push_back(s);
          track_fixes.push_back(MakeFix(e.t_s, s.sensor_id, Eigen::Vector3d(s_i->x, s_i->y, s_i->z)));
        }
        if (!k_epoch.samples.empty()) mine.push_back(std::move(k_epoch));
      }
      if (mine.empty()) continue;
      TrackEstimate est = SolveBatch(mine, B0_W, topt, &track_fixes);
      const bool ok = est.summary.initialized && est.summary.usable &&
                      std::any_of(est.epochs.begin(), est.epochs.end(), [](const EpochEstimate& e) { return e.usable; });
      if (ok) {
        result[i].track = std::move(est);
      } else {
        result[i].track.summary.message =
            "window estimates: batch refinement failed (" + est.summary.message + ")";
      }
    }
  }
  return result;
}

}  // namespace magnav::tracker
