// Options and solve summary of the dipole (vessel) tracker.
//
// Frames and units: world frame = local NED (x north, y east, z down), metres;
// time in seconds; B in tesla, T in tesla per metre; moment in A·m²; heading in
// radians from north, clockwise seen from above; turn rate in rad/s. Process
// noise is given as random-walk intensities, i.e. the 1-σ change per √s.
#pragma once

#include <string>

#include "magnav/core/loss.h"

namespace magnav::tracker {

// Robust loss applied to a whitened residual block (units of σ); shared with
// the localizer (core/loss.h).
using magnav::LossType;
using magnav::LossTypeName;
using magnav::ParseLossType;

// Coordinated-turn process model x_{k+1} = f(x_k, dt) + w, w ~ N(0, Q dt).
struct ProcessNoise {
  // Horizontal position random walk added to the coordinated-turn
  // prediction (x, y).
  double position_m_per_sqrt_s = 0.01;
  // Depth random walk (z): the model's only vertical motion (the state has no
  // vertical velocity). The default keeps the horizontal value (behaviour as
  // before the two were split). Outside the sensors' reach and while coasting
  // it makes the window's depth σ 2–6× the depth error of a depth-keeping
  // vessel; 3e-4 brings the held-out single passes' ANEES there within
  // [1.5, 6] (but h12's coasting, 1.44), yet costs
  // the reference AUV fluxgate pass accuracy (window RMS 0.107 → 0.170 m,
  // NEES above its χ² bound) and the crossing's window an overconfident
  // start: docs/ACCURACY.md, "Window σ when the data grow weak". So this
  // walk is used where the depth is observed, depth_weak_m_per_sqrt_s below
  // where it is not.
  double depth_m_per_sqrt_s = 0.01;
  // The depth walk (window and batch) from an epoch whose measured tensors are all weak
  // (every ‖T‖/σ_T < depth_weak_tensor_snr: the depth is not observed there)
  // to the next; 0 = depth_m_per_sqrt_s everywhere. A stiff walk only where
  // the data cannot move the depth keeps the depth σ from growing
  // past its error outside the reach and while coasting, and leaves the
  // strong part of a pass (where a loose walk forgets a start's depth error)
  // as it was (docs/ACCURACY.md, "The depth walk where the depth is not
  // observed"). Measured from the data alone, so a checkpoint restores it.
  // Off by default here, on in MultiTrackerOptions (kFieldDepthWeakMPerSqrtS,
  // so in `magnav track` and magnav-tracker). 3e-4 keeps every reference pass figure and brings 16 of
  // the 18 fluxgate σ cells of the held-out passes within [1.5, 6] (10 with
  // it off), but the batch's chain solver and Ceres then differ by 0.0089 σ
  // on the reference AUV fluxgate pass (the agreement test's bound: 0.001 σ);
  // not analysed yet.
  double depth_weak_m_per_sqrt_s = 0.0;
  double depth_weak_tensor_snr = 10.0;
  // Speed random walk.
  double speed_mps_per_sqrt_s = 0.005;
  // Heading random walk added to h + ω dt.
  double heading_rad_per_sqrt_s = 0.002;
  // Turn-rate random walk. Kept small so the turn rate is piecewise constant;
  // manoeuvre onsets (jumps in ω) are let through by the robust loss below.
  double turn_rate_radps_per_sqrt_s = 3e-4;
  LossType turn_rate_loss = LossType::kCauchy;
  double turn_rate_loss_scale_sigma = 2.0;
  // Batch warm-up: a first solve with this larger Gaussian turn-rate noise
  // (no robust loss) lets the track follow manoeuvres as smooth ramps; the
  // final solve then sharpens them into jumps. 0 = no warm-up pass.
  double turn_rate_warmup_radps_per_sqrt_s = 1e-3;
  // Turn-rate random walk of the sliding window, which replaces
  // turn_rate_radps_per_sqrt_s there: a causal fixed-lag solver cannot place
  // a manoeuvre onset it has not seen yet, so it needs a looser model to
  // follow the turn (same robust loss).
  double window_turn_rate_radps_per_sqrt_s = 3e-3;

  bool IsValid(std::string* error) const;
};

// Where the initialiser takes its single-sample fixes from.
enum class InitSource {
  // The tracker's own TED+EGT (the inverter's solver) on every strong sample.
  kSamples,
  // Only fixes handed in from outside: WindowTracker::AddFix (magnav-tracker
  // feeds it magnav-inverter's gated fixes from magnav/dipole_fix) or the
  // `fixes` of SolveBatch (magnav track --fixes). No fix, no track.
  kExternal,
  // The fixes handed in (once any has been, rejected ones included) when they
  // suffice to start a track, the tracker's own otherwise: never starts later
  // than kSamples. (magnav-inverter's default gates are strict — σ ≤ 5 cm per
  // fix — so on a fluxgate pass its fixes may be too few or span too short.)
  kAuto,
};

// Parses "samples" | "dipole_fix" | "auto"; false on anything else.
bool ParseInitSource(const std::string& name, InitSource* source);
const char* InitSourceName(InitSource source);

// Initialisation from single-sample fixes (TED+EGT).
struct InitOptions {
  InitSource source = InitSource::kAuto;
  // A sample gives a fix only if ‖T‖_F ≥ min_tensor_snr · σ_T (strong signal).
  double min_tensor_snr = 50.0;
  // At least this many fixes, spanning at least min_span_s, are needed.
  int min_fixes = 20;
  double min_span_s = 5.0;
  // Only fixes within ±span_s/2 of the strongest signal (largest running
  // median of the SNR over ±1 s, so a single bad sample cannot pick it) are
  // used, so that the straight-line fit stays valid on turning tracks.
  double span_s = 20.0;
  // Fixes farther than this many robust σ (1.4826·MAD) from the fitted line
  // are rejected; the line is refitted a few times.
  double outlier_threshold_mad = 4.0;
  // Several vessels at once: the line is first fitted to the fixes of the
  // sensor with the strongest signal only, and only fixes within this
  // distance (m) of that line are kept for the fit over every sensor, so
  // that fixes of other vessels elsewhere in the field do not enter it.
  // 0 = off (every fix in the span enters the fit).
  double cluster_gate_m = 10.0;
  // A single-sample fix is only made from a sample that one dipole
  // explains: with the dipole at the TED+EGT offset and its least-squares
  // moment (FitDipoleMoment), the whitened residual of the 8 rows (B and T)
  // must be at most this share of the whitened signal (√(Σr²/Σm²)). A sensor
  // between two vessels sees the sum of their fields; its fix falls between
  // them and would seed a ghost line. The sample still counts for nothing
  // in the choice of the strongest signal. 0 = off.
  double max_dipole_misfit = 0.0;
  // The part of every sample's σ_B that is an allowance for the fits (T per
  // axis), not the sensor's noise: the initiator's searches take it out in
  // quadrature — the single-sample fixes (SampleFix's one-dipole test and
  // covariance) and the two-dipole pair fits (InitializePair, RefitPair, and
  // their misfit gate); the single start's moment fit, the association and
  // the solves keep it. The multi-vessel tracker sets it to
  // FarSourceOptions::unexplained_sigma_T when that allowance is kept out of
  // the fix search (FarSourceOptions::unexplained_in_fix_search false).
  // 0 = none.
  double fix_sigma_B_allowance_T = 0.0;

  bool IsValid(std::string* error) const;
};

// Each track's solve given a per-sensor B offset as a nuisance (issue 24
// item 1, docs/ACCURACY.md "A per-sensor B offset in each track's solve"):
// instead of estimating each sensor's background from quiet samples, every
// sensor that gives a track's solve B samples gets its own offset o_s
// (3 components, world NED, T) added to B0 in those samples, constant over
// the window (window solve) or over one segment of segment_s (batch). B then
// informs the track through its variation across the window and across the
// sensors, which a near vessel dominates (hundreds of nT within seconds) and
// a drift of a few nT/min (≤ 2 nT over 20 s) barely touches.
//
// Two switches: `window` (each window solve; with it the association, the
// starts and the window's rows see the offsets through the window's
// estimates) and `batch` (each batch solve over the whole pass, where every
// track is known and the others' fields are taken out).
//
// The drift model gives the offset's zero-mean Gaussian prior, per axis:
//   σ_o(t) = √(floor_T² + (max_rate_T_per_s · max(0, t − b0_time_s))²)
// at the middle t of the window or segment (s, the samples' time base):
// a drift of at most max_rate since B0 held (b0_time_s: the start of the
// data, t = 0 in scenario files).
//
// Solved by alternation: after each solve every offset is set to its
// conditional mean given the track, Σ w_i r_i/σ_i² / (Σ w_i/σ_i² + 1/σ_o²)
// (r_i: the sample's B minus B0 minus the track's predicted B; w_i: the
// robust loss's weight ρ′ at the sample; σ_i its σ_B), and the track is
// solved again: `passes` rounds after each window solve, up to batch_passes
// after each stage of the batch's growing solve. In the batch one sensor's
// consecutive segment offsets are also joined by a random walk of σ
// StepSigma() per segment (a drift moves little between segments, a passing
// vessel's B a lot), and solved jointly per sensor. Each step lowers the
// joint cost (track, offsets, priors); the track's covariance is
// conditional on the offsets.
//
// The window's prior (the information of the samples that have left it) keeps
// only the tensor of a sample whose sensor has its own offset: the offset is
// solved again at every window solve, so the B level a leaving sample gave
// under the offset of that moment is not kept as the state's information
// (kept, it held the moment 7 % off at 55 σ on fresh_farsrc2/far_ship_105;
// docs/ACCURACY.md, "The window's prior without the offset sensors' B").
//
// carry (with window): each sensor's offset is a state carried
// from window to window with the drift's dynamics instead of being
// re-estimated from the zero-mean prior in every window. The samples that
// leave the window are folded into a per-sensor Gaussian (mean, variance per
// axis, at their time; their residual at the track's estimate when they
// leave), and the window's offset of that sensor gets it as its prior, its
// variance grown by (max_rate_T_per_s · Δt)² over the Δt from that time to
// the window's middle. A drift of a few nT/min is followed; a level the
// window's samples alone would give (a vessel's slow B) must agree with
// what the sensor gave before. A sensor with nothing carried yet keeps the
// zero-mean prior. Per track (each window tracker carries its own).
//
// min_tensor_snr (window and batch, with either switch; 0 = every sensor): a sensor
// gets an offset only where the track's predicted tensor SNR ‖T̂‖_F/σ_T
// reaches this at one of its samples in the window (batch: in the solved
// span) at the current estimate: there the tensor pins the track, while
// where the tensor is weak B is the only information and an offset takes it.
// At the other sensors the window's samples do not move the offset: the
// window keeps the carried one (with carry; none without), the batch none.
// quiet (with window; MultiTracker only): each sensor's offset is
// owned by the sensor, not the track: the multi-tracker keeps, per sensor,
// the samples it gave while it was quiet (no live track's predicted tensor
// SNR ≥ 3 and predicted B ≥ 3 σ_B there, no untracked near source in its
// residual tensor — the single sample's and its quiet_tensor_mean_s mean's
// gates, tracker/src/quiet_sample.h — over the last quiet_span_s of such
// samples), and every track's window gets that sensor's offset as its prior:
// the per-axis median of those samples' residual B (sample − B0 − the tracks'
// predicted B − the far source's, world NED, T), σ the median's spread
// (1.2533 · 1.4826 · MAD/√n, the largest axis) widened by a random walk at
// max_rate_T_per_s over the time from the samples' median time to the
// window's middle. A sensor below min_tensor_snr takes the quiet offset as
// it is (not the carried one); one above takes it as the prior of the
// window's own estimate. A sensor with fewer than quiet_min_samples quiet
// samples keeps the rule without it. Not in the checkpoint (a restored
// tracker starts the store empty). Off by default (docs/ACCURACY.md, "One B
// offset per sensor, owned by the sensor").
// quiet_rate (with quiet): each sensor's quiet offset is a line in time,
// level + rate · (t − t_ref) (world NED, T and T/s), fitted robustly over the
// last quiet_rate_span_s of its quiet samples (the store keeps at least that
// much): the rate from the medians of the store's older and newer halves,
// bounded by max_rate_T_per_s; the level the median of the samples with the
// rate taken out; predicted to the window's middle, its σ² = σ_level² +
// (σ_rate · Δt)² growing with the extrapolation Δt (tracker/src/
// quiet_offset.h). A drift's ramp is followed while the sensor is occupied
// instead of held at the level of samples tens of seconds old.
// quiet_approach (with quiet): when a track is confirmed, its back-predicted
// field is taken out of every sensor's stored quiet samples: a sample where it
// would have made the sensor not quiet (its predicted tensor SNR ≥ 3 or B ≥
// 3 σ_B) is dropped, the others lose its predicted B — the vessel's approach,
// before it had a track, leaves the sensors' offsets.
// The window's offsets, carry, quiet and the lines are off by default; the batch's
// offsets are on, behind their score test (docs/ACCURACY.md: the measured rows).
struct SensorOffsetOptions {
  // The window's off by default; the batch's on, with its score test
  // (docs/ACCURACY.md, "The batch's sensor offsets, where its B residuals
  // call for them").
  bool window = false;
  bool batch = true;
  // With batch: the batch is solved without offsets first, and solved again
  // with them only when its B residuals call for them — the score test of the
  // segment offsets at zero: χ² = Σ over (sensor, segment) of the robust
  // score ‖Σ w r/σ²‖² / Σ w/σ² of its samples' B residuals r at the solution
  // (w the robust loss's weight there: n ‖ē‖² of the whitened residuals when
  // every w is 1; a gross outlier weighs as little as in the solve), against
  // the TrackerOptions::batch_variance_factor.quantile point of χ² with 3 dof
  // per (sensor, segment). Without a drift the offsets cost information (with
  // one gradiometer its B level and the track's range trade off: f13's RMS
  // 0.050 → 0.357 m with 20 s segments and 8 rounds, the offsets solved
  // unconditionally), and the B residuals say there is nothing to explain.
  bool batch_score_test = true;
  // With batch: after the alternation (the offsets given the track, the track
  // given the offsets, up to batch_passes rounds from each stage), one joint
  // solve of the track and every (sensor, segment) offset as parameter blocks
  // of one problem, from the alternation's end — the optimum at which the
  // covariance (the offsets marginalised) is computed. Where the track's range
  // and its sensors' offsets are held by the same few samples (a departure
  // beyond the reach) the alternation stops short of it (docs/ACCURACY.md,
  // "The batch's offsets solved jointly with the track").
  bool batch_joint = true;
  // With window (or window_lines): a track's window is solved without
  // offsets until its B residuals call for them — the same score test as
  // the batch's (batch_score_test), per sensor over the window (3 dof per
  // sensor), after each window solve, at the TrackerOptions::
  // batch_variance_factor.quantile point — and with them from the solve
  // where it first fires to the track's end (latched: the drift that fired
  // it does not leave). Off by default: the window's offsets, when on, are
  // solved from the start (docs/ACCURACY.md, "The window's offsets behind
  // the batch's score test").
  bool window_score_test = false;
  // With window_score_test (needs it): the test latches only once
  // it has fired at every window solve for this long (s; 0 = at its first
  // firing). Until it latches the window keeps, beside its prior, a second
  // one folded from the leaving samples' tensors alone, which becomes the
  // window's prior at the latch: the B levels of the samples that left
  // before the latch, under the drift that fires it, do not stay in the
  // prior (a plain delay kept them: heldout/drift's mean NEES 27). Two
  // tracked AUVs abreast 20 m apart without a drift (heldout_abreast/
  // abreast_20) fire the test for a few seconds after their pair start: with
  // 3 s their rows are 0.299 / 0.202 m RMS (0.495 / 0.352 m latched at once,
  // 0.193 / 0.168 m without the offsets), with 5 s it does not latch there;
  // but each second of delay costs drift rows (over the 34 scenario sets, 0 /
  // 3 / 4 / 5 s: 27 / 24 / 22 / 20 of 44 drift rows meet every target).
  // 0 by default (docs/ACCURACY.md, "The drift flags as the window's
  // defaults: measured, not merged").
  double window_score_persist_s = 0.0;
  bool carry = false;
  double min_tensor_snr = 0.0;
  bool quiet = false;
  double quiet_span_s = 20.0;
  int quiet_min_samples = 50;
  double quiet_tensor_mean_s = 10.0;
  bool quiet_rate = false;
  double quiet_rate_span_s = 60.0;
  bool quiet_approach = false;
  double max_rate_T_per_s = 6e-9 / 60.0;
  double floor_T = 1e-9;
  double b0_time_s = 0.0;
  // Batch: the offsets' segment length, s (the window's offset spans the window).
  // 10 s since 2026-11-28 (session 22; 20 s before): a ramp is followed by a
  // constant per segment, and what is left (± rate · segment_s / 2, ±0.7 nT
  // at 4 nT/min over 20 s) is a bias the model does not have (heldout/drift,
  // one run: 20 s RMS inside 0.039 m, NEES 6.1; 10 s 0.025 m, NEES 1.2;
  // 5 s 0.024 m, NEES 1.1).
  double segment_s = 10.0;
  // Rounds after each solve (window) or each batch stage (the batch stops
  // early once no offset moves by more than tolerance_T).
  int passes = 2;
  // 40: the alternation converges slowly from a batch a drift has pulled
  // (heldout/drift: 8 rounds RMS 0.076 m, NEES 17.6; 40 and 100 rounds
  // 0.039 m, NEES 6.1 — the tolerance stops it before 100).
  int batch_passes = 40;
  double tolerance_T = 0.1e-9;
  // Window only: each sensor's offset in each track's window solve is a line
  // in time over the window — a level (T, world NED, at the window's middle
  // time) and a rate (T/s) — instead of a constant. An untracked vessel
  // 20–40 m from a track's sensors (an overtaker beyond the tensor reach,
  // seen there by its B alone) changes its B at a sensor by tens of nT
  // within the 20 s window; a constant offset takes out its mean only
  // (docs/ACCURACY.md, "The slow vessel's window RMS while an untracked
  // overtaker closes"). On by itself it turns the window's offsets on (the
  // batch follows `batch` alone). The level's prior is PriorSigma's, the rate's zero-mean with
  // σ line_rate_sigma_T_per_s per axis. The window's published covariance
  // (its rows, re-acquisition, the association's gates) has the lines
  // marginalised (tracker/src/offset_marginal.h: the lines are solved by
  // alternation, and the track's covariance given them leaves out what they
  // took), and its variance factor reads residual means per quarter of the
  // window (WindowTracker::ResidualMeansChi2; docs/ACCURACY.md, "The window
  // offsets' uncertainty in the window's σ"). Off by default; not with carry.
  bool window_lines = false;
  double line_rate_sigma_T_per_s = 5e-9;
  // Whether the window solves offsets at all (enabled or window_lines).
  bool WindowOffsets() const { return window || window_lines; }

  // The prior σ (T, per axis) at time t_s.
  double PriorSigma(double t_s) const;
  // Batch: consecutive segments' offsets of one sensor are joined by a random
  // walk of this σ per step (T, per axis): max_rate_T_per_s · segment_s, the
  // most the drift moves in one segment, floored at floor_T/10.
  double StepSigma() const;
  bool IsValid(std::string* error) const;
};

// The a-posteriori variance factor (tracker/variance_factor.h): the window's
// (MultiTrackerOptions::variance_factor) and the batch's
// (TrackerOptions::batch_variance_factor) options.
struct VarianceFactorOptions {
  // On by default (docs/ACCURACY.md, "The a-posteriori variance factor"):
  // over 20 draws it moves the window's overconfident overtaking cells into
  // [1.5, 6] and fails no cell that passed. Off: covariances as the window
  // solve gives them.
  bool enabled = true;
  // The factor applies when χ²/dof exceeds this quantile of χ²_dof/dof
  // (0.99: a fit this poor happens by chance once in 100 solves). In (0, 1).
  double quantile = 0.99;
  // The factor is at most this (≥ 1): a bound against a diverged solve.
  double max_factor = 1e4;
  // What χ² and dof are:
  //  - kResiduals: every whitened residual of the window's samples (white
  //    noise assumed): χ² = 2·final_cost, dof = 8·samples (WindowVarianceFactor
  //    from the Summary; no pass over the samples);
  //  - kSensorMeans: the per-sensor means of the whitened residuals over the
  //    window, χ² = Σ_j n_j ‖ē_j‖², dof = 8·sensors
  //    (WindowTracker::ResidualMeansChi2): a slowly varying unmodelled field
  //    is a bias over the window's n_j samples, and shifts the estimate as
  //    much as n_j independent errors would, which this χ² counts (the white
  //    χ² sees it once per sample). One more evaluation of the window's
  //    measurement factors per solve.
  enum class Statistic { kResiduals, kSensorMeans };
  // kSensorMeans by default: on the held-out overtaking's window (3 draws)
  // the inside ANEES 60.8 → 3.02 with it, → 38.7 with kResiduals
  // (docs/ACCURACY.md).
  Statistic statistic = Statistic::kSensorMeans;

  bool IsValid(std::string* error) const;
};

struct TrackerOptions {
  // Sensor noise used when a sample carries sigma 0 (unknown).
  double default_sigma_B_T = 1e-9;
  double default_sigma_T_Tpm = 1.4e-9;
  // Tensor noise model: symmetric trace-free (the diagonal elements share a
  // −1/2 correlation because their noise sums to zero, as in the reference
  // data) when true, independent elements when false.
  bool tensor_noise_trace_free = true;

  // Robust loss on the 8-vector measurement residual of one sample, in σ of
  // its norm (a clean sample has ‖e‖ ≈ √8 ≈ 2.8). Cauchy: the influence of a
  // gross outlier vanishes (∝ a²/‖e‖), clean samples keep weight ≥ ~0.9.
  LossType measurement_loss = LossType::kCauchy;
  double measurement_loss_scale_sigma = 10.0;

  ProcessNoise process;
  InitOptions init;

  // Samples whose times differ by at most this belong to one epoch (s).
  double epoch_tolerance_s = 1e-6;

  // Batch solver.
  int max_num_iterations = 100;
  double function_tolerance = 1e-8;
  // Tolerance of the passes that only give a starting point (warm-up,
  // robust-loss continuation, batch spans before the whole pass). Kept as
  // tight as the final one: with 1e-6 the warm-up stopped early on the AUV
  // pass with outliers and the final pass missed the turn onset (0.95 m RMS).
  double intermediate_function_tolerance = 1e-8;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-10;
  int num_threads = 1;

  // Solver of the batch passes and of the window's first solve (same problem
  // either way). kChainLevenbergMarquardt: Levenberg-Marquardt with Ceres'
  // step rules whose damped normal equations are solved by block-tridiagonal
  // elimination of the chain of states plus the shared moment (O(N) per
  // iteration); kCeres: ceres::Solve with SPARSE_NORMAL_CHOLESKY (general
  // sparse Cholesky, slower on long passes; kept as the reference).
  enum class BatchSolver { kChainLevenbergMarquardt, kCeres };
  BatchSolver batch_solver = BatchSolver::kChainLevenbergMarquardt;

  // Batch: the pass is solved first over the initialiser's span, then over
  // spans grown by this factor (new epochs predicted from the span's ends)
  // until every epoch is included; > 1.
  double batch_growth_factor = 3.0;
  // Batch: the turn-rate model (a random walk with a robust jump) has local
  // minima where a turn of steps in ω is followed as a slow drift of too
  // small a turn once the data grow weak. After the solve the batch is
  // restarted from its own estimate with ω_k replaced by its least-squares
  // piecewise-constant fit with 1, ..., batch_turn_change_points change
  // points (positions, speeds, headings and the moment kept); a restart is
  // kept only if it ends at a cost of the same problem lower by at least 1
  // (½ Σ ρ, in σ²). 0 = none.
  int batch_turn_change_points = 2;
  static constexpr int kMaxBatchTurnChangePoints = 4;
  // Batch: the covariance is that of the chosen restart (conditional on its
  // turn-rate change points). If true, the spread of the other restarts'
  // ends about it, weighted by exp(−Δcost) (model averaging), is added to
  // every state's covariance; false: the conditional covariance alone.
  bool batch_model_spread = true;

  // Sliding window: fixed lag (s) and iterations per new epoch.
  double window_s = 20.0;
  int window_max_num_iterations = 4;
  // The window is solved once per this much data (s); the epochs that came
  // in between get their estimates from that solve (a lag of at most this
  // long). 0 = after every epoch (the single-vessel default).
  double window_solve_interval_s = 0.0;
  // Relative cost change that ends a window solve (the window starts from
  // the previous solution, so a loose tolerance loses nothing).
  double window_function_tolerance = 1e-4;
  // Window: a second turn-rate model tried after every window solve (a
  // two-model choice; docs/ACCURACY.md, "The window's turn onset as a model
  // choice"). The default window's turn rate is a loose random walk
  // (process.window_turn_rate_radps_per_sqrt_s), which spreads a turn's onset
  // over the window as a ramp, so the newest heading lags the turn. The
  // onset model is the batch's stiff walk (process.turn_rate_radps_per_sqrt_s,
  // same robust loss) with one free jump of ω at an onset time chosen on a
  // grid inside the window; it is solved on the same window (same prior,
  // samples and kinematic factors) from the default solution, and its newest
  // states and covariance are emitted instead of the default's if its data
  // cost (prior + measurements, ½ Σ ρ in σ²) exceeds the default's by at
  // most window_turn_onset_bic_params · ½ ln n, n the number of measurement
  // residuals in the window (BIC: the default's walk taken as that many more
  // free parameters than the onset model). The window itself
  // (marginalisation, prediction, association) keeps the default model.
  bool window_turn_onset_model = false;
  // Grid of onset times (s) inside the window (the window's first and last
  // 1 s are not tried; "no onset" always is).
  double window_turn_onset_grid_s = 1.0;
  // Δk of the BIC comparison (see window_turn_onset_model).
  double window_turn_onset_bic_params = 1.0;
  // Gauss-Newton iterations of each onset candidate's solve.
  int window_turn_onset_iterations = 8;
  // Which onsets are tried (docs/ACCURACY.md, "The window's turn onset: cheap
  // and guarded"). kFull: every grid point (from 1 s after the window's
  // front) and "no onset", after every window solve, each from the default
  // solution. kFast: the grid at whole multiples of window_turn_onset_grid_s
  // (so an onset stays on it as the window slides), no "no onset" candidate.
  // The trigger: the default solution's turn rate spans more than
  // window_turn_onset_trigger_sigmas × the stiff walk's σ over the window
  // (process.turn_rate_radps_per_sqrt_s · √(window span), rad/s). If the
  // previous try's best onset is still on the grid and was chosen (or the
  // trigger fires), that onset and one neighbour (alternate sides from try
  // to try; on along that side while the farther one is best), each started
  // from the previous try's best solution (a warm start); else, if the
  // trigger fires, every window_turn_onset_coarse_grid_s, then both
  // neighbours of the best (on while an edge is best), from the default
  // solution; else nothing is solved and the default is emitted.
  enum class OnsetSearch { kFull, kFast };
  OnsetSearch window_turn_onset_search = OnsetSearch::kFast;
  double window_turn_onset_trigger_sigmas = 3.0;
  // 1 s (= the grid: every onset once per turn event); 3 s, the first
  // value, moved the onset found on f27 (0.244 → 0.309 m, docs/ACCURACY.md).
  double window_turn_onset_coarse_grid_s = 1.0;
  // The onset model is emitted only if its jump of ω at the onset is
  // significant: |Δω| ≥ this × σ_Δω, σ_Δω² = the onset model's marginal
  // variances of ω on the two epochs either side of the onset, summed (their
  // covariance left out). 3: χ²(1 dof) at 0.9973, i.e. a 5 % family-wise
  // level over the ≈ 19 onsets of a 20 s window (Bonferroni: 9.1 ≈ 3²).
  // 0 = no guard (session 16's rule; with "no onset" as the best candidate
  // the onset model is then emitted without a jump).
  double window_turn_onset_jump_sigmas = 3.0;
  // The trigger's noise test (kFast; docs/ACCURACY.md, "The window's turn
  // onset at scale: the trigger fires on the default's own noise"): 0 = off
  // (session 17's trigger). > 0: a trigger counts only if the default's turn
  // rate span ω_hi − ω_lo (rad/s) is also at least this × √(σ_stiff² + σ_lo² +
  // σ_hi²), σ_stiff the stiff walk's σ over the window (as above) and σ_lo,
  // σ_hi the default solution's marginal σ of ω at the two epochs of the
  // span's ends (chain selected inversion, prior included; their covariance
  // left out). Where the data hold ω weakly (a vessel 12 m or more from the
  // sensors, or beside another vessel whose removed field is in its samples)
  // the default's ω wanders by more than 3 σ_stiff on a straight course.
  double window_turn_onset_trigger_noise_sigmas = 0.0;

  // Per-epoch window update: kChainGaussNewton = Gauss-Newton steps solved
  // by block-tridiagonal elimination of the chain (O(window) per step, with
  // backtracking and the robust weights of the factors); kCeres = a Ceres
  // solve of the window problem (slower, same problem). The first window
  // solve (initialisation) uses batch_solver.
  enum class WindowSolver { kChainGaussNewton, kCeres };
  WindowSolver window_solver = WindowSolver::kChainGaussNewton;

  // Compute the covariance of the estimate (marginal covariance of every
  // state and of the moment at the solution, robust weights applied).
  bool compute_covariance = true;
  // kChain: exact block-tridiagonal selected inversion exploiting the chain
  // structure (O(N)); kCeres: ceres::Covariance (SPARSE_QR, slower for long
  // passes; batch only, the window always uses kChain).
  enum class CovarianceMethod { kChain, kCeres };
  CovarianceMethod covariance_method = CovarianceMethod::kChain;

  // A per-sensor B offset in each track's window and batch solve (off).
  SensorOffsetOptions sensor_offset;

  // Batch: the a-posteriori variance factor per epoch (variance_factor.h,
  // SlidingVarianceFactors; docs/ACCURACY.md, "The batch's variance
  // factor"). An unmodelled field in a batch's samples (a sensor's drift, a
  // far ship's field the far source left, another vessel's) biases its
  // estimate while the covariance, conditional on the model, stays as if the
  // samples were clean: each state's covariance is scaled by χ²/dof of the
  // per-sensor mean whitened residuals over the batch_variance_factor_span_s
  // centred on its epoch where that exceeds the quantile's point (never
  // below 1), and the moment's by the whole pass's. Residuals are clipped at
  // measurement_loss_scale_sigma first. Only σ changes. On by default
  // (the window's defaults): over 20 draws the drift cells' ANEES 1279 /
  // 1952 → 2.5 / 3.1 and far-ship's 6.7 / 30 → 1.2 / 1.7 (inside / outside
  // the reach), single passes, crossing and abreast unchanged.
  VarianceFactorOptions batch_variance_factor;
  // > 0, s: the span (the window's 20 s by default: the same question over
  // as much data as the window's factor asks it).
  double batch_variance_factor_span_s = 20.0;
  // Whether batch_variance_factor also scales a track whose sensor offsets
  // were solved (SensorOffsetOptions::batch, its score test fired). On by
  // default. Off: there the B misfit the factor stood in for is modelled and
  // the offsets' uncertainty is marginalised in the covariance, and what the
  // factor then reads beside a far ship is mostly the ship's tensor (below
  // the noise per sample, a bias over the span's 200 samples) that barely
  // moves a near track: the far ship's σ cells, conservative with it (ANEES
  // 1.18 / 1.29 inside / outside the reach over 20 draws), are accepted
  // without it (1.85 / 1.91; blind draws 101–120 1.75 / 1.67). But it also
  // removes the factor where the offsets took another vessel's B and the
  // track is still pulled: over 25 scenario sets the overconfident batch rows
  // (> 1 m and > 5 σ off) go 1051 → 1157, overtaking_swbs11's slow vessel
  // 1.0–1.4 m off at 20–30 σ (docs/ACCURACY.md, "The batch's variance factor
  // on top of its solved offsets, or not"). So it stays on.
  bool batch_variance_factor_with_offsets = true;

  bool IsValid(std::string* error) const;
};

// What a solve did.
struct Summary {
  bool initialized = false;  // a track was started
  bool usable = false;       // the solver returned a usable solution
  bool converged = false;    // ... and its last pass met a convergence tolerance
                             // (false: stopped at max_num_iterations, or a
                             // window update found no descent step)
  int num_epochs = 0;        // epochs in the problem
  int num_samples = 0;       // gradiometer samples in the problem
  int num_init_fixes = 0;    // fixes kept by the initialiser
  bool init_from_external_fixes = false;  // ... handed in (AddFix / SolveBatch's fixes)
  int iterations = 0;
  double initial_cost = 0.0;  // ½ Σ ρ(‖r‖²), r in σ
  double final_cost = 0.0;
  double solve_time_s = 0.0;
  double covariance_time_s = 0.0;
  double total_time_s = 0.0;
  bool covariance_ok = false;
  // Samples refused at the door (core CheckSample: non-finite time, field,
  // tensor, position or σ; all-zero tensor), never seen by the solver: for a
  // batch, in its input; for a window, since the tracker was made.
  int num_rejected_samples = 0;
  // Window: factors left out of a marginalisation because they could not be
  // evaluated at the estimate (non-finite), since the tracker was made.
  int num_dropped_factors = 0;
  // Batch: the largest variance factor applied to a state's covariance (1:
  // none), and at how many epochs it was > 1
  // (TrackerOptions::batch_variance_factor).
  double max_variance_factor = 1.0;
  int num_variance_factor_epochs = 0;
  // Batch: the score test of the sensor offsets (SensorOffsetOptions::
  // batch_score_test): its χ² and dof on the solve without offsets (dof 0:
  // not run), and whether the offsets were solved.
  double offset_score_chi2 = 0.0;
  int offset_score_dof = 0;
  bool offsets_solved = false;
  // Batch: restarts from a piecewise-constant turn rate tried, and kept
  // because they ended at a lower cost (TrackerOptions::batch_turn_change_points).
  int num_turn_restarts = 0;
  int num_turn_restarts_kept = 0;
  // Window: solves after which the turn-onset model was tried, and chosen
  // (TrackerOptions::window_turn_onset_model), since the tracker was made.
  int num_turn_onset_tries = 0;
  int num_turn_onset_chosen = 0;
  // Window, the onset model's cost: candidate solves and their Gauss-Newton
  // iterations; tries whose best onset's jump was not significant
  // (window_turn_onset_jump_sigmas), since the tracker was made.
  int num_turn_onset_candidate_solves = 0;
  int num_turn_onset_iterations = 0;
  int num_turn_onset_refused_jump = 0;
  // Window, where the fast search's tries come from, since the tracker was
  // made: window solves after the start (each may try the onset model);
  // solves whose trigger fired (window_turn_onset_trigger_sigmas, before the
  // noise test); triggers the noise test turned down
  // (window_turn_onset_trigger_noise_sigmas); tries that searched the grid
  // (the trigger fired and no carried onset was on the grid; every try of
  // the full search). The other tries started from a carried onset.
  int num_window_solves = 0;
  int num_turn_onset_triggered = 0;
  int num_turn_onset_noise_vetoes = 0;
  int num_turn_onset_grid_searches = 0;
  // Batch: candidate ends whose spread entered the covariance with a weight
  // > 1e-12 (TrackerOptions::batch_model_spread; the chosen one included).
  int num_model_spread_candidates = 0;
  std::string message;  // Ceres termination message or failure reason

  std::string BriefReport() const;
};

}  // namespace magnav::tracker
