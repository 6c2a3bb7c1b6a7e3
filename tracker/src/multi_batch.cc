// SolveBatchMulti: the window tracker finds the vessels, SolveBatch refines
// each over its own samples.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "magnav/core/error.h"
#include "magnav/tracker/association.h"
#include "magnav/tracker/cluster_background.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/sensor_drift.h"
#include "other_fields.h"

namespace magnav::tracker {

namespace {

// σ_B of a sample whose B is not to be used (its weight 1e-12 of a normal one).
constexpr double kUnusedSigmaFactor = 1e6;
// A track that ended because its sensors stopped fitting it (most often an
// untracked vessel dominating them, then tracked later) is taken on for at
// most this long past its last detection, on its tensor alone: its B there
// is that vessel's far field as much as its own, and grown by the SNR alone
// its extrapolation drifted on the reference field (vessel 2: 0.49 m RMS,
// 105 false rows, against 0.043 m and none with this bound).
constexpr double kMissedExtensionS = 5.0;

// A track's estimates as a function of time (nearest estimate, propagated).
struct TrackPath {
  std::vector<EpochEstimate> epochs;  // time-ordered
  Eigen::Vector3d m_B = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov_m_B = Eigen::Matrix3d::Zero();  // (A·m²)²

  // The estimate nearest to t_s (nullptr if none): its covariance is the
  // one taken for the state At(t_s) (not propagated: at most half an epoch
  // apart within the span; the end's past it).
  const EpochEstimate* Nearest(double t_s) const {
    if (epochs.empty()) return nullptr;
    auto it = std::lower_bound(epochs.begin(), epochs.end(), t_s,
                               [](const EpochEstimate& e, double t) { return e.t_s < t; });
    if (it == epochs.end() || (it != epochs.begin() && t_s - std::prev(it)->t_s < it->t_s - t_s)) --it;
    return &*it;
  }

  // State at t_s: between the first and the last estimate from the nearest
  // one no farther than max_gap_s; before the first or after the last
  // propagated from it however far (the batch's extension, bounded by the
  // predicted SNR).
  std::optional<CtState<double>> At(double t_s, double max_gap_s) const {
    if (epochs.empty()) return std::nullopt;
    auto it = std::lower_bound(epochs.begin(), epochs.end(), t_s,
                               [](const EpochEstimate& e, double t) { return e.t_s < t; });
    if (it == epochs.end() || (it != epochs.begin() && t_s - std::prev(it)->t_s < it->t_s - t_s)) --it;
    const bool outside = t_s < epochs.front().t_s || t_s > epochs.back().t_s;
    if (!outside && std::abs(it->t_s - t_s) > max_gap_s) return std::nullopt;
    const CtState<double> s{it->p_VinW.x(), it->p_VinW.y(), it->p_VinW.z(), it->speed_mps, it->heading_rad,
                            it->turn_rate_radps};
    return PropagateCoordinatedTurn(s, t_s - it->t_s);
  }
};

// The other tracks (their paths as refined, their spans): a sensor where
// another track, within its span, is seen as well is that track's, so that
// a vessel followed by two tracks in turn, or a second vessel near, is not
// taken into this track's problem by an extrapolation.
// A partner (TrackRecord::partner_id: the other vessel of a pair started
// abreast) is not such a track: its tensor, propagated past its span too, is
// taken out of the measured one instead (PartnerTensor).
struct Others {
  const std::vector<TrackPath>* paths = nullptr;
  const std::vector<std::pair<double, double>>* spans = nullptr;
  std::size_t self = 0;
  double max_gap_s = 0.0;
  std::size_t partner = std::numeric_limits<std::size_t>::max();  // none

  bool SeenAt(double t_s, const GradiometerSample& g, double gate, const TrackerOptions& topt) const {
    for (std::size_t k = 0; k < paths->size(); ++k) {
      if (k == self || k == partner || t_s < (*spans)[k].first || t_s > (*spans)[k].second) continue;
      const auto s = (*paths)[k].At(t_s, max_gap_s);
      if (!s) continue;
      Eigen::Vector3d B;
      Eigen::Matrix3d T;
      PredictedField(*s, (*paths)[k].m_B, g.p_SinW, &B, &T);
      if (T.norm() >= gate * SigmaT(g, topt)) return true;
    }
    return false;
  }

  // The partner's predicted tensor at the sample (zero if none).
  Eigen::Matrix3d PartnerTensor(double t_s, const GradiometerSample& g) const {
    Eigen::Vector3d B = Eigen::Vector3d::Zero();
    Eigen::Matrix3d T = Eigen::Matrix3d::Zero();
    if (partner >= paths->size()) return T;
    const auto s = (*paths)[partner].At(t_s, max_gap_s);
    if (s) PredictedField(*s, (*paths)[partner].m_B, g.p_SinW, &B, &T);
    return T;
  }
};

// The track's predicted tensors at an epoch, over the sensors where its
// predicted tensor SNR ‖T̂‖/σ_T reaches the gate and no other track is seen:
// Σ⟨T, T̂⟩/σ_T² (measured against predicted) and Σ‖T̂‖²/σ_T²; energy 0 = not
// seen there.
struct Seen {
  double inner = 0.0, energy = 0.0;
};
Seen TensorSeen(const Epoch& e, const CtState<double>& s, const Eigen::Vector3d& m_B, double gate,
                const TrackerOptions& topt, const Others& others) {
  Seen seen;
  for (const auto& g : e.samples) {
    if (CheckSample(g) != SampleDefect::kNone) continue;
    Eigen::Vector3d B;
    Eigen::Matrix3d T;
    PredictedField(s, m_B, g.p_SinW, &B, &T);
    const double st = SigmaT(g, topt);
    if (T.norm() >= gate * st && !others.SeenAt(e.t_s, g, gate, topt)) {
      const Eigen::Matrix3d measured = g.T - others.PartnerTensor(e.t_s, g);
      seen.inner += (measured.array() * T.array()).sum() / (st * st);
      seen.energy += T.squaredNorm() / (st * st);
    }
  }
  return seen;
}

// Grows [t0, t1] outwards, by at most step_s on each side (the end only if
// grow_end), over the epochs where the track's trajectory, propagated past
// its ends, is seen (TensorSeen), block by block of kExtensionBlock epochs:
// a block is taken if the measured tensors agree with the predicted ones,
// Σ⟨T, T̂⟩ ≥ ½ Σ‖T̂‖² (a matched filter: the prediction explains more than
// it adds; at an SNR of 1 per epoch a present vessel passes a block ~95 %
// of the time, an absent one ~5 %), and growing stops at the first block
// that is not, or at the first epoch where the track is not seen. True if
// it grew.
constexpr int kExtensionBlock = 10;
bool ExtendSpan(const std::vector<Epoch>& epochs, const TrackPath& path, double gate, double step_s, bool grow_end,
                const TrackerOptions& topt, const Others& others, std::pair<double, double>* span) {
  bool grew = false;
  const auto walk = [&](auto it, auto end, double limit_s, double* edge) {
    Seen block;
    int n = 0;
    double block_edge = *edge;
    const auto take = [&] {
      if (n == 0 || block.inner < 0.5 * block.energy) return false;
      *edge = block_edge;
      grew = true;
      block = {};
      n = 0;
      return true;
    };
    for (; it != end; ++it) {
      if (std::abs(it->t_s - limit_s) > step_s) break;
      const auto s = path.At(it->t_s, 1.0);
      if (!s) break;
      const Seen seen = TensorSeen(*it, *s, path.m_B, gate, topt, others);
      if (seen.energy == 0.0) break;
      block.inner += seen.inner;
      block.energy += seen.energy;
      block_edge = it->t_s;
      if (++n == kExtensionBlock && !take()) return;
    }
    take();
  };
  const auto first = std::lower_bound(epochs.begin(), epochs.end(), span->first,
                                      [](const Epoch& e, double t) { return e.t_s < t; });
  walk(std::make_reverse_iterator(first), epochs.rend(), span->first, &span->first);
  if (!grow_end) return grew;
  const auto last = std::upper_bound(epochs.begin(), epochs.end(), span->second,
                                     [](double t, const Epoch& e) { return t < e.t_s; });
  walk(last, epochs.end(), span->second, &span->second);
  return grew;
}

// Each estimate's state (TrackState): the associator's detection test
// (AssociateEpoch: gate, LLR ≥ detect_llr, not a poor fit) on the track's
// own samples of that epoch (`mine`: others' fields and background
// removed, as solved), predicted from the refined state and moment.
std::vector<TrackState> BatchStates(const TrackEstimate& est, const std::vector<Epoch>& mine,
                                    const Eigen::Vector3d& B0_W, const MultiTrackerOptions& options) {
  std::vector<TrackState> states(est.epochs.size(), TrackState::kCoasting);
  auto m = mine.begin();
  for (std::size_t k = 0; k < est.epochs.size(); ++k) {
    const EpochEstimate& e = est.epochs[k];
    while (m != mine.end() && m->t_s < e.t_s) ++m;
    if (m == mine.end() || m->t_s != e.t_s || !e.usable) continue;
    const CtState<double> s{e.p_VinW.x(), e.p_VinW.y(), e.p_VinW.z(), e.speed_mps, e.heading_rad, e.turn_rate_radps};
    std::vector<TrackPrediction> pred(1);
    pred[0].valid = true;
    for (const auto& g : m->samples) pred[0].at.push_back(PredictAtSample(s, est.m_B_Am2, g, options.track));
    if (AssociateEpoch(*m, pred, B0_W, options)[0].detected) states[k] = TrackState::kConfirmed;
  }
  return states;
}

// The reach rule of the window's life cycle (TrackManagementOptions::
// out_of_reach_s, reach_tensor_snr) on the batch's rows: a track's leading
// and trailing estimates outside the sensors' horizontal bounding box whose
// predicted tensor SNR is below reach_tensor_snr at every sensor are not
// reported (their samples were used; only the rows go). Past the reach its
// position rests on B, which a far ship or a drift also moves. Off with
// out_of_reach_s = 0.
void TrimOutOfReach(const std::vector<Epoch>& epochs, const MultiTrackerOptions& options,
                    std::vector<MultiTrackEstimate>* result) {
  if (!(options.management.out_of_reach_s > 0.0)) return;
  // The sensors (position, σ_T), each once.
  std::map<std::uint32_t, std::pair<Eigen::Vector3d, double>> sensors;
  for (const Epoch& e : epochs) {
    for (const auto& s : e.samples) {
      if (!sensors.count(s.sensor_id)) sensors[s.sensor_id] = {s.p_SinW, SigmaT(s, options.track)};
    }
  }
  if (sensors.empty()) return;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& [id, s] : sensors) {
    lo = lo.cwiseMin(s.first.head<2>());
    hi = hi.cwiseMax(s.first.head<2>());
  }
  for (MultiTrackEstimate& m : *result) {
    const auto in_reach = [&](const EpochEstimate& e) {
      const Eigen::Vector2d h = e.p_VinW.head<2>();
      if ((h.array() >= lo.array()).all() && (h.array() <= hi.array()).all()) return true;
      const CtState<double> x{e.p_VinW.x(), e.p_VinW.y(), e.p_VinW.z(), e.speed_mps, e.heading_rad, e.turn_rate_radps};
      for (const auto& [id, s] : sensors) {
        Eigen::Vector3d B;
        Eigen::Matrix3d T;
        PredictedField(x, m.track.m_B_Am2, s.first, &B, &T);
        if (T.norm() / s.second >= options.management.reach_tensor_snr) return true;
      }
      return false;
    };
    std::vector<EpochEstimate>& est = m.track.epochs;
    const bool with_states = m.states.size() == est.size();
    std::size_t first = 0, last = est.size();
    while (first < last && !in_reach(est[first])) ++first;
    while (last > first && !in_reach(est[last - 1])) --last;
    if (first == 0 && last == est.size()) continue;
    est = std::vector<EpochEstimate>(est.begin() + first, est.begin() + last);
    if (with_states) m.states = std::vector<TrackState>(m.states.begin() + first, m.states.begin() + last);
  }
}

}  // namespace

std::vector<MultiTrackEstimate> SolveBatchMulti(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                                const MultiTrackerOptions& options,
                                                const std::vector<DipoleFix>* fixes,
                                                const BatchProgress& progress, MultiSummary* finder_summary) {
  std::string why;
  if (!options.IsValid(&why)) throw InputError("multi-tracker options: " + why);
  // 1. The causal pass finds the vessels.
  // The out_of_reach end rule is the window's (a track's reported rows);
  // the batch finds its tracks without it, refines each over every sample
  // where it is seen (past its reach too: on a clean field a departing
  // vessel's B still steers its turn) and then reports only its rows within
  // reach (TrimOutOfReach).
  MultiTrackerOptions finder_options = options;
  finder_options.management.out_of_reach_s = 0.0;
  MultiTracker finder(B0_W, finder_options);
  std::map<std::uint32_t, TrackPath> paths;
  std::map<std::uint32_t, std::vector<TrackState>> window_states;  // per paths[id].epochs
  std::size_t next_fix = 0;
  const auto take = [&](const std::vector<TrackOutput>& out) {
    for (const auto& o : out) {
      if (!o.estimate.usable) continue;
      paths[o.track_id].epochs.push_back(o.estimate);
      window_states[o.track_id].push_back(o.state);
    }
  };
  // Each sample's background prior from the finder (background.h), taken
  // out of the samples the refinement gets.
  std::vector<std::vector<BackgroundEstimate>> background(options.background.enabled ? epochs.size() : 0);
  // The same for the far source's B (far_source.h): what the finder removed.
  std::vector<std::vector<std::pair<Eigen::Vector3d, double>>> far(options.far_source.enabled ? epochs.size() : 0);
  // With the drift refitted over the whole pass (SensorDriftOptions::
  // batch_refit), the far source's B alone (the finder's minus its drift
  // line then) and its σ.
  const SensorDriftOptions& drift_opt = options.far_source.drift;
  const bool drift_refit = options.far_source.enabled && drift_opt.enabled && drift_opt.batch_refit;
  std::vector<std::vector<std::pair<Eigen::Vector3d, double>>> far_only(drift_refit ? epochs.size() : 0);
  for (const Epoch& e : epochs) {
    for (const auto& s : e.samples) {
      if (options.background.enabled) background[&e - epochs.data()].push_back(finder.Background(s.sensor_id, e.t_s));
      if (options.far_source.enabled) {
        double sf = 0.0;
        const Eigen::Vector3d b = finder.FarSourceB(s, &sf);
        far[&e - epochs.data()].emplace_back(b, sf);
        if (drift_refit) {
          double sd = 0.0;
          const Eigen::Vector3d d = finder.Drift().At(s.sensor_id, e.t_s, &sd);
          far_only[&e - epochs.data()].emplace_back(b - d, std::sqrt(std::max(0.0, sf * sf - sd * sd)));
        }
      }
    }
    while (fixes != nullptr && next_fix < fixes->size() && (*fixes)[next_fix].t_s <= e.t_s) {
      finder.AddFix((*fixes)[next_fix++]);
    }
    take(finder.AddEpoch(e));
    if (progress) progress("finding tracks", static_cast<std::size_t>(&e - epochs.data()) + 1, epochs.size());
  }
  take(finder.Flush());
  if (finder_summary != nullptr) *finder_summary = finder.summary();
  std::vector<MultiTrackEstimate> result;
  // Each track's span: its window estimates'; a track that ended because its
  // sensors stopped fitting it (an untracked vessel came, or it was lost)
  // ends at its last detection. Each round then grows the spans outwards
  // over the samples where the refined track is still seen (ExtendSpan).
  std::vector<std::pair<double, double>> spans;
  std::vector<bool> grow_end;        // unusable and duplicate tracks keep their end
  std::vector<double> b_only_until;  // past this, the extension: tensor only
  std::vector<double> end_limit;     // a missed track's span ends by this
  std::vector<std::uint32_t> partner_id;
  std::vector<TrackPath> window_paths;  // as the finder left them
  for (const TrackRecord& r : finder.Tracks()) {
    auto it = paths.find(r.track_id);
    if (it == paths.end() || it->second.epochs.empty()) continue;
    it->second.m_B = r.m_B_Am2;
    MultiTrackEstimate m;
    m.track_id = r.track_id;
    m.track.epochs = it->second.epochs;
    m.states = window_states[r.track_id];
    m.track.m_B_Am2 = r.m_B_Am2;
    m.track.cov_m_B = r.cov_m_B;
    m.track.summary.initialized = true;
    m.track.summary.usable = true;
    m.track.summary.message = "window estimates (batch refinement not run)";
    const bool cut = r.end_reason == "missed" || r.end_reason == "unusable" || r.end_reason == "duplicate";
    spans.emplace_back(m.track.epochs.front().t_s, cut ? r.t_last_detection_s : m.track.epochs.back().t_s);
    grow_end.push_back(r.end_reason != "unusable" && r.end_reason != "duplicate");
    b_only_until.push_back(cut ? r.t_last_detection_s : std::numeric_limits<double>::infinity());
    end_limit.push_back(cut ? r.t_last_detection_s + kMissedExtensionS : std::numeric_limits<double>::infinity());
    partner_id.push_back(r.partner_id);
    window_paths.push_back(it->second);
    result.push_back(std::move(m));
  }
  // Each track's partner (index into result; none: result.size()).
  std::vector<std::size_t> partner(result.size(), result.size());
  for (std::size_t i = 0; i < result.size(); ++i) {
    for (std::size_t k = 0; k < result.size(); ++k) {
      if (k != i && partner_id[i] != 0 && result[k].track_id == partner_id[i]) partner[i] = k;
    }
  }
  // 2. Rounds of refinement, each track over its own samples with the other
  // tracks' fields (from the previous round) removed; after each, the spans
  // grow outwards. At least batch_rounds rounds, more while a span grows.
  const double step = options.batch_extension_step_s;
  const double max_gap = step + options.track.window_s;
  const double gate = options.batch_gate_snr;             // a sample is used
  const double seen_gate = options.batch_gate_snr;  // an epoch extends the span (tensor)
  TrackerOptions topt = options.track;
  if (topt.init.source == InitSource::kExternal) topt.init.source = InitSource::kAuto;
  if (options.batch_turn_loss_scale_sigma > 0.0) {
    topt.process.turn_rate_loss_scale_sigma = options.batch_turn_loss_scale_sigma;
  }
  // A track the field's start SNR cannot initialise (batch_weak_init).
  const bool weak_init = options.batch_weak_init && options.management.residual_start.tensor_snr > 0.0 &&
                         options.management.residual_start.tensor_snr < topt.init.min_tensor_snr;
  const TrackerOptions weak_topt = ResidualStartTrackerOptions(topt, options.management.residual_start);
  bool grew = true;
  const int max_rounds = std::max(options.batch_rounds, MultiTrackerOptions::kMaxBatchRounds);
  for (int round = 0; round < max_rounds && (round < options.batch_rounds || grew); ++round) {
    std::vector<TrackPath> now(result.size());
    for (std::size_t i = 0; i < result.size(); ++i) {
      now[i].epochs = result[i].track.epochs;
      now[i].m_B = result[i].track.m_B_Am2;
      now[i].cov_m_B = result[i].track.cov_m_B;
    }
    // Cluster background (cluster_background.h): the offset step given the
    // tracks as they are now (each within its span), over the whole pass.
    SensorOffsets offsets;
    if (options.cluster_background.enabled) {
      std::vector<ClusterTrack> ct(result.size());
      std::vector<std::set<std::uint32_t>> seen(result.size());
      for (const Epoch& e : epochs) {
        for (std::size_t i = 0; i < result.size(); ++i) {
          if (e.t_s < spans[i].first || e.t_s > spans[i].second) continue;
          const auto s_i = now[i].At(e.t_s, max_gap);
          if (!s_i) continue;
          for (const auto& smp : e.samples) {
            Eigen::Vector3d B;
            Eigen::Matrix3d T;
            PredictedField(*s_i, now[i].m_B, smp.p_SinW, &B, &T);
            const double sb = SigmaB(smp, topt), st = SigmaT(smp, topt);
            if (std::sqrt(B.squaredNorm() / (sb * sb) + T.squaredNorm() / (st * st)) >= gate) seen[i].insert(smp.sensor_id);
          }
        }
      }
      for (std::size_t i = 0; i < result.size(); ++i) {
        ct[i].m_B_Am2 = now[i].m_B;
        ct[i].sensors.assign(seen[i].begin(), seen[i].end());
        const TrackPath* path = &now[i];
        const std::pair<double, double> span = spans[i];
        ct[i].state_at = [path, span, max_gap](double t) -> std::optional<CtState<double>> {
          if (t < span.first || t > span.second) return std::nullopt;
          return path->At(t, max_gap);
        };
      }
      std::vector<const Epoch*> all;
      for (const Epoch& e : epochs) all.push_back(&e);
      EstimateClusterOffsets(all, ct, B0_W, topt, options.cluster_background, nullptr, &offsets);
    }
    // The drift refitted over the whole pass given the tracks as they are
    // now (sensor_drift.h, batch_refit): each sensor's line on its samples
    // where no track's field is (every track's predicted B, in its span or
    // extrapolated up to max_gap beyond it, below occupied_B_sigmas σ_B)
    // and the residual tensor is within the far source's tensor_gate, minus
    // B0, the far source and the tracks' B; one epoch per sample_interval_s.
    std::map<std::uint32_t, DriftLine> lines;
    if (drift_refit) {
      std::map<std::uint32_t, std::vector<DriftSample>> series;
      double last_t = -std::numeric_limits<double>::infinity();
      for (const Epoch& e : epochs) {
        if (e.t_s - last_t < drift_opt.sample_interval_s - 1e-6) continue;
        last_t = e.t_s;
        std::vector<std::optional<CtState<double>>> at(result.size());
        for (std::size_t k = 0; k < result.size(); ++k) at[k] = now[k].At(e.t_s, max_gap);
        for (std::size_t j = 0; j < e.samples.size(); ++j) {
          const GradiometerSample& smp = e.samples[j];
          if (CheckSample(smp) != SampleDefect::kNone) continue;
          Eigen::Vector3d B_tracks = Eigen::Vector3d::Zero();
          Eigen::Matrix3d T_tracks = Eigen::Matrix3d::Zero();
          double B_near = 0.0;
          for (std::size_t k = 0; k < result.size(); ++k) {
            if (!at[k]) continue;
            Eigen::Vector3d B;
            Eigen::Matrix3d T;
            PredictedField(*at[k], now[k].m_B, smp.p_SinW, &B, &T);
            B_near += B.norm();
            if (e.t_s >= spans[k].first && e.t_s <= spans[k].second) {
              B_tracks += B;
              T_tracks += T;
            }
          }
          const double sb = SigmaB(smp, topt), st = SigmaT(smp, topt);
          if (B_near > drift_opt.occupied_B_sigmas * sb) continue;
          const double st2 = st * st + RelativeOtherFieldVariance(B_tracks, T_tracks).T;
          if ((smp.T - T_tracks).squaredNorm() / st2 / 9.0 > options.far_source.tensor_gate) continue;
          const auto& [b_far, s_far] = far_only[&e - epochs.data()][j];
          series[smp.sensor_id].push_back(
              {smp.sensor_id, e.t_s, smp.B - B0_W - b_far - B_tracks, std::hypot(sb, s_far)});
        }
      }
      for (const auto& [id, ser] : series) {
        DriftLine line;
        if (FitDriftLine(ser, drift_opt, &line, nullptr) && line.Confirmed(drift_opt)) lines[id] = line;
      }
    }
    for (std::size_t i = 0; i < result.size(); ++i) {
      if (progress) {
        progress("refining track " + std::to_string(result[i].track_id) + ", round " + std::to_string(round + 1) +
                     (round < options.batch_rounds ? " of " + std::to_string(options.batch_rounds)
                                                   : " (its span grew)"),
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
          // vessel came its extrapolation is no field at all. The partner's
          // (the other vessel abreast) also outside it: they came together.
          if (k != i && ((e.t_s >= spans[k].first && e.t_s <= spans[k].second) || k == partner[i])) {
            others[k] = now[k].At(e.t_s, max_gap);
          }
        }
        Epoch k_epoch{e.t_s, {}};
        for (std::size_t j = 0; j < e.samples.size(); ++j) {
          GradiometerSample s0 = e.samples[j];
          if (CheckSample(s0) != SampleDefect::kNone) continue;
          if (options.cluster_background.enabled) s0.B -= offsets.At(s0.sensor_id, e.t_s);
          const auto line = lines.find(s0.sensor_id);
          if (drift_refit && line != lines.end()) {
            // The far source's B and this round's drift line.
            const auto& [b_far, s_far] = far_only[&e - epochs.data()][j];
            const double sd = line->second.SigmaAt(e.t_s);
            s0.sigma_B = std::hypot(SigmaB(s0, topt), std::hypot(s_far, sd));
            s0.B -= b_far + line->second.At(e.t_s);
          } else if (options.far_source.enabled) {
            const auto& [b_far, s_far] = far[&e - epochs.data()][j];
            if (s_far > 0.0) s0.sigma_B = std::hypot(SigmaB(s0, topt), s_far);
            s0.B -= b_far;
          }
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
          OtherFieldVariance var;  // batch_other_field_covariance
          for (std::size_t k = 0; k < result.size(); ++k) {
            if (!others[k]) continue;
            PredictedField(*others[k], now[k].m_B, s.p_SinW, &B, &T);
            B_others += B;
            T_others += T;
            if (!options.batch_other_field_covariance) continue;
            const EpochEstimate* near = now[k].Nearest(e.t_s);
            if (near != nullptr && near->has_covariance && near->cov_state.allFinite() && now[k].cov_m_B.allFinite()) {
              const OtherFieldVariance v =
                  OtherFieldVarianceFromCovariance(*others[k], now[k].m_B, near->cov_state, now[k].cov_m_B, s.p_SinW);
              var.B += v.B;
              var.T += v.T;
            } else {
              // No covariance for it: its relative error, as the default.
              const OtherFieldVariance v = RelativeOtherFieldVariance(B, T);
              var.B += v.B;
              var.T += v.T;
            }
          }
          if (options.batch_other_field_covariance) {
            RemoveOtherFieldsWithVariance(B_others, T_others, var, sb, st, &s);
          } else {
            RemoveOtherFields(B_others, T_others, sb, st, &s, options.batch_other_field_relative_error);
          }
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
      std::vector<BatchStart> starts;
      if (options.batch_restart_from_window) {
        const TrackPath* path = &window_paths[i];
        starts.push_back([path, max_gap](double t) { return path->At(t, max_gap); });
      }
      TrackEstimate est = SolveBatch(mine, B0_W, topt, &track_fixes, &starts);
      if (!est.summary.initialized && weak_init) {
        // Too few fixes at the field's start SNR: a vessel started in the
        // residual (batch_weak_init).
        est = SolveBatch(mine, B0_W, weak_topt, &track_fixes, &starts);
        if (est.summary.initialized) est.summary.message += " (initialised at the residual start's SNR)";
      }
      const bool ok = est.summary.initialized && est.summary.usable &&
                      std::any_of(est.epochs.begin(), est.epochs.end(), [](const EpochEstimate& e) { return e.usable; });
      if (ok) {
        result[i].states = BatchStates(est, mine, B0_W, options);
        result[i].track = std::move(est);
      } else {
        result[i].track.summary.message =
            "window estimates: batch refinement failed (" + est.summary.message + ")";
      }
    }
    // Grow every span over the samples where its refined track is still seen.
    grew = false;
    std::vector<TrackPath> refined(result.size());
    for (std::size_t i = 0; i < result.size(); ++i) {
      refined[i].epochs = result[i].track.epochs;
      refined[i].m_B = result[i].track.m_B_Am2;
      std::erase_if(refined[i].epochs, [](const EpochEstimate& e) { return !e.usable; });
    }
    // In track order, each against the others' spans as grown so far.
    for (std::size_t i = 0; i < result.size(); ++i) {
      const Others others{&refined, &spans, i, max_gap, partner[i] < result.size() ? partner[i] : std::numeric_limits<std::size_t>::max()};
      if (ExtendSpan(epochs, refined[i], seen_gate, step, grow_end[i], topt, others, &spans[i])) grew = true;
      spans[i].second = std::min(spans[i].second, end_limit[i]);
    }
  }
  TrimOutOfReach(epochs, options, &result);
  return result;
}

}  // namespace magnav::tracker
