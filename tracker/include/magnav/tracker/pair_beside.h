// A second vessel coming close to one that is already tracked (issue 24,
// overtaking): the pair start of initialize.h for the case where one of the
// two already has a track.
//
// Frames and units as initialize.h: world NED, metres, seconds, T, T/m, A·m².
//
// Why: while a track follows vessel A, a vessel B that comes within a few
// metres of it over the same sensors first shows as a small part of what
// those sensors see (its tensor 10–20 % of A's). Its single-sample fixes are
// mixed (InitOptions::max_dipole_misfit), the residual after A's prediction
// is masked as A's model error (TrackManagementOptions::min_new_share), and
// the part of B's field that A's window cannot absorb makes A's fit poor:
// A ends "missed" before B gets a track (held-out overtaking: the slow
// vessel's track ends at 34.5 s as the fast one closes to 15 m;
// docs/ACCURACY.md, "One vessel overtaking another").
//
// InitializeBeside fits two straight-line dipoles (RefitPair) to the
// samples with every other track's field removed, one started from the
// tracked vessel's line, the other from each of these in turn, the first
// that passes RefitPair's gates (the pair explains the samples as one dipole
// explains a clean one; lines ≥ min_separation_m apart; each dipole's own
// tensor reaches the init SNR) kept. The init SNR here (its samples and
// the strength gate) is 10, not the field's 20 (min of the two): what spoils
// the track's fit first is the newcomer's B, while its tensor is still weak
// (tuning overtaking: the slow vessel's track went poor at 35 s with the
// fast one 27 m behind, its tensor below 20 σ at every sensor; the fit then
// explained the samples to a misfit of 0.007, 37 m apart, and was refused
// by the strength gate alone). Kept:
//  1. the line InitializeTrack finds in the samples minus the track's own
//     predicted field (the newcomer's fixes, once the track's field is out),
//     if it is ≥ min_separation_m from the track;
//  2. the track's line shifted sideways by ±min_separation_m and, along it,
//     10 m behind at twice its speed or 10 m ahead at half its speed (a
//     vessel overtaking it, or one it overtakes).
// Returned: {the tracked vessel's refitted line, the newcomer's}, each with
// the joint fit's covariances (InitialTrack::has_pair_covariance); empty if
// no start passes.
//
// `seen_snr` and `waiting` (optional; issue 24, fresh_sigma2/
// overtaking_s2): when no start passes but one start's fit explains the
// samples (the misfit and separation gates pass, the tracked line strong)
// with the newcomer's own field seen (its B and tensor, whitened, ≥
// seen_snr at a sample, as a track's gate SNR) but its tensor below
// the init SNR above, *waiting is set: a vessel beside the track,
// too weak yet to be started, whose field spoils the track's fit. The
// multi-tracker then does not count the track's misses (TrackLifeCycle::
// ExcuseMisses) until the newcomer can be started. On overtaking_s2 the
// fit found the fast vessel 25 m behind the slow one 1.5 m from its true
// position (misfit 0.004) while its tensor was 7.6 and 9.9 σ_T, and the slow
// vessel's track ended "missed" (2 s of poor fits) before it reached 10.
// The newcomer is seen by its B too, not its tensor alone (fresh_overtaking2/
// overtaking_n14): there the fast vessel's B spoiled the slow one's fit from
// 43.6 s, 31 m behind it, while its own tensor was 1.1–1.5 σ_T; the fit
// explained the samples (misfit 0.018, the fast line 31 m away) with its
// field at 10.6–13.7 whitened. With the tensor rule the slow vessel's track
// ended "missed" at 45.5 s; with its field's, it coasts until the fast one
// is started beside it at 49 s. And its tensor where it is (branch n14b):
// B alone is also explained by a far dipole — the fit then puts its second
// line kilometres away or 90–150 m above the sensors with a moment of
// 1e6 A·m² (MultiTracker.FarShipArrivingWhileAnAuvIsTracked: a ship's B;
// FieldReference: a track's own model error as its vessel leaves), and the
// excused track coasted on a poor fit (RMS 0.06 → 0.87 m) — so the
// newcomer is seen only if, at some sample of `epochs`, its predicted
// tensor reaches seen_snr σ_T and reduces the tensor χ² of what the fit's
// tracked line leaves there, as a tentative track's tensor evidence for
// confirmation (overtaking_n14: 3.2–7.9 σ_T at 44–48 s, but 2.4 at 45 s;
// those far lines: ≤ 2.9 before the track ends "missed"; ≤ 1.5 in the ship test).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "magnav/tracker/initialize.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

// `epochs`: the samples with every track's field removed but the tracked
// vessel's; `tracked`: its line now (state at t_ref_s, moment); its own
// predicted field at each sample is `tracked`'s (for start 1).
std::vector<InitialTrack> InitializeBeside(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                           const TrackerOptions& options, const InitialTrack& tracked,
                                           double min_separation_m, double seen_snr = 0.0,
                                           bool* waiting = nullptr);

// The options of the beside fit: `options` with the init SNR (its samples
// and the strength gate) at most 10. The pair's later refit (the
// multi-tracker's RefitPairs) uses them too: at the field's 20 the
// newcomer's samples barely enter it (fresh_overtaking2/overtaking_n14: the
// refit 15 s after the start put the fast vessel's line 16 m off).
TrackerOptions BesideFitOptions(const TrackerOptions& options);

}  // namespace magnav::tracker
