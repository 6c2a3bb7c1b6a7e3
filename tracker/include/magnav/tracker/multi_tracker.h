// Several vessels at once in a sensor field: track management (start,
// confirmation, coasting, end) and association around the single-track
// engines of tracker.h (WindowTracker per track; SolveBatch per track for the
// batch refinement).
//
// Frames and units as tracker.h: world = local NED (x north, y east, z down),
// metres, seconds, tesla, T/m, A·m² (body moment), radians.
//
// Its parts: the associator (association.h: steps 2 and 3), the track life
// cycle (track_life_cycle.h: confirmation and end rules of steps 5 and 6),
// each track's WindowTracker (step 4) and the initiator (step 5, here).
//
// Per epoch (the samples of every sensor at one instant):
//  1. Prediction: every live track's newest state is propagated to the epoch
//     and its field (B̂, T̂) predicted at every sensor from its own body moment.
//  2. Association: a track takes the sensors where its predicted signal
//     SNR = √(‖B̂‖²/σ_B² + ‖T̂‖²/σ_T²) ≥ gate_snr ("its sensors"); it is
//     given there the sample minus the predicted fields of the other live
//     tracks (a joint multi-dipole model solved track by track, so two
//     vessels seen by one sensor share it). A sensor no track reaches is not
//     given to any track.
//  2b. Evidence (association.h AssignEvidence): the epoch's single-sample
//     fixes (each strong sample one dipole explains, TED+EGT) are assigned
//     to the live tracks, one track per fix at most and one fix per sensor
//     per track, by a global assignment per cluster of least total
//     innovation χ² + ln det S, gated by χ² ≤ evidence_gate_chi2 and the
//     track's predicted tensor SNR at the fix's sensor ≥
//     evidence_min_tensor_snr. A tentative track whose gated fixes all went
//     to other tracks is not detected this epoch (one fix never confirms two
//     tracks); a sample whose fix a confirmed track took is not offered to
//     the initiator (step 5); a fix no track takes is.
//  3. Score: per track, the log-likelihood ratio of "this track's field is
//     there" against "it is not", over its sensors, with m the whitened
//     sample minus B0 and the other tracks and ẑ the whitened prediction:
//     LLR = ½ Σ (‖m‖² − ‖m − ẑ‖²). LLR ≥ detect_llr: detected; LLR ≤
//     −detect_llr: missed (the track predicts a field that is not there);
//     otherwise (far from every sensor) unobserved.
//  4. Update: each track's window gets its sensors' samples (none: it
//     coasts, its covariance grows with the motion model).
//  5. Start: the samples minus every track's prediction are buffered
//     (window_s long); every init_interval_s the single-track initialiser
//     (InitializeTrack: a robust line through strong single-sample TED+EGT
//     fixes, or through fixes handed in by AddFix) looks for a new vessel
//     there. A new track closer than min_separation_m to a live one is not
//     started. New tracks are tentative until confirm_m of their first
//     confirm_n epochs are detections (M-of-N) seen in the tensor too
//     (confirm_tensor_snr: B alone, which a far ship or a drift also
//     explains, does not confirm); a tentative track that cannot
//     reach that is dropped. Only confirmed tracks get a track_id (1, 2, …;
//     never reused) and produce estimates; a confirmed track's rows are
//     back-filled from its first strong epoch, later, from the smoothed
//     window (TrackManagementOptions::backfill_start, TrackState::kStart). Two vessels started together by
//     the two-dipole start (InitializePair) are refitted together once,
//     pair_refit_s later (RefitPair), and their engines started again from
//     that refit (TrackManagementOptions::pair_refit_s). A single start
//     within joint_start_s of another young track's start that shares a
//     sensor with it is fitted jointly with it at once (RefitPair) and the
//     two become such a pair (TrackManagementOptions::joint_start_s). When
//     nothing starts and a confirmed track's fit was poor within the last
//     init_interval_s (a vessel come close to it: an overtaking), the
//     two-dipole fit is tried beside it (pair_beside.h InitializeBeside, on
//     the last window_s of samples with every other track's field removed):
//     if it passes, the track's engine is started again from its line of the
//     fit (id and earlier rows kept) and the newcomer starts tentative, the
//     two partners as a pair start's (refitted pair_refit_s later; 0 turns
//     this off too).
//  Background (background.h): before step 2 every sample's B is corrected by
//     its sensor's background prior (its deviation from B0; its variance
//     added to σ_B²), and after step 3 each sensor's background takes the
//     residual B: the raw sample minus every live track's predicted B.
//  6. End: a confirmed track ends when it has been missed for max_miss_s in
//     a row, or out of the sensors' reach for out_of_reach_s ("out_of_reach":
//     outside their horizontal bounding box with a predicted tensor SNR below
//     reach_tensor_snr at every sensor), or not detected for max_coast_s, or its horizontal 1-σ exceeds
//     max_sigma_horizontal_m, or its window solve stays unusable for
//     max_miss_s, or it runs within min_separation_m of an older track for
//     max_miss_s (a duplicate; the younger ends) — not two tracks started
//     together by a two-dipole fit (partners), which found them apart.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "magnav/tracker/background.h"
#include "magnav/tracker/cluster_background.h"
#include "magnav/tracker/far_source.h"
#include "magnav/tracker/options.h"
#include "magnav/tracker/residual_start.h"
#include "magnav/tracker/tracker.h"
#include "magnav/tracker/variance_factor.h"

namespace magnav::tracker {

struct TrackManagementOptions {
  // A sensor is a track's when the track's predicted signal there has at
  // least this SNR (see above).
  double gate_snr = 3.0;
  // Per-epoch log-likelihood ratio of a detection (and, negated, of a miss).
  double detect_llr = 12.5;
  // Poor fit: an epoch whose whitened residual energy Σ‖m − ẑ‖² over the
  // track's sensors exceeds max_chi2_per_dof per residual (8 per sample)
  // and max_unexplained of the signal energy Σ‖m‖² counts as a miss: the
  // track explains too little of what its sensors see (an untracked vessel
  // dominates them, or it lost its own). On the reference field a tracked
  // vessel gives ≤ 4.4 per residual, a disturbed one ≥ 300.
  double max_chi2_per_dof = 25.0;
  double max_unexplained = 0.01;
  // Not in the poor-fit test: a sample where the track's own predicted
  // tensor SNR ‖T̂‖_F/σ_T is below this and the residual tensor ‖T − T̂‖_F/σ_T
  // reaches it (another source's tensor: an untracked vessel too weak to
  // start, beside the track), unless no sample would be left. 0 = off, every
  // sample (the default). At 6 it tracks the blind fresh_abreast2 file that
  // got no track but costs abreast RMS elsewhere (docs/ACCURACY.md, "Two
  // blind abreast files that got no track").
  double poor_fit_tensor_snr = 0.0;
  // A track does not take a sample in its gate where its own predicted
  // tensor SNR ‖T̂‖_F/σ_T is below reach_tensor_snr (it is seen there by
  // its B alone) and the B its prediction leaves there, ‖B − B̂‖ (the other
  // tracks' fields removed), is at least gate_snr σ_B and more than
  // foreign_b_ratio × ‖B̂‖: more than its whole field there is unexplained,
  // another source's B (an untracked vessel overtaking it, beyond the
  // reach or too weak to start) — not in its solve, its detection or its
  // poor-fit test. Only for a track held by its tensor at that epoch (its
  // predicted tensor SNR reaches residual_start.tensor_snr, 10, at one of
  // the sensors): a track at the reach's edge, seen by its B alone, keeps
  // its B samples. 0 = off (the default: on, it breaks
  // fresh_abreast4/abreast_31's window). docs/ACCURACY.md, "The overtaker's
  // B at the slow vessel's far sensors".
  double foreign_b_ratio = 0.0;
  // The initiator is not offered a sample whose residual tensor (the sample
  // minus every track's field) is below this share of the strongest track's
  // predicted tensor there: that residual is mostly the track's model error,
  // the seed of a ghost. (A new vessel that weak beside a tracked one waits
  // until it is farther from it.)
  double min_new_share = 0.2;
  // Confirmation: confirm_m detections among a tentative track's first
  // confirm_n epochs (with at least one sensor).
  int confirm_m = 8;
  int confirm_n = 10;
  // Tensor evidence for confirmation (issue 24 items 1 and 3: no ghost
  // track from a far ship's or a drifting background's B). A far source and
  // a drift change B at every sensor, and a dipole placed far enough away
  // explains such a B change; only a near vessel's tensor is seen. So an
  // epoch's detection counts toward a tentative track's M-of-N only if the
  // track's predicted tensor SNR ‖T̂‖_F/σ_T is at least confirm_tensor_snr
  // at one of its sensors and its tensor χ² there is reduced by it
  // (Σ ‖T‖² − ‖T − T̂‖², whitened, > 0). 0 = off (B alone may confirm).
  double confirm_tensor_snr = 3.0;
  // End rule "out_of_reach": a confirmed track whose predicted tensor SNR is
  // below reach_tensor_snr at every sensor while it is outside the sensors'
  // horizontal bounding box, for out_of_reach_s in a row, has left what the
  // array observes (a departing vessel): it ends then, not after coasting
  // for max_coast_s on B alone (which a far ship or a drift also explains).
  // Inside the box it is kept (a vessel crossing a cell centre returns
  // within reach). The batch's leading and trailing rows out of reach are
  // then not reported either (SolveBatchMulti; the batch still refines each
  // track over every sample where it is seen, past the reach too).
  // out_of_reach_s 0 = off. On by default (2 s) since 2026-11-26 (branch
  // reach): the far-ship and drift false rows from 9–52 % to ≤ 5 % on
  // most files (not all), no target met before lost; the window then
  // reports no coasting rows beyond the reach (docs/ACCURACY.md, "The end
  // rule beyond the reach by default").
  double reach_tensor_snr = 3.0;
  double out_of_reach_s = 2.0;
  // A departing track is kept within reach while its predicted B SNR
  // ‖B̂‖/σ_B is at least reach_shared_b_snr at a sensor another live track
  // gates (its field still in that track's samples: ended, it would no
  // longer be removed from them and would spoil that track's fit;
  // docs/ACCURACY.md, "Single passes and σ cells on the merged defaults",
  // overtaking). 0 = off (the tensor and the box only, as before 2026-11-27).
  double reach_shared_b_snr = 0.0;
  // The ghost field of a track ended out of reach: its field stays
  // subtracted from every epoch's samples (so from every other track's
  // samples, the initiator's buffer and the pair refits) — its newest
  // estimate propagated by the coordinated-turn model, moment as at its end —
  // while its predicted B SNR ‖B̂‖/σ_B is at least ghost_b_snr at some sensor
  // and for at most ghost_field_s after its end. It is not a track: no row,
  // no association, no event of its own. Its uncertainty widens the samples'
  // σ: the field's model error as another track's (kOtherFieldRelativeError)
  // in quadrature with its position covariance (the window's newest,
  // propagated with the window's process noise as the evidence gate's)
  // through the field's position Jacobian (B: −T; T: ≈ 4‖T‖/r). Dropped
  // too once a confirmed track is within min_separation_m of it (its vessel
  // tracked again). 0 = off; MultiTrackerOptions() sets 30 s, on (ACCURACY.md,
  // "The ended track's field subtracted as a ghost"; set before any run).
  double ghost_field_s = 0.0;
  double ghost_b_snr = 3.0;
  // Re-acquisition (reacquire.h): a newly confirmed track whose state
  // ([x, y, speed, heading], both propagated to its confirmation) gates a
  // confirmed track that ended at most reacquire_s before (not a
  // "duplicate"), by χ² (4 dof) ≤ reacquire_gate_chi2, with no other live
  // track closer to either, and whose first row comes after the ended
  // track's last, continues that track: it takes its id (its rows and
  // record, so the batch refines one path over both) instead of a new one.
  // The covariances are the rows' (scaled by the window's a-posteriori
  // variance factor, variance_factor.h). 0 = off; MultiTrackerOptions()
  // sets 30 s, on (the ghost field's 30 s; ACCURACY.md "Re-acquisition
  // keeps the id"); the gate is χ²(4) at 0.99.
  double reacquire_s = 0.0;
  double reacquire_gate_chi2 = 13.28;
  // End rules (s, m): see above.
  double max_miss_s = 2.0;
  double max_coast_s = 10.0;
  double max_sigma_horizontal_m = 5.0;
  double min_separation_m = 8.0;
  // The initiator runs once per this much data (s).
  double init_interval_s = 1.0;
  // Evidence assignment (association.h AssignEvidence; step 2b above): a
  // single-sample fix may go to a track only if its innovation χ² against
  // the track's predicted position (both covariances, 3 dof) is at most
  // evidence_gate_chi2 — 16.27, the 0.999 quantile of χ²(3): a true pair
  // fails it once in 1000 — and the track's predicted tensor SNR at the
  // fix's sensor, ‖T̂‖_F/σ_T, is at least evidence_min_tensor_snr (3, the
  // association gate on the tensor alone: a track that does not see that
  // sensor's tensor cannot explain its fix).
  double evidence_gate_chi2 = 16.27;
  double evidence_min_tensor_snr = 3.0;
  // A pair started together by the two-dipole start (InitializePair) is
  // refitted pair_refit_s (s) after its start, once the pair is better
  // observed: the two-dipole fit again (RefitPair) on the last window_s of
  // samples with every other track's field removed, started from the two
  // tracks; if it passes InitializePair's gates, both tracks' engines are
  // started again from it on those samples, each without the other's
  // refitted field. So the early start's moment, and the partner's field it
  // was started without, do not bias the whole track (docs/ACCURACY.md,
  // "Abreast from when they come within reach"). Tried while both are
  // confirmed, then once per init_interval_s until it passes or window_s
  // has gone by. 0 = off.
  double pair_refit_s = 5.0;
  // The refit's coupling in the refitted tracks' covariance (issue 24 item
  // 6): each refitted engine's window takes its partner's field as known
  // (its σ is the one given the partner), while the partner's estimate is
  // as uncertain as the two-dipole fit says. With this on, the refit's
  // excess — the line's marginal covariance in the joint fit minus the one
  // given the partner (InitialTrack::cov_state_given_partner), the start's
  // pair excess — is added to the refitted track's covariance (rows, gates,
  // end rules) for window_s after the refit, as the start's is until the
  // refit. On by default since 2026-11-27 (σ only: the scenario sets' rows
  // are identical; docs/ACCURACY.md, "Two young tracks abreast: the pair
  // refit's coupling in the window's σ"); false = the refitted engines' own
  // covariance, as before.
  bool pair_refit_excess = true;
  // Two vessels started one by one, close in time, that share a sensor
  // (issue 24, abreast_36): each single start is made with the other's
  // field unexplained at the shared sensors, and its moment and line carry
  // that through the whole track (the window's prior keeps the moment).
  // A single start made within joint_start_s (s) of another live track's
  // start, where both predicted signals reach gate_snr at one sensor at
  // least, is fitted jointly with it (RefitPair on the last window_s of
  // samples, every other track's field removed); if the fit passes
  // InitializePair's gates, the older track's engine is started again from
  // it and the new one is started from it, each without the other's field,
  // and the two are then a pair as if started together (pair refit,
  // partner, the joint fit's covariance excess). Otherwise the single start
  // goes on alone. 0 = off. 20 s (window_s): 5 s, the first value, left
  // fresh_abreast/abreast_28 (starts 6 s apart) failing (docs/ACCURACY.md,
  // "Two vessels started one by one: the joint start").
  double joint_start_s = 20.0;
  // A confirmed track's misses are excused while the two-dipole fit beside
  // it explains its samples with a newcomer seen (its field, B and tensor
  // whitened, at least confirm_tensor_snr at a sample, and its tensor
  // evidence as a tentative track's: at some sample its predicted tensor at
  // least confirm_tensor_snr and reducing the tensor χ² there) but its
  // tensor still below the beside start's SNR
  // (pair_beside.h, `waiting`; TrackLifeCycle::ExcuseMisses): the track
  // does not end "missed" before the vessel that spoils its fit can be
  // started beside it (issue 24, fresh_sigma2/overtaking_s2: the slow
  // vessel's track ended 0.5 s before the fast one's tensor reached the
  // beside start's 10 σ_T, and it got a second id; fresh_overtaking2/
  // overtaking_n14: the fast vessel's B spoiled the slow one's fit while its
  // tensor was 1–1.5 σ_T at the fit's samples, hence the field and not the
  // tensor alone; the tensor evidence, since a far ship's B alone also fits
  // a far second line). Needs pair_refit_s > 0
  // (the beside start) and confirm_tensor_snr > 0. On by default.
  bool excuse_beside = true;
  // The back-filled start (issue 24, branch coverage): a start needs
  // min_span_s of strong fixes and then confirm_m of confirm_n detections,
  // so a vessel's first rows came ≈ 6 s after its first strong sample (one
  // vessel of heldout_abreast/abreast_36 and of fresh_abreast/abreast_39
  // below the window coverage target for that alone). With backfill_start,
  // the confirmation of a track started by a two-dipole fit (a pair start,
  // a joint start, a start beside a track: its start explained its
  // neighbour's field) marks its start's epochs for output: from the
  // first epoch where its window predicts a tensor of at least the lowest
  // start SNR (residual_start.tensor_snr if on, else init.min_tensor_snr)
  // · σ_T at one of its sensors (a vessel started in the residual never
  // reaches the field's SNR: fresh_abreast4/abreast_31's vessel 2 was not
  // back-filled at all), but not before its start's first evidence (the first fix it
  // was started from; min_span_s before a two-dipole start, which has no
  // fix), to the newest epoch its engine solved while it was tentative
  // (those estimates were dropped; the live rows follow it). They are
  // output, TrackState::kStart, from the window as it is
  // window_s − init_interval_s after that first epoch (just before it
  // leaves the window; at once if that is past), or when the track ends:
  // the fixed-lag smoother's estimate with that lag, each with the window's
  // covariance — after a pair refit or joint start has restarted the
  // engine, its refitted estimate. So they come out of time order, up to
  // window_s late (the event of the confirmation says when). Only confirmed
  // tracks back-fill: no row of a track that is never confirmed. A single
  // start does not: its early window carries any neighbour's field it was
  // started without (on heldout/far_ship a ghost's 168 back-filled rows
  // were 11 m off, on fresh_overtaking/overtaking_a a vessel's 0.8 m off
  // with a σ of 2 cm). The DDS
  // node (magnav-tracker) turns it off: it publishes in time order and the
  // wire's TrackState has no value for such a row.
  bool backfill_start = true;
  // With backfill_start, a track made by a single start (one dipole, from
  // its own fixes) is back-filled too, from its first fix (issue 24,
  // branch winstart: the start's ≈ 6 s of min_span_s and confirm_m of
  // confirm_n are never output for a lone vessel, e.g.
  // fresh_farsrc2/far_ship_147's window coverage 0.77). Off by default.
  bool backfill_single = false;
  // A vessel too weak for the field's start SNR beside a tracked neighbour
  // (residual_start.h): a start in the residual at a lower SNR, jointly with
  // the neighbour; and the older track of a joint start back-filled.
  ResidualStartOptions residual_start;

  bool IsValid(std::string* error) const;
};

struct MultiTrackerOptions {
  MultiTrackerOptions();
  // Each track's engine. Differs from TrackerOptions' defaults in four
  // values: init.min_tensor_snr = kFieldInitSnr, so that a vessel crossing
  // a field gets a track before it is right above a sensor;
  // init.max_dipole_misfit = kFieldMaxDipoleMisfit;
  // window_solve_interval_s = kFieldSolveIntervalS: each track's window is
  // solved twice a second, not every epoch (on the reference field as
  // accurate, 3x cheaper; 100 sensors and 10 vessels need it to run in
  // 0.1 s of CPU per second of data: docs/BENCHMARKS.md); and
  // process.depth_weak_m_per_sqrt_s = kFieldDepthWeakMPerSqrtS: the depth
  // σ outside the reach and while coasting follows a depth-keeping vessel's
  // error (docs/ACCURACY.md, "Tracker σ over 20 draws, and the depth walk on
  // by default").
  TrackerOptions track;
  static constexpr double kFieldInitSnr = 20.0;
  static constexpr double kFieldSolveIntervalS = 0.5;
  // process.depth_weak_m_per_sqrt_s in a field, m/√s (chosen on the tuning passes t1–t3).
  static constexpr double kFieldDepthWeakMPerSqrtS = 3e-4;
  // init.max_dipole_misfit in a field (several vessels): a sample between
  // two vessels seeds no fix. Chosen on the tuning scenarios
  // (tests/data/generated/scenarios/tuning): the misfit of samples one
  // vessel dominates (the other's tensor < 10 % of it) is ≤ 0.047 at the
  // 99th percentile, 1 of 4300 above 0.05; 60 % of the mixed ones (the
  // other's tensor > 30 %) are above it (docs/ACCURACY.md).
  static constexpr double kFieldMaxDipoleMisfit = 0.05;
  TrackManagementOptions management;
  // Batch (SolveBatchMulti): refinement rounds; each solves every track over
  // its own samples with the others' fields (from the previous round)
  // removed, then grows each track's span outwards (below). At least this
  // many rounds (≥ 1); more while a span grows, up to kMaxBatchRounds.
  int batch_rounds = 2;
  static constexpr int kMaxBatchRounds = 6;
  // Batch: a track is refined over the samples of its span where its
  // predicted SNR √(‖B̂‖²/σ_B² + ‖T̂‖²/σ_T²) ≥ batch_gate_snr (1: every
  // sample that carries its signal; 3, the association gate, lost the far
  // B samples that hold a lone vessel's departure: 1.13 m RMS on a held-out
  // 6 m pass against 0.065 m). After each round its span (first to last
  // window estimate at the start) grows by at most batch_extension_step_s on
  // each side over the epochs where its refined trajectory, propagated past
  // its ends, predicts a tensor SNR ≥ batch_gate_snr at a sensor no other
  // track is seen at, in blocks of 1 s whose measured tensors agree with
  // the predicted ones (a matched filter: not where the vessel is not). So
  // the samples before its first detection and after its last are used. A
  // track ended as unusable or duplicate keeps its end; one ended by misses
  // grows at most 5 s past its last detection, on its tensor alone. Both > 0.
  double batch_gate_snr = 1.0;
  double batch_extension_step_s = 20.0;
  // Batch: each track's solve is also restarted from the window track that
  // found it (its states at every epoch, propagated past its ends; SolveBatch's
  // `starts`), kept if it ends at a cost lower by ≥ 1: the causal window,
  // which re-solves its turn rate as the data come, is a start from another
  // basin than the batch's own turn-rate restarts.
  bool batch_restart_from_window = true;
  // Batch: a track whose solve finds too few fixes at the field's start SNR
  // (track.init.min_tensor_snr, 20) to initialise — a vessel started in the
  // residual beside its neighbour (management.residual_start), whose tensor
  // never reaches 20 — is initialised again at the residual start's SNR
  // (ResidualStartTrackerOptions, 10), from the fixes its window track
  // gives (only its initialisation changes), and refined over its own
  // samples as any track: each round with the neighbour's refined field
  // removed, the neighbour's with its own (the rounds alternate, so the two
  // overlapping fields are fitted together), its span grown over every
  // epoch where it is seen. Off (or residual start off): such a track keeps
  // its window estimates, and its window field is what the neighbour's
  // refinement removes.
  bool batch_weak_init = true;
  // Batch: the Cauchy scale of the turn-rate changes in each track's solve,
  // in σ of one step (0 = track.process.turn_rate_loss_scale_sigma, 2, as
  // the window and the single-target SolveBatch). A 0.015 rad/s onset under
  // the batch's walk (3e-4 rad/s/√s) is ≈ 160 σ of a 0.1 s step: it costs
  // ≈ 17.5 (½ρ) at scale 2, ≈ 10.5 at 1.5, ≈ 5.1 at 1. Past ~15 m a lone
  // vessel's B fits a straight path that drifts sideways about as well as
  // the true turn, so at scale 2 the batch kept the straight path (the
  // fresh2 passes f20, f22–f24: 0.44–0.68 m within 30 m; from the truth the
  // same problem ended higher on f22 and f24: the model's choice, not a
  // local minimum); at 1.5 and at 1 they are ≤ 0.18 m. 1 broke the cluster
  // background's drifting-sensor batch (0.044 → 0.145 m, 18 false rows);
  // 1.5 keeps it (docs/ACCURACY.md, "The batch's turn onset cost"). ≥ 0.
  double batch_turn_loss_scale_sigma = 1.5;
  // Window and batch: the fields of the other tracks removed from a sample
  // are models, taken as uncertain by this share of their norm (per
  // element: the norm over √3 for B, over 3 for T), added in quadrature to
  // the sample's σ.
  static constexpr double kOtherFieldRelativeError = 0.05;
  // Batch: the other tracks' removed fields taken as uncertain by their own
  // covariance instead (each track's refined position and heading
  // covariance at the nearest epoch and its body moment's, propagated to
  // the field at the sensor to first order; no relative share; a track
  // without a covariance keeps kOtherFieldRelativeError), in quadrature with
  // the sample's σ. Changes the weights of the samples near another track,
  // hence the estimate and its σ. Default off (docs/ACCURACY.md, "The
  // batch's σ beside another vessel"); the window is unchanged.
  bool batch_other_field_covariance = false;
  // Batch: the share of their norm by which the other tracks' removed
  // fields are taken as uncertain (as kOtherFieldRelativeError; not with
  // batch_other_field_covariance). In [0, 1]. 0.05 by default, the window's;
  // 0.02 was measured with the batch's variance factor (docs/ACCURACY.md,
  // "The batch's variance factor": the conservative crossing and overtaking
  // inside cells accepted, their inside RMS 6–20 % higher) and is not the
  // default.
  double batch_other_field_relative_error = kOtherFieldRelativeError;
  // Window and batch: each sensor's background B0 is a state estimated
  // with the tracks (background.h); the B0 given to the tracker is its
  // start. Off (background.enabled = false): the fixed B0 everywhere.
  BackgroundOptions background;
  // Window and batch: each sensor's B0 offset estimated jointly with the
  // tracks that see it (cluster_background.h), one offset step per
  // window solve interval (window) and per refinement round (batch). Off
  // (cluster_background.enabled = false): the fixed B0. Not together with
  // `background` (one background model at a time).
  ClusterBackgroundOptions cluster_background;
  // Window and batch: a far ship as one dipole outside the array
  // (far_source.h), fitted over the recent samples minus the tracks'
  // predicted B; its B removed from every sample the tracks, the
  // association and the initiator see (its uncertainty added to σ_B). On by
  // default; far_source.enabled = false: nothing removed. Not together with
  // `background` or `cluster_background`.
  FarSourceOptions far_source;
  // Window: each track's reported covariance scaled by its window solve's
  // a-posteriori variance factor when the fit is poorer than chance allows
  // (variance_factor.h); only the rows' σ, not the gates. On by default.
  VarianceFactorOptions variance_factor;

  bool IsValid(std::string* error) const;
};

// What a confirmed track's estimate of one epoch rests on (the life cycle's
// words; a tentative track produces no estimate):
//  - kConfirmed: the track was detected at that epoch (the associator's
//    verdict, association.h: LLR ≥ detect_llr and not a poor fit);
//  - kCoasting: it was not (missed, or unobserved: no sensor within its
//    gate, or too weak a signal there): the estimate is the motion model's
//    prediction, corrected at most by samples too weak for a detection.
//    A confirmed track ends "lost" after max_coast_s of it;
//  - kStart: a back-filled row of the track's start
//    (TrackManagementOptions::backfill_start): the window's smoothed
//    estimate of an epoch before the track was confirmed, output later.
// Written per row by `magnav track` (column `state`).
enum class TrackState { kConfirmed, kCoasting, kStart };
const char* TrackStateName(TrackState state);  // "confirmed", "coasting", "start"

// One estimate of one track.
struct TrackOutput {
  std::uint32_t track_id = 0;
  EpochEstimate estimate;
  TrackState state = TrackState::kConfirmed;  // at estimate.t_s
  Eigen::Vector3d m_B_Am2 = Eigen::Vector3d::Zero();  // the track's body moment now
  Eigen::Matrix3d cov_m_B = Eigen::Matrix3d::Zero();
};

// A track's start or end, for logs.
struct TrackEvent {
  enum class Kind { kStarted, kEnded };
  Kind kind = Kind::kStarted;
  std::uint32_t track_id = 0;
  double t_s = 0.0;
  // Start: "confirmed (tentative since T s); from N dipole_fix fixes" (or
  // "... fixes of its own TED+EGT"; T its tentative start); end: "missed", "lost", "uncertain", "unusable", "duplicate",
  // "end of data".
  std::string reason;
};

// What became of one confirmed track (ended or still live).
struct TrackRecord {
  std::uint32_t track_id = 0;
  bool live = true;
  double t_start_s = 0.0;  // first estimate
  double t_end_s = 0.0;    // last estimate
  double t_last_detection_s = 0.0;
  std::string end_reason;  // empty while live
  int num_estimates = 0;
  Eigen::Vector3d m_B_Am2 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov_m_B = Eigen::Matrix3d::Zero();
  // The track started together with this one by the two-dipole start
  // (InitializePair; both confirmed), 0 = none: a second vessel abreast,
  // whose field SolveBatchMulti removes from this track's samples also
  // before and after its own span.
  std::uint32_t partner_id = 0;
  // The window's sensor offsets (SensorOffsetOptions::window_score_test):
  // the time of the first estimate from a solve with them (the score test
  // had fired), s; NaN while they are not solved.
  double t_window_offsets_s = std::numeric_limits<double>::quiet_NaN();
};

// The windows' turn-onset model (TrackerOptions::window_turn_onset_model):
// the engines' Summary counters (num_window_solves, num_turn_onset_*) summed
// over every track engine the tracker has run — live, ended, dropped or
// replaced by a restart. Counts, not times: they do not depend on the load.
struct TurnOnsetCounts {
  int window_solves = 0;     // window solves after the start
  int triggered = 0;         // ... whose trigger fired (before the noise test)
  int noise_vetoes = 0;      // triggers the noise test turned down
  int tries = 0;             // tries of the onset model
  int grid_searches = 0;     // ... that searched the grid (the rest: a carried onset)
  int chosen = 0;            // ... whose onset model was emitted
  int refused_jump = 0;      // ... refused by the jump's guard
  int candidate_solves = 0;  // onset candidates solved
  int iterations = 0;        // their Gauss-Newton iterations
  void Add(const Summary& s);
};

struct MultiSummary {
  int num_epochs = 0;
  int num_rejected_samples = 0;  // refused at the door (CheckSample)
  int num_tentative_dropped = 0;  // tentative tracks never confirmed
  int num_starts_refused = 0;     // initialisations too close to a live track
  int num_confirmed = 0;
  int num_ended = 0;
  // Cluster background (cluster_background.h): offset steps made, clusters
  // solved over them, their tracks in all, the largest cluster's tracks.
  int num_cluster_steps = 0;
  int num_clusters = 0;
  int num_cluster_tracks = 0;
  int max_cluster_tracks = 0;
  // Ghost fields made (TrackManagementOptions::ghost_field_s): tracks ended
  // out of reach whose predicted field was then subtracted.
  int num_ghosts = 0;
  // Tracks re-acquired (TrackManagementOptions::reacquire_s): newly
  // confirmed tracks that continued an ended track under its id (not in
  // num_confirmed; their earlier end not in num_ended).
  int num_reacquired = 0;
  // The confirmed tracks' approach taken out of the sensors' quiet samples
  // (SensorOffsetOptions::quiet_approach): samples dropped and corrected.
  // Not in the checkpoint (nor is the store).
  int num_quiet_approach_dropped = 0;
  int num_quiet_approach_corrected = 0;
  // The far source (far_source.h), when on: its fits accepted and refused,
  // the time its B was removed, its position at the last accepted fit. Not
  // in the checkpoint (nor is its fit): counted again after a restart.
  bool far_source_enabled = false;
  FarSourceStats far_source;
  // The windows' turn-onset model's work (all zero while it is off). Not in
  // the checkpoint: counted again after a restart.
  TurnOnsetCounts turn_onset;
  std::string BriefReport() const;
};

// Sliding-window tracking of every vessel of a field. Not thread-safe.
class MultiTracker {
 public:
  // Throws InputError if options are invalid or B0 is not finite.
  MultiTracker(const Eigen::Vector3d& B0_W, const MultiTrackerOptions& options);
  ~MultiTracker();
  MultiTracker(const MultiTracker&) = delete;
  MultiTracker& operator=(const MultiTracker&) = delete;

  // As WindowTracker::AddSample / AddEpoch / Flush: samples in time order,
  // a later time closes the current epoch. Returns the confirmed tracks'
  // estimates produced by it (in time order per track, but for the
  // back-filled start rows: TrackManagementOptions::backfill_start). A sample that fails
  // CheckSample is counted and skipped. Throws InputError if time goes back.
  std::vector<TrackOutput> AddSample(const GradiometerSample& sample);
  std::vector<TrackOutput> AddEpoch(const Epoch& epoch);
  // End of data: processes the pending epoch, solves what is pending, ends
  // every live track ("end of data").
  std::vector<TrackOutput> Flush();
  // A single-sample fix from elsewhere (magnav/dipole_fix) for the
  // initiator, as WindowTracker::AddFix — unless a live track explains it
  // (AssignEvidence at the fix's time, with the fix's cov_p_DinW; the
  // tracks' tensor SNR from its sample while that is in the epoch being
  // filled or the initiator's buffer, else the χ² gate alone): then it is
  // that track's evidence and dropped.
  void AddFix(const DipoleFix& fix);

  // Starts and ends since the last call.
  std::vector<TrackEvent> TakeEvents();
  // Every confirmed track so far, in track_id order.
  std::vector<TrackRecord> Tracks() const;
  int num_live_tracks() const;  // confirmed + tentative
  int num_ghost_fields() const;  // ghosts still subtracted (TrackManagementOptions::ghost_field_s)
  const MultiSummary& summary() const;
  // Sensor `sensor_id`'s background prior at t_s (B0 while the background
  // is off or the sensor not seen yet). World NED, T.
  BackgroundEstimate Background(std::uint32_t sensor_id, double t_s) const;
  // The far source's B plus the sensor's drift (T, world NED) that the next
  // epoch's sample `s` will have removed, and its σ per axis (T); zero while
  // the far source is off or has no fit.
  Eigen::Vector3d FarSourceB(const GradiometerSample& s, double* sigma_T) const;
  // The far source's current fit (valid = false: none).
  const FarSourceModel& FarSource() const;
  // The sensors' drift lines fitted with it (sensor_drift.h).
  const SensorDrift& Drift() const;

  // Checkpoint (tracker/checkpoint.h; docs/RELIABILITY.md): a payload with
  // the configuration it was made for (B0, every option the results depend
  // on) and everything that changes: the live tracks (confirmed and
  // tentative: ids, management state, each engine's window, states,
  // moment, prior and covariance; WindowTracker::SaveState), the records of
  // every confirmed track, the next id, the counters, the initiator's
  // buffer and fixes, the epoch being filled, the events not taken yet.
  // Every double bit for bit.
  std::string SaveState() const;
  // Into a multi-tracker made with the same B0 and options and fed nothing
  // (std::logic_error otherwise). Throws CheckpointError with the reason
  // (corrupt, truncated, made for other options) and leaves the tracker as
  // it was. Afterwards it goes on exactly as the saved one would: fed the
  // same samples from there, it gives the same estimates, bit for bit.
  void RestoreState(const std::string& payload);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// One track of a batch solve.
struct MultiTrackEstimate {
  std::uint32_t track_id = 0;
  TrackEstimate track;  // epochs, moment, summary (SolveBatch over the track's own samples)
  // One per track.epochs: kConfirmed where the refined track is detected
  // at that epoch — the associator's test (AssociateEpoch, association.h)
  // on the track's own samples with the refined state and moment —,
  // kCoasting where it is not. A track whose refinement failed keeps its
  // window estimates and their states.
  std::vector<TrackState> states;
};

// Every vessel of a pass: the window tracker finds the tracks (without the
// out_of_reach end rule, so a track is refined past the reach too), then each is
// refined by SolveBatch over its own samples (its sensors, over its span
// grown to every epoch where it is seen — batch_extension_step_s — the other
// tracks' fields removed within their spans, its partner's — the other
// vessel of a pair started abreast, TrackRecord::partner_id — also outside
// its span, in the problem and in the span's growth test), for batch_rounds
// rounds or more while a span grows. A track whose refinement fails keeps its window
// estimates (its summary says so). Its leading and trailing rows out of the
// sensors' reach (TrackManagementOptions::out_of_reach_s, reach_tensor_snr:
// outside their horizontal bounding box, predicted tensor SNR below
// reach_tensor_snr at every sensor) are not reported. Tracks in track_id order; none if no
// vessel was found. `progress`, if given, is called from the calling thread
// after every epoch of the window pass ("finding tracks", epochs done, of
// all) and before each track's refinement ("refining track N, round R", 0,
// 0): a long pass can say how far it is (magnav track). `finder_summary`, if
// given, gets the causal pass's summary (its far source's activity).
using BatchProgress = std::function<void(const std::string& stage, std::size_t done, std::size_t total)>;
std::vector<MultiTrackEstimate> SolveBatchMulti(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                                const MultiTrackerOptions& options,
                                                const std::vector<DipoleFix>* fixes = nullptr,
                                                const BatchProgress& progress = {},
                                                MultiSummary* finder_summary = nullptr);

// Predicted field of a dipole vessel at a sensor (T, T/m).
void PredictedField(const CtState<double>& state, const Eigen::Vector3d& m_B_Am2, const Eigen::Vector3d& p_SinW,
                    Eigen::Vector3d* B, Eigen::Matrix3d* T);

}  // namespace magnav::tracker
