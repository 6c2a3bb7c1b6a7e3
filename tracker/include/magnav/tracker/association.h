// The multi-tracker's data associator (Stone Soup's composition, STYLE §13):
// given every live track's predicted field at each sample of one epoch, it
// decides which samples each track gets and scores whether the track's field
// is there. No state: one call per epoch (MultiTracker, step 2 and 3 of
// multi_tracker.h).
//
// Frames and units as tracker.h: world NED, metres, seconds, T, T/m.
//
//  - Gate: a track takes the samples where its predicted signal SNR =
//    √(‖B̂‖²/σ_B² + ‖T̂‖²/σ_T²) ≥ gate_snr ("its sensors").
//  - Joint model, track by track: each such sample is handed over minus the
//    predicted fields of the other tracks (RemoveOtherFields: their model
//    error widens its σ), so two vessels seen by one sensor share it.
//  - Score: LLR = ½ Σ (‖m‖² − ‖m − ẑ‖²) over its sensors (m: the whitened
//    sample minus B0 and the other tracks; ẑ: the whitened prediction).
//    Detected: LLR ≥ detect_llr and not a poor fit; missed: LLR ≤
//    −detect_llr or a poor fit (residual χ² > max_chi2_per_dof per residual,
//    8 per sample, and > max_unexplained of the signal energy); otherwise
//    unobserved.
//  - Evidence (AssignEvidence): the single-sample dipole fixes of the epoch
//    (the tracker's own TED+EGT fix of each strong sample one dipole
//    explains, initialize.h SampleFix; or a fix handed in by AddFix) are
//    estimates of one vessel's position each. Which live track each belongs
//    to, and which no track explains (the initiator's: a new-vessel
//    candidate), is decided for all of them at once: a global assignment
//    (tracker/assignment.h, the Hungarian method) per cluster of tracks and
//    fixes linked by their gates, of least total innovation χ², one fix to at
//    most one track and one track to at most one fix per sensor and epoch.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "magnav/core/gradiometer.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

// One track's predicted field at one sample, and its SNR (see above).
struct FieldPrediction {
  Eigen::Vector3d B = Eigen::Vector3d::Zero();  // T
  Eigen::Matrix3d T = Eigen::Matrix3d::Zero();  // T/m
  double snr = 0.0;
};

// A track's predictions at every sample of the epoch (in the epoch's sample
// order); `valid` false: the track has no prediction this epoch (it takes no
// sample and removes nothing from the others').
struct TrackPrediction {
  bool valid = false;
  std::vector<FieldPrediction> at;
};

// The prediction of a dipole track (state, body moment) at a sample, with
// the sample's σ (or the options' defaults: SigmaB, SigmaT) for the SNR.
FieldPrediction PredictAtSample(const CtState<double>& state, const Eigen::Vector3d& m_B_Am2,
                                const GradiometerSample& sample, const TrackerOptions& options);

// What one track got from the epoch.
struct TrackAssociation {
  Epoch mine;             // its samples (others' fields removed), at the epoch's time
  double llr = 0.0;       // log-likelihood ratio of its field being there
  double sum_m2 = 0.0;    // whitened signal energy over its samples
  double sum_r2 = 0.0;    // whitened residual energy over its samples
  // The samples the poor-fit test is over: all but those where another
  // source's tensor shows (TrackManagementOptions::poor_fit_tensor_snr),
  // or all if none would be left.
  int num_fit_samples = 0;
  // The tensor alone (TrackManagementOptions::confirm_tensor_snr): the
  // largest predicted tensor SNR ‖T̂‖_F/σ_T at any sensor of the epoch, the
  // largest at its own sensors, and ½ Σ (‖T‖² − ‖T − T̂‖²)/σ_T² over them.
  double max_tensor_snr = 0.0;
  double max_own_tensor_snr = 0.0;
  // Its largest predicted B SNR ‖B̂‖/σ_B at a sensor another valid track
  // gates (that track's predicted SNR ≥ gate_snr there); 0 if none, and 0
  // while its only user, TrackManagementOptions::reach_shared_b_snr, is off.
  double max_shared_b_snr = 0.0;
  double tensor_llr = 0.0;
  // Samples in its gate left out as another source's B
  // (TrackManagementOptions::foreign_b_ratio).
  int num_foreign = 0;
  bool tensor_evidence = false;  // max_own_tensor_snr ≥ confirm_tensor_snr and tensor_llr > 0 (or the rule off)
  bool poor_fit = false;
  bool detected = false;
  bool missed = false;
};

// TrackManagementOptions::foreign_b_ratio: whether a sample in a track's
// gate is another source's B — the track's predicted tensor T̂ below
// reach_tensor_snr σ_T there, and what its predicted B̂ leaves of the
// sample's dB = B − B0 (the other tracks' fields removed) at least gate_snr
// σ_B and more than foreign_b_ratio ‖B̂‖. False when the rule is off (0).
bool ForeignB(const Eigen::Vector3d& dB, const Eigen::Vector3d& B_hat, const Eigen::Matrix3d& T_hat, double sigma_B,
              double sigma_T, const TrackManagementOptions& mg);

// Per track (the order of `predictions`), its samples and score. Uses
// options.management's gate_snr, detect_llr, max_chi2_per_dof and
// max_unexplained, and options.track's default σ.
std::vector<TrackAssociation> AssociateEpoch(const Epoch& epoch, const std::vector<TrackPrediction>& predictions,
                                             const Eigen::Vector3d& B0_W, const MultiTrackerOptions& options);

// ---- Evidence assignment (issue 24 item 4) ----

// A track's predicted position at one instant, for the evidence gate:
// world NED, m; covariance m². `valid` false: the track takes no evidence.
struct TrackGate {
  bool valid = false;
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov_p_W = Eigen::Matrix3d::Zero();
};

// The gate of a track whose newest state is propagated to t_s (`predicted`,
// the engine's PredictState(t_s)): the covariance of `newest` (the track's
// newest estimate, taken at newest.t_s) propagated by the coordinated-turn
// model's Jacobian with the window's process noise (options.track.process;
// the window's turn-rate walk) over |t_s − newest.t_s|. Without a usable
// estimate with a covariance, an isotropic covariance of
// (max_sigma_horizontal_m)² (as uncertain as a live track may be) is used.
TrackGate PredictGate(const CtState<double>& predicted, double t_s, const EpochEstimate* newest,
                      const MultiTrackerOptions& options);

// An estimate's state and covariance propagated to t_s by the
// coordinated-turn model, its covariance by the model's Jacobian with the
// window's process noise (options.track.process, the window's turn-rate
// walk) over |t_s − e.t_s| — PredictGate's propagation. False without a
// usable estimate with a finite covariance, or if the result is not finite.
bool PropagateEstimate(const EpochEstimate& e, double t_s, const MultiTrackerOptions& options, CtState<double>* state,
                       StateCovariance* P);

// One piece of evidence: a fix (world NED, m) of one sample, with its
// covariance (m²; not finite: taken as exact, the track's covariance alone
// gates it).
struct Evidence {
  std::uint32_t sensor_id = 0;
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov_p_W = Eigen::Matrix3d::Zero();
};

// The innovation χ² of a fix against a gate: dᵀ (P_track + P_fix)⁻¹ d with
// d = fix − predicted position (3 dof). +inf if the sum is not positive
// definite.
double InnovationChi2(const Evidence& fix, const TrackGate& gate);

struct EvidenceAssignment {
  std::vector<int> track_of_evidence;  // per evidence: its track's index, or −1 (unexplained: the initiator's)
  std::vector<int> num_taken;          // per track: evidence it took
  // Per track: some evidence was in its gate, but all of it went to other
  // tracks (it explains it worse than they do).
  std::vector<bool> outbid;
  int num_clusters = 0;  // clusters solved (tracks and evidence linked by gates)
};

// Assigns the evidence to the tracks (`gates`, in the tracks' order).
// `tensor_snr(i, k)`: track i's predicted tensor SNR ‖T̂‖_F/σ_T at
// evidence k's sensor (at the evidence's time). A pair is allowed if
// tensor_snr ≥ management.evidence_min_tensor_snr and InnovationChi2 ≤
// management.evidence_gate_chi2; its cost is the pair's negative
// log-likelihood up to a constant, χ² + ln det S (S = P_track + P_fix in m²:
// a track with a wide covariance does not win a fix over a precise one at
// the same χ²). Tracks and evidence linked by allowed pairs form clusters,
// each solved by SolveGatedAssignment with one row per (track, sensor)
// slot — so a track takes at most one fix of each sensor and epoch, and each
// fix goes to at most one track — and one miss cost per slot, above every
// allowed pair's (as many pairs as possible are made; among those, the
// likeliest). With at most one fix per sensor (the tracker's own: one per
// sample) this splits by sensor: each fix goes to the likeliest track whose
// gates it passes.
// Throws std::invalid_argument if tensor_snr is not gates × evidence.
EvidenceAssignment AssignEvidence(const std::vector<Evidence>& evidence, const std::vector<TrackGate>& gates,
                                  const Eigen::MatrixXd& tensor_snr, const TrackManagementOptions& management);

// The epoch's own evidence assigned: each sample's single-sample fix
// (initialize.h SampleFix: strong, one dipole explains it; its first-order
// covariance), the tracks' tensor SNR at its sensor from `predictions` (in
// the epoch's sample order; an invalid one: 0), then AssignEvidence.
// `sample_of` gets, per evidence, its sample's index in the epoch. Throws
// std::invalid_argument if predictions and gates differ in number.
EvidenceAssignment AssignEpochFixes(const Epoch& epoch, const std::vector<TrackPrediction>& predictions,
                                    const std::vector<TrackGate>& gates, const Eigen::Vector3d& B0_W,
                                    const MultiTrackerOptions& options, std::vector<std::size_t>* sample_of);

}  // namespace magnav::tracker
