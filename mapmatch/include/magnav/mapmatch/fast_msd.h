// Fast MSD matching (METHODS.md §5, after the fast-MSD paper) by Jacobi
// iteration, with re-linearisation rounds and an optional coarse stage.
//
// Units: positions and corrections e_i in degrees (lat, lon, used as a plane),
// map values m and measurements l in nT, gradients g in nT/deg, λ in nT²/deg².
//
// Each round linearises the map around the reference path r_i,
// m(r_i + e_i) ≈ m_i + g_i·e_i, and minimises
//   Σ (g_i·e_i + m_i − l_i)² + λ Σ |e_i − ē_i|²   (ē_i = mean of the neighbours' e)
// point by point: (λ I + g gᵀ) e_i = λ ē_i − g (m_i − l_i), whose exact solution
//   e_i = ē_i − g (g·ē_i + m_i − l_i) / (λ + |g|²)
// is the Jacobi update (the paper's printed eq. 15–16 drop the factor g in
// front of the fraction — not copied). The two end points have one neighbour.
// Iterate from e = 0 until the mean squared change < epsilon; then r ← r + e
// and re-linearise, for `rounds` rounds (or, once λ is at its final value,
// until a round's mean squared correction < epsilon). A point off the map (or with a bad measurement) has
// no data term: it follows its neighbours (e_i = ē_i) and is counted.
//
// Coarse stage (search_window_deg > 0): an MSD correlation search over
// ±window (correlation.h) first, and the rounds start from its shifted path.
#pragma once

#include <cstddef>
#include <string>

#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"

namespace magnav::mapmatch {

// How each round's linear equations are solved: the paper's Jacobi iteration
// (stops at epsilon_deg2), or directly (the same equations are block
// tridiagonal in path order: block Thomas elimination, O(N), the exact fixed
// point of the Jacobi iteration). Direct is the default: the same answer
// (tested) about 100x faster (a 200-point path in 50 µs instead of 5.7 ms,
// docs/BENCHMARKS.md); Jacobi is kept as the paper's method.
enum class FastMsdSolver { kJacobi, kDirect };

struct FastMsdOptions {
  FastMsdSolver solver = FastMsdSolver::kDirect;
  // Smoothness weight λ (nT²/deg²): ~1e7 suits the crustal reference map
  // (RMS gradient ≈ 1.2e4 nT/deg); larger = stiffer path.
  double lambda_nT2_per_deg2 = 1e7;
  // λ from the path's own noise and drift (issue 25 item 6; docs/ACCURACY.md,
  // "Fast MSD: the smoothing weight from the path's own noise and drift"):
  // the rounds' fixed point is the MAP of readings with noise σ² and
  // corrections that random-walk by τ² per point and axis when
  // λ/2 = σ²/τ² (fast_msd_covariance.h: Σ w r² + (λ/2) Σ |e_{i+1} − e_i|²),
  // so after the rounds (and the robust refit) σ² and τ² are estimated from
  // the solution (the covariance's EM, internal::EstimatePathScales), λ is
  // set to 2σ²/τ² clamped to [lambda_min, lambda_max], and the rounds run
  // again from the same start with it (the continuation scaled with it);
  // repeated up to lambda_from_path_iterations times, stopping once λ moves
  // by less than 1 %. The covariance then uses that λ; the notes say which
  // ("smoothing weight lambda ..."). Off: at 3 nT it lowers every set's mean
  // error by 21-30 % (held out 0.00116 -> 0.00088°), but held-out 626 at
  // 3 nT (its start 0.019° off) is re-solved into a wrong basin for its
  // first points, 0.00192 -> 0.00440°. 0 = off: lambda_nT2_per_deg2 as given.
  int lambda_from_path_iterations = 0;
  // The range the estimated λ is held to (nT²/deg²). The floor is the
  // default λ (1e7): the EM's σ² is biased low by the non-linear rounds'
  // closer fit (σ ≈ 0.3 nT for 0.5 nT readings, fast_msd_covariance.h), so
  // at low noise 2σ²/τ² (2e6-6e6) would loosen a smoother the 0.5 nT tuning
  // paths 501-520 do not gain from loosening (free, mean 0.00074 ->
  // 0.00075°, 510 above 0.001°); with the floor the estimate only ever
  // stiffens it. The ceiling is a guard against a degenerate EM (τ² → 0),
  // not a tuned value: 2σ²/τ² for σ ≤ 10 nT, τ ≥ 4.5e-5° per point.
  double lambda_min_nT2_per_deg2 = 1e7;
  double lambda_max_nT2_per_deg2 = 1e11;
  // Continuation (not in the paper): round k of R uses
  // λ · factor^((R − 1 − k)/(R − 1)), i.e. a stiffer path (closer to a pure
  // translation) while the linearisation is still far off, and λ itself in the
  // last round; 1 = the paper's constant λ. On the crustal reference paths a
  // constant λ overfits each point along its iso-line (mean error 0.0023° from
  // the coarse stage at 0.5 nT; 0.0007° with 100, docs/ACCURACY.md).
  double lambda_first_round_factor = 100.0;
  // Jacobi stop: mean squared change of e per iteration (deg²).
  double epsilon_deg2 = 1e-14;
  int max_iterations_per_round = 20000;
  // Re-linearisation rounds (the paper repeats the process three times from
  // 0.1°; five carry the λ continuation down in steps of 10^0.5).
  int rounds = 5;
  // A round needs this fraction of the usable points on the map.
  double min_on_map_fraction = 0.3;
  // Coarse MSD translation search ±window (deg) before the rounds; 0 = none.
  double search_window_deg = 0.0;
  // Coarse stage, ambiguity (issue 25 item 3): when the MSD surface's second
  // local minimum — at least peak_separation_deg (and 2 grid steps) from the
  // best in lat or lon — has an MSD below ambiguity_ratio × the best's, the
  // best may be the wrong peak: the result is not converged (reason
  // "ambiguous: ..."), the rounds also run from the second minimum, and the
  // covariance is the second moment, about the published path, of an equal
  // mixture of the two refined paths — unless the rounds from the second
  // minimum end where the best's did (mean over the points of dᵀΣ⁻¹d below
  // the 99 % point of χ²(2), 9.21: the same basin). The position stays the
  // best coarse minimum's. 2 lies beyond the 99.9 % quantile (≈ 1.7) of the
  // ratio of two MSDs of 150 points of the same noise (F(150, 150)); on the
  // 40 tuning paths (501–520, 0.5 and 3 nT) the second minimum was ≥ 4.3x
  // the best but on one (docs/ACCURACY.md). 0 = off.
  double ambiguity_ratio = 2.0;
  double peak_separation_deg = 0.003;
  // Robust residuals, in both stages (match_common.h): a reading outside the
  // map's range (± a quarter of it) has no data term at all; in each round a
  // residual m_i − l_i beyond outlier_sigmas · σ_l (σ_l = 1.4826·MAD of the
  // path's readings, at least 1 nT) has none that round (the point follows
  // its neighbours, as a point off the map does); after the rounds, a point
  // whose leave-one-out residual (its reading against the map where its
  // neighbours' matched positions put it) is beyond outlier_sigmas robust
  // sigmas of the others' is left out and the rounds run again once from the
  // same start (a point's own data term can bend the path onto a wrong
  // reading, its neighbours cannot). The coarse stage is the robust
  // correlation (correlation.h). Counted in MatchResult::points_outlier.
  // 0 = off (every point's squared residual counts, as in the paper).
  double outlier_sigmas = 5.0;
  // Covariance: the map's representation error in each reading's variance
  // (issue 25 item 4). The matcher reads the field between the grid's nodes
  // bilinearly; the field's curvature inside a cell is an error of the map,
  // not of the reading, and the rounds bend the path to follow it (the
  // residuals do not show it). With this on, each point's reading variance
  // in the covariance is σ² + b², b = (Δlat²/8)|∂²m/∂lat²| + (Δlon²/8)|∂²m/∂lon²|
  // the bilinear interpolant's error bound over the point's cell from the
  // grid's second differences at its nearest node (nT; no constant chosen).
  // It is also the size of the linearisation's error over half a cell (the
  // bilinear gradient jumps at cell edges), which on generated paths is where
  // its gain comes from (docs/ACCURACY.md, "Fast MSD: the map's own error in
  // the covariance": 0.5 nT every-point ANEES 5.32 -> 3.79 on the tuning
  // paths; the wrong-basin stretches it does not reach).
  // Changes the covariance only, never the positions. false = σ² alone.
  bool map_error_in_covariance = true;
  // The other basins (issue 25 item 4; mapmatch/src/fast_msd_basins.h,
  // docs/ACCURACY.md, "Fast MSD: the other basins in the covariance"). The
  // linearised covariance describes the basin the rounds ended in; a stretch
  // refined into a wrong local minimum of the map needs the others. With
  // basin_half_width_deg > 0 the posterior over offsets from the published
  // points (a grid of basin_step_cells × the map's step, ± the half width)
  // under the covariance's own model (σ², τ², map-error bound; no
  // linearisation) is computed by forward-backward along the path, and each
  // point's covariance gets the second moment of the posterior mass outside
  // its published basin (beyond the 99 % ellipse of the linearised one).
  // Changes the covariance only, and the positions through basin_mean_shift
  // (below). 0 = off (and no shift). At most 400
  // offsets each side: a wider half width for the map's step coarsens the grid.
  double basin_half_width_deg = 0.012;
  double basin_step_cells = 0.25;
  // The widest the offset grid grows to (deg; issue 25 item 6; docs/ACCURACY.md,
  // "Fast MSD: the posterior the offset grid truncated"): while the posterior's
  // mass on the grid's outermost ring reaches 1 % somewhere on the path, the
  // half width doubles (same step), up to this; the notes say "offset grid
  // widened to W deg". A posterior still at the edge then moves nothing
  // (basin_mean_shift). ≤ basin_half_width_deg = never widen (before
  // 2026-11-27). Default 0.048 (two doublings; within the coarse stage's
  // ±0.15° window): paths whose start lies beyond 0.012° of the truth.
  double basin_max_half_width_deg = 0.048;
  // Positions from the other basins (issue 25 item 6; docs/ACCURACY.md, "Fast
  // MSD: single paths above 0.001°"; needs basin_half_width_deg > 0): each
  // point moves to the mean of that posterior mixture — the published basin's
  // mass at the published point, the other basins' mass where it lies — i.e.
  // by far_mean = Σ_outside p(d) d (fast_msd_basins.h), and its covariance is
  // the mixture's second moment about the moved point, C_i + S_i − far_mean
  // far_meanᵀ (S_i the outside second moment; never narrower than C_i). Where
  // the posterior holds no mass outside the published basin nothing moves.
  // Nothing moves either when the posterior's mass on the offset grid's
  // outermost ring reaches 1 % at some point (the grid truncates it there, so
  // its mean is not the posterior's; notes: "not moved to the posterior mean").
  // Not applied when the result is ambiguous (ambiguity_ratio: the covariance
  // covers the second peak about the rounds' positions, as before). On by
  // default since 2026-11-26 evening: held-out paths 601-640 at 0.5 nT, every
  // path ≤ 0.001° (2 of 40 above before). false = the rounds' positions (the
  // covariance as above, about them).
  bool basin_mean_shift = true;
  // With basin_mean_shift: each point to the whole posterior's mean (issue 25
  // item 6; docs/ACCURACY.md, "Fast MSD: the single paths above the target
  // inside their basin"), Σ_all p(d) d over the offset grid — the published
  // basin's mass where the grid puts it, not at the published point —, i.e.
  // the posterior mean (MMSE point) of the covariance's model (σ², τ² from the
  // EM, the map-error bound) without linearising, where basin_mean_shift
  // moves only by the other basins' share. Its covariance: that posterior's
  // own second moment about μ (each grid cell's h²/12 per axis included;
  // capped at the search window's prior), not the linearised C_i of the
  // rounds' λ (at 3 nT the mixture about μ gave ANEES 0.74-0.93, below
  // [1, 4]). The same guards (not when ambiguous, not when the grid's edge
  // holds ≥ 1 %). Off: at 3 nT it lowers every set's mean error by 25-30 %,
  // but a few paths under the target rise above it (held-out 626 and 630 at
  // 3 nT, blind2 4501 at 0.5 nT; docs/ACCURACY.md). false = basin_mean_shift's move.
  bool basin_full_mean = false;

  bool IsValid(std::string* error) const;
};

// Positions: the rounds' path, each point then moved to the other basins' posterior mean (basin_mean_shift).
// iterations = Jacobi iterations over all rounds (direct solver: one per round); score = MSD (nT²) at the
// published points on the map, outliers left out; converged = every round's Jacobi met epsilon and the
// coarse stage's best minimum is not ambiguous (ambiguity_ratio).
// Covariance (MatchResult::cov_*, per point, deg² in (lat, lon)): the error
// covariance of the smoother (mapmatch/src/fast_msd_covariance.h) — the fixed
// point minimises Σ w_i (g_i·e_i + m_i − l_i)² + (λ/2) Σ |e_{i+1} − e_i|²
// (w = 1, ½ at the two ends) — under a model whose reading noise σ² and INS
// drift τ² (a random walk of the corrections, per point and axis) are
// estimated from the path (EM on the linearised model), not tied together by
// λ: M⁻¹ (Gᵀ W R W G + (λ/2)² τ² L) M⁻¹, M = Gᵀ W G + (λ/2) L, with R = σ²
// plus the second moment of the map's second-order term over the position error
// (the grid's curvature) and the map's bilinear interpolation error bound
// (map_error_in_covariance). Where that term's passes do not contract the point
// keeps its last contracting pass's term (notes: "curvature-limited points:
// K"); with a coarse stage no point's covariance is wider than the search
// window's uniform prior (w²/3 per axis; notes say at how many points it was
// capped). Plus the other basins (basin_half_width_deg): the second moment
// about the published point of the path's posterior mass outside each point's
// linearised basin (mapmatch/src/fast_msd_basins.h; notes: "other basins hold
// > 5 % of the posterior at K points"). Widened to cover a second peak when
// ambiguous (above). Calibration: docs/ACCURACY.md, "Trust: covariance
// calibration" and "Fast MSD: the other basins in the covariance".
MatchResult MatchFastMsd(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                         const FastMsdOptions& options = {});

}  // namespace magnav::mapmatch
