#include "magnav/tracker/association.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <stdexcept>
#include <utility>

#include "magnav/core/motion.h"
#include "magnav/tracker/assignment.h"
#include "magnav/tracker/initialize.h"
#include "other_fields.h"

namespace magnav::tracker {

FieldPrediction PredictAtSample(const CtState<double>& state, const Eigen::Vector3d& m_B_Am2,
                                const GradiometerSample& sample, const TrackerOptions& options) {
  FieldPrediction p;
  PredictedField(state, m_B_Am2, sample.p_SinW, &p.B, &p.T);
  const double sb = SigmaB(sample, options), st = SigmaT(sample, options);
  p.snr = std::sqrt(p.B.squaredNorm() / (sb * sb) + p.T.squaredNorm() / (st * st));
  if (!std::isfinite(p.snr)) p.snr = 0.0;
  return p;
}

bool ForeignB(const Eigen::Vector3d& dB, const Eigen::Vector3d& B_hat, const Eigen::Matrix3d& T_hat, double sigma_B,
              double sigma_T, const TrackManagementOptions& mg) {
  if (!(mg.foreign_b_ratio > 0.0) || !(T_hat.norm() < mg.reach_tensor_snr * sigma_T)) return false;
  const double rb = (dB - B_hat).norm();
  return rb >= mg.gate_snr * sigma_B && rb > mg.foreign_b_ratio * B_hat.norm();
}

std::vector<TrackAssociation> AssociateEpoch(const Epoch& epoch, const std::vector<TrackPrediction>& predictions,
                                             const Eigen::Vector3d& B0_W, const MultiTrackerOptions& options) {
  const TrackManagementOptions& mg = options.management;
  const std::size_t n = epoch.samples.size();
  std::vector<TrackAssociation> out(predictions.size());
  for (std::size_t i = 0; i < predictions.size(); ++i) {
    TrackAssociation& a = out[i];
    a.mine.t_s = epoch.t_s;
    double fit_m2 = 0.0, fit_r2 = 0.0;  // the poor-fit test's sums without the others' samples
    int num_others = 0;
    // foreign_b_ratio acts on a track held by its tensor: seen at the
    // residual start's tensor SNR at one of the epoch's sensors.
    bool held = false;
    if (predictions[i].valid && mg.foreign_b_ratio > 0.0) {
      for (std::size_t j = 0; j < n; ++j) {
        held = held || predictions[i].at[j].T.norm() >= mg.residual_start.tensor_snr * SigmaT(epoch.samples[j], options.track);
      }
    }
    if (predictions[i].valid) {
      for (std::size_t j = 0; j < n; ++j) {
        const double st0 = SigmaT(epoch.samples[j], options.track);
        const double t_snr = predictions[i].at[j].T.norm() / st0;
        if (std::isfinite(t_snr)) a.max_tensor_snr = std::max(a.max_tensor_snr, t_snr);
        for (std::size_t k = 0; mg.reach_shared_b_snr > 0.0 && k < predictions.size(); ++k) {
          if (k == i || !predictions[k].valid || !(predictions[k].at[j].snr >= mg.gate_snr)) continue;
          const double b_snr = predictions[i].at[j].B.norm() / SigmaB(epoch.samples[j], options.track);
          if (std::isfinite(b_snr)) a.max_shared_b_snr = std::max(a.max_shared_b_snr, b_snr);
          break;
        }
        if (!(predictions[i].at[j].snr >= mg.gate_snr)) continue;
        GradiometerSample s = epoch.samples[j];
        Eigen::Vector3d B_others = Eigen::Vector3d::Zero();
        Eigen::Matrix3d T_others = Eigen::Matrix3d::Zero();
        bool any_other = false;
        for (std::size_t k = 0; k < predictions.size(); ++k) {
          if (k == i || !predictions[k].valid) continue;
          B_others += predictions[k].at[j].B;
          T_others += predictions[k].at[j].T;
          any_other = true;
        }
        if (any_other) {
          RemoveOtherFields(B_others, T_others, SigmaB(s, options.track), SigmaT(s, options.track), &s);
        }
        const double sb = SigmaB(s, options.track), st = SigmaT(s, options.track);
        const Eigen::Vector3d dB = s.B - B0_W;
        const FieldPrediction& p = predictions[i].at[j];
        // Whitened squared norms: the tensor's part alone (the tensor
        // evidence) and with B (the detection and poor-fit tests).
        const double mt2 = s.T.squaredNorm() / (st * st), rt2 = (s.T - p.T).squaredNorm() / (st * st);
        const double m2 = dB.squaredNorm() / (sb * sb) + mt2;
        const double r2 = (dB - p.B).squaredNorm() / (sb * sb) + rt2;
        const double own_t_snr = p.T.norm() / st;
        // Another source's B where this track is not seen in the tensor
        // (TrackManagementOptions::foreign_b_ratio): not this track's sample.
        if (held && ForeignB(dB, p.B, p.T, sb, st, mg)) {
          ++a.num_foreign;
          continue;
        }
        if (std::isfinite(mt2) && std::isfinite(rt2)) {
          a.tensor_llr += 0.5 * (mt2 - rt2);
          a.max_own_tensor_snr = std::max(a.max_own_tensor_snr, own_t_snr);
        }
        if (std::isfinite(m2) && std::isfinite(r2)) {
          a.llr += 0.5 * (m2 - r2);
          a.sum_m2 += m2;
          a.sum_r2 += r2;
          // Not this track's misfit: another source's tensor where this
          // track's own predicted tensor is weak.
          const bool others = own_t_snr < mg.poor_fit_tensor_snr && std::sqrt(rt2) >= mg.poor_fit_tensor_snr;
          if (others) {
            ++num_others;
          } else {
            fit_m2 += m2;
            fit_r2 += r2;
          }
        }
        a.mine.samples.push_back(std::move(s));
      }
    }
    // Explained share: a track whose prediction leaves most of a strong
    // signal unexplained (another, untracked source dominates its sensors,
    // or it has drifted off its vessel) is not detected but missed.
    // Without the samples where another source's tensor shows and the
    // track's own is weak (TrackManagementOptions::poor_fit_tensor_snr:
    // an untracked vessel too weak to start, beside the track), if any
    // sample is left; else over all.
    a.num_fit_samples = static_cast<int>(a.mine.samples.size()) - num_others;
    if (num_others == 0 || a.num_fit_samples <= 0) {
      a.num_fit_samples = static_cast<int>(a.mine.samples.size());
      fit_m2 = a.sum_m2;
      fit_r2 = a.sum_r2;
    }
    const double dof = 8.0 * static_cast<double>(a.num_fit_samples);
    a.poor_fit = dof > 0.0 && fit_r2 > mg.max_chi2_per_dof * dof && fit_r2 > mg.max_unexplained * fit_m2;
    a.detected = a.llr >= mg.detect_llr && !a.poor_fit;
    a.missed = a.llr <= -mg.detect_llr || a.poor_fit;
    a.tensor_evidence = !(mg.confirm_tensor_snr > 0.0) ||
                        (a.max_own_tensor_snr >= mg.confirm_tensor_snr && a.tensor_llr > 0.0);
  }
  return out;
}

TrackGate PredictGate(const CtState<double>& predicted, double t_s, const EpochEstimate* newest,
                      const MultiTrackerOptions& options) {
  TrackGate g;
  g.p_W = {predicted.x, predicted.y, predicted.z};
  g.valid = g.p_W.allFinite();
  if (newest == nullptr || !newest->usable || !newest->has_covariance || !newest->cov_state.allFinite()) {
    const double s = options.management.max_sigma_horizontal_m;
    g.cov_p_W = s * s * Eigen::Matrix3d::Identity();
    return g;
  }
  CtState<double> x;
  StateCovariance P;
  PropagateEstimate(*newest, t_s, options, &x, &P);
  g.cov_p_W = P.topLeftCorner<3, 3>();
  g.valid = g.valid && g.cov_p_W.allFinite();
  return g;
}

bool PropagateEstimate(const EpochEstimate& e, double t_s, const MultiTrackerOptions& options, CtState<double>* state,
                       StateCovariance* P) {
  if (!e.usable || !e.has_covariance || !e.cov_state.allFinite()) return false;
  const CtState<double> x{e.p_VinW.x(), e.p_VinW.y(), e.p_VinW.z(), e.speed_mps, e.heading_rad, e.turn_rate_radps};
  const double dt = t_s - e.t_s;
  *state = PropagateCoordinatedTurn(x, dt);
  const Eigen::Matrix<double, 6, 6> F = CoordinatedTurnJacobian(x, dt);
  const ProcessNoise& q = options.track.process;
  Eigen::Matrix<double, 6, 1> w;
  w << q.position_m_per_sqrt_s, q.position_m_per_sqrt_s, q.depth_m_per_sqrt_s, q.speed_mps_per_sqrt_s,
      q.heading_rad_per_sqrt_s, q.window_turn_rate_radps_per_sqrt_s;
  *P = F * e.cov_state * F.transpose();
  P->diagonal() += w.array().square().matrix() * std::abs(dt);
  return std::isfinite(state->x) && std::isfinite(state->y) && P->allFinite();
}

namespace {

// χ² and ln det S (S in m²) of a fix against a gate; false if S is not
// positive definite or the result not finite.
bool Innovation(const Evidence& fix, const TrackGate& gate, double* chi2, double* log_det) {
  if (!gate.valid || !fix.p_W.allFinite()) return false;
  Eigen::Matrix3d S = gate.cov_p_W;
  if (fix.cov_p_W.allFinite()) S += fix.cov_p_W;
  S = 0.5 * (S + S.transpose());
  const Eigen::LLT<Eigen::Matrix3d> llt(S);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::Vector3d d = fix.p_W - gate.p_W;
  *chi2 = d.dot(llt.solve(d));
  *log_det = 2.0 * llt.matrixL().toDenseMatrix().diagonal().array().log().sum();
  return std::isfinite(*chi2) && *chi2 >= 0.0 && std::isfinite(*log_det);
}

}  // namespace

double InnovationChi2(const Evidence& fix, const TrackGate& gate) {
  double chi2 = 0.0, log_det = 0.0;
  return Innovation(fix, gate, &chi2, &log_det) ? chi2 : std::numeric_limits<double>::infinity();
}

namespace {

// Union-find over tracks (0 … nt−1) and evidence (nt … nt+ne−1).
struct Components {
  std::vector<int> parent;
  explicit Components(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int Find(int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void Join(int a, int b) { parent[Find(a)] = Find(b); }
};

}  // namespace

EvidenceAssignment AssignEvidence(const std::vector<Evidence>& evidence, const std::vector<TrackGate>& gates,
                                  const Eigen::MatrixXd& tensor_snr, const TrackManagementOptions& mg) {
  const int nt = static_cast<int>(gates.size()), ne = static_cast<int>(evidence.size());
  if (tensor_snr.rows() != nt || tensor_snr.cols() != ne) {
    throw std::invalid_argument("AssignEvidence: tensor_snr must be tracks x evidence");
  }
  EvidenceAssignment out;
  out.track_of_evidence.assign(ne, -1);
  out.num_taken.assign(nt, 0);
  out.outbid.assign(nt, false);
  // Allowed pairs and their cost.
  Eigen::MatrixXd pair_cost = Eigen::MatrixXd::Constant(nt, ne, kForbidden);
  Components comp(nt + ne);
  std::vector<bool> gated(nt, false);
  for (int i = 0; i < nt; ++i) {
    for (int k = 0; k < ne; ++k) {
      if (!(tensor_snr(i, k) >= mg.evidence_min_tensor_snr)) continue;
      double chi2 = 0.0, log_det = 0.0;
      if (!Innovation(evidence[k], gates[i], &chi2, &log_det) || !(chi2 <= mg.evidence_gate_chi2)) continue;
      pair_cost(i, k) = chi2 + log_det;
      gated[i] = true;
      comp.Join(i, nt + k);
    }
  }
  // Clusters with at least one allowed pair.
  std::map<int, std::pair<std::vector<int>, std::vector<int>>> clusters;  // root -> (tracks, evidence)
  for (int i = 0; i < nt; ++i) {
    if (gated[i]) clusters[comp.Find(i)].first.push_back(i);
  }
  for (int k = 0; k < ne; ++k) {
    const int root = comp.Find(nt + k);
    if (clusters.count(root) > 0) clusters[root].second.push_back(k);
  }
  for (const auto& [root, members] : clusters) {
    const auto& [tracks, ev] = members;
    // One row per (track, sensor) slot the track has an allowed pair at.
    std::vector<std::pair<int, std::uint32_t>> slots;
    for (int i : tracks) {
      std::vector<std::uint32_t> sensors;
      for (int k : ev) {
        if (std::isfinite(pair_cost(i, k))) sensors.push_back(evidence[k].sensor_id);
      }
      std::sort(sensors.begin(), sensors.end());
      sensors.erase(std::unique(sensors.begin(), sensors.end()), sensors.end());
      for (std::uint32_t s : sensors) slots.emplace_back(i, s);
    }
    Eigen::MatrixXd cost = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(slots.size()),
                                                     static_cast<Eigen::Index>(ev.size()), kForbidden);
    double most = -std::numeric_limits<double>::infinity();
    for (std::size_t r = 0; r < slots.size(); ++r) {
      for (std::size_t c = 0; c < ev.size(); ++c) {
        if (evidence[ev[c]].sensor_id != slots[r].second) continue;
        cost(r, c) = pair_cost(slots[r].first, ev[c]);
        most = std::max(most, cost(r, c));
      }
    }
    // The same miss cost for every slot, above every allowed pair's: the
    // most pairs are made, and among those the likeliest.
    const GatedAssignment a = SolveGatedAssignment(cost, std::vector<double>(slots.size(), most + 1.0));
    for (std::size_t r = 0; r < slots.size(); ++r) {
      const int c = a.column_of_row[r];
      if (c < 0) continue;
      out.track_of_evidence[ev[c]] = slots[r].first;
      ++out.num_taken[slots[r].first];
    }
    ++out.num_clusters;
  }
  for (int i = 0; i < nt; ++i) out.outbid[i] = gated[i] && out.num_taken[i] == 0;
  return out;
}

EvidenceAssignment AssignEpochFixes(const Epoch& epoch, const std::vector<TrackPrediction>& predictions,
                                    const std::vector<TrackGate>& gates, const Eigen::Vector3d& B0_W,
                                    const MultiTrackerOptions& options, std::vector<std::size_t>* sample_of) {
  if (predictions.size() != gates.size()) throw std::invalid_argument("AssignEpochFixes: one gate per prediction");
  sample_of->clear();
  std::vector<Evidence> ev;
  for (std::size_t j = 0; j < epoch.samples.size(); ++j) {
    const auto f = SampleFix(epoch.samples[j], epoch.t_s, B0_W, options.track);
    if (!f) continue;
    ev.push_back({f->sensor_id, f->p_DinW, f->cov_p_DinW});
    sample_of->push_back(j);
  }
  Eigen::MatrixXd snr =
      Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(gates.size()), static_cast<Eigen::Index>(ev.size()));
  for (std::size_t i = 0; i < predictions.size(); ++i) {
    if (!predictions[i].valid) continue;
    for (std::size_t k = 0; k < ev.size(); ++k) {
      const std::size_t j = (*sample_of)[k];
      snr(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k)) =
          predictions[i].at[j].T.norm() / SigmaT(epoch.samples[j], options.track);
    }
  }
  return AssignEvidence(ev, gates, snr, options.management);
}

}  // namespace magnav::tracker
