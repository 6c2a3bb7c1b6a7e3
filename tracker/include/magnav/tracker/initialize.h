// Track initialisation from single-sample fixes.
//
// Frames and units: world NED, metres, seconds, tesla, T/m, A·m², radians.
//
// Each strong sample (‖T‖_F ≥ min_tensor_snr · σ_T) gives a dipole position
// p_D = p_S − r by TED+EGT (see SingleSampleOffset) — or the fixes come from
// outside (magnav-inverter's gated fixes on magnav/dipole_fix, or the output
// of `magnav invert`), matched to the samples they were computed from;
// options.init.source chooses. A robust straight-line
// fit p(t) = p̄ + v (t − t̄) over the fixes within ±span_s/2 of the strongest
// signal gives position, speed and heading
// (turn rate 0); the body moment is the component-wise median of
// Rz(h)ᵀ m_W with m_W = FitDipoleMoment at each fix.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "magnav/core/motion.h"
#include "magnav/tracker/options.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

// Offset r_DtoS (m, dipole → sensor) from one sample by the inverter's scaled
// TED+EGT (magnav::inversion::SolveTedEgt with its default row weight).
// dB_W = B − B0 (T), T in T/m. nullopt if T = 0 or the result is not finite.
std::optional<Eigen::Vector3d> SingleSampleOffset(const Eigen::Vector3d& dB_W, const Eigen::Matrix3d& T);

struct InitialTrack {
  double t_ref_s = 0.0;    // time of `state`
  double t_first_s = 0.0;  // time span of the inlier fixes
  double t_last_s = 0.0;
  CtState<double> state{};  // straight-line state at t_ref_s (ω = 0)
  Eigen::Vector3d m_B_Am2 = Eigen::Vector3d::Zero();
  std::vector<DipoleFix> fixes;  // inliers used
  bool from_external_fixes = false;  // fixes handed in, not the tracker's own
  // Pair starts only (InitializePair, RefitPair): the covariance of `state`
  // (order [x y z v h ω], m, m/s, rad; ω's row and column 0: the line has no
  // turn) from the joint two-dipole fit at its solution (Gauss–Newton
  // information of the whitened samples, so σ_B, σ_T as the samples'):
  // `cov_state` with the partner's line and moment marginalised (what this
  // track's start is known to), `cov_state_given_partner` with them held
  // at the fit's values (what a track started on the samples minus the
  // partner's field would claim). Both with this track's own moment
  // marginalised. The difference is what the two fields' overlap at the
  // shared sensors costs.
  bool has_pair_covariance = false;
  StateCovariance cov_state = StateCovariance::Zero();
  StateCovariance cov_state_given_partner = StateCovariance::Zero();
};

// The tracker's own fix of one sample (taken at t_s): TED+EGT as
// SingleSampleOffset, if the sample is strong (‖T‖_F ≥ min_tensor_snr · σ_T)
// and one dipole explains it (InitOptions::max_dipole_misfit). Its snr,
// r_DtoS and cov_p_DinW (first-order, from the sample's σ_B, σ_T; m², world
// NED) are set. nullopt otherwise.
std::optional<DipoleFix> SampleFix(const GradiometerSample& s, double t_s, const Eigen::Vector3d& B0_W,
                                   const TrackerOptions& options);

// Fixes of every strong sample of the epochs (SampleFix of each).
std::vector<DipoleFix> StrongFixes(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                   const TrackerOptions& options);

// Fixes handed in from outside, matched to the samples they came from (same
// sensor, epoch time within options.epoch_tolerance_s), with tensor_snr set
// from that sample. Left out: a fix that is not valid, whose position or time
// is not finite,
// whose sample is not among the epochs, or whose sample is weak (‖T‖_F <
// min_tensor_snr · σ_T, as for the tracker's own fixes). Ordered by time, then
// sensor.
std::vector<DipoleFix> MatchFixes(const std::vector<Epoch>& epochs, const std::vector<DipoleFix>& fixes,
                                  const TrackerOptions& options);

// Initial track, or nullopt if there are too few fixes. `external_fixes`:
// fixes handed in from outside (nullptr = none has been). options.init.source:
// kAuto tries them first when given and falls back to the tracker's own fixes
// when they do not suffice (InitialTrack::from_external_fixes tells which
// were used); kExternal uses nothing else; kSamples ignores them.
std::optional<InitialTrack> InitializeTrack(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                            const TrackerOptions& options,
                                            const std::vector<DipoleFix>* external_fixes = nullptr);

// Two vessels close together that one dipole does not explain (issue 24
// item 2): a sensor between two vessels abreast sees the sum of their
// fields, its samples fail the dipole misfit gate
// (InitOptions::max_dipole_misfit) and give no fix, so InitializeTrack finds
// no line there. This fits two straight-line dipoles (constant depth and
// body moment each) at once to the samples within ±span_s/2 of the
// strongest such sample, on every sensor where it is strong (‖T‖_F ≥
// min_tensor_snr · σ_T, B and T whitened by the sample's σ): Gauss–Newton
// on the two lines (position, horizontal velocity; the moments by linear
// least squares at each step), started from the line through the mixed
// samples' own fixes split sideways by 4, 8, 12 and 16 m, and from that line
// with its velocity reversed and at rest, at least 3 m above the strongest
// mixed sample's sensor, split by 8, 16 and 24 m (on the approach the ghost
// line's own velocity and depth are wrong). Returned (two
// tracks, ordered by their y at t_ref) only if the pair explains the
// samples as a single dipole explains a clean one (√(Σr²/Σm²) ≤
// max_dipole_misfit), the two lines are at least `min_separation_m` apart
// horizontally, each one's own tensor reaches min_tensor_snr at one of the
// samples at least, and at least min_fixes such samples span min_span_s.
// Empty otherwise, or when max_dipole_misfit is 0 (off). Their `fixes` are
// empty (no single-sample fix went into them).
std::vector<InitialTrack> InitializePair(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                         const TrackerOptions& options, double min_separation_m);

// The same two-dipole fit refitted once the pair is tracked (issue 24): a
// pair started on the approach, where essentially one sensor sees both
// vessels, carries that start's error (its moment, and the partner's field
// it was started without) through its whole track. This fits the two
// straight-line dipoles again, started from the tracks `a` and `b` (their
// states propagated to the middle of `epochs`, their moments ignored:
// solved linearly), to every strong sample of `epochs` within three
// cluster gates (horizontally) of either line; `epochs` are the samples with
// every other track's field removed. The same gates as InitializePair's;
// the result in the order a, b, with t_ref the middle of the epochs. Empty
// if a gate fails. `report` (optional): what the fit found, whether or not
// its gates passed (PairFitReport).
struct PairFitReport {
  bool fitted = false;  // enough strong samples over min_span_s: the fit was made
  double misfit = 0.0;  // √(Σr²/Σm²) of the pair, as max_dipole_misfit
  double separation_m = 0.0;  // horizontal distance of the two lines at t_ref (m)
  double max_tensor_snr[2] = {0.0, 0.0};  // each dipole's own tensor SNR, at its strongest sample (a, b)
  double max_signal_snr[2] = {0.0, 0.0};  // each dipole's own field SNR (B and tensor whitened, as a track's gate), at its strongest sample
  InitialTrack line[2];  // the two fitted lines (state at t_ref, body moment), whether or not the gates passed
};
std::vector<InitialTrack> RefitPair(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                    const TrackerOptions& options, const InitialTrack& a, const InitialTrack& b,
                                    double min_separation_m, PairFitReport* report = nullptr);

// Why InitializeTrack gave no track, for a user: `have_external_fixes` as
// its external_fixes != nullptr.
std::string NoTrackMessage(const TrackerOptions& options, bool have_external_fixes);

// Effective sensor sigmas of a sample (the sample's, else the options').
double SigmaB(const GradiometerSample& s, const TrackerOptions& options);
double SigmaT(const GradiometerSample& s, const TrackerOptions& options);

}  // namespace magnav::tracker
