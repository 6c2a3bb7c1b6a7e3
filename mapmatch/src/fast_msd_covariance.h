// Internal: the covariance of a fast-MSD solution (fast_msd.h), by the
// Laplace approximation of the cost its fixed point minimises.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

namespace magnav::mapmatch::internal {

// The fast-MSD fixed point (fast_msd.cc DirectRound) solves, per point,
//   (λ I + g gᵀ) e_i − λ ē_i = −g r_i      (ē_i: mean of the neighbours' e)
// Multiplied by each point's number of neighbours d_i (2 inside, 1 at the
// ends) these are the normal equations of
//   Σ_i w_i (g_i·e_i + r_i)² + (λ/2) Σ_{i} |e_{i+1} − e_i|²,   w_i = d_i / 2,
// a Gaussian measurement model (noise σ²) with a random-walk prior on the
// corrections. Its posterior precision at the solution is
//   P = (Gᵀ W G + (λ/2) L) / σ²   (L: the path graph's Laplacian),
// block tridiagonal (2 × 2 blocks). This returns, per point, the 2 × 2
// diagonal block of σ² P⁻¹ with σ² estimated from the residuals at the
// solution: s² = Σ w r² / (Σ w − edf), edf = Σ w gᵀ C g the smoother's
// effective number of parameters (C = the unscaled block of P⁻¹·σ²), the
// usual correction for a linear smoother's fit to its own data (the
// non-linear rounds still fit closer: at 0.5 nT it gives σ ≈ 0.3 nT,
// docs/ACCURACY.md).
//
// Inputs per point (all the same size n >= 2): g_lat, g_lon (nT/deg) and
// resid (nT) at the solution; data = 0 for a point without a data term
// (off the map, bad or outlying reading). λ in nT²/deg².
// Output per point: cov (lat lat, lat lon, lon lon), deg²; *s2_out = s² (nT²),
// *edf_out = edf. Without any data term the covariance is infinite.
struct PathCovariance {
  std::vector<double> lat_lat, lat_lon, lon_lon;
  double s2_nT2 = 0.0;
  double edf = 0.0;
};
PathCovariance FastMsdCovariance(const std::vector<double>& g_lat, const std::vector<double>& g_lon,
                                 const std::vector<double>& resid, const std::vector<char>& data, double lambda);

// The covariance fast MSD writes (docs/ACCURACY.md, "At 0.5 nT"): the error
// covariance of the fixed-λ smoother above under a model whose two scales are
// estimated from the path itself, plus the map's curvature.
//  - Model: readings y_i = g_i·e_i + n_i, n_i ~ N(0, σ²); the corrections e
//    (the INS error) a random walk of τ² per step and axis. The smoother's λ
//    ties its prior to the noise (τ² = 2σ²/λ), which at low noise is far
//    tighter than the INS drift it has to follow: the error there does not
//    shrink with σ, and σ²(Gᵀ W G + (λ/2) L)⁻¹ does.
//  - σ², τ²: maximum marginal likelihood of the linearised model (EM, from
//    the residual σ² above and τ² = 2σ²/λ; pseudo-observations
//    y_i = g_i·ê_i − r_i with ê the solution's corrections from the start).
//  - Error covariance of the smoother with its own λ (a sandwich):
//      M⁻¹ (Gᵀ W R W G + (λ/2)² τ² L) M⁻¹,  M = Gᵀ W G + (λ/2) L,
//    R = diag(σ² + v_i), v_i = ½ tr((H_i C_i)²) + ¼ tr(H_i C_i)² the second
//    moment (variance plus squared mean) of the map's second-order term
//    ½ δᵀ H_i δ over the position error δ ~ N(0, C_i)
//    (H_i: the map's Hessian at the point, nT/deg²; C_i this covariance,
//    iterated `curvature_iterations` times from v = 0).
//  - The curvature passes must contract. v_i grows as C_i² and C_i with v_i:
//    roughly C ∝ (σ² + v)/|g|², so v ≈ a (σ² + v)² with a ~ |H|²/|g|⁴, which
//    has no fixed point once 4 a σ² > 1 — where the map's curvature is large
//    against its gradient (near an extremum or a saddle) the loop gains more
//    than 1 and the passes diverge (they wrote σ up to 2e8° on generated paths;
//    docs/ACCURACY.md, "The runaway fixed"). Rule: a point's v_i is updated
//    only while its change shrinks, |v_i^(k+1) − v_i^(k)| ≤ |v_i^(k) − v_i^(k−1)|
//    (or is below 1e-9 of σ² + v_i, i.e. converged); at the first pass where
//    it does not, v_i is held at its last value (the last contracting pass;
//    the first correction from the linear covariance at the earliest) and the
//    point is flagged curvature-limited: the linearisation cannot carry its
//    second-order term, and its covariance is the last one before the loop
//    stopped contracting, not a converged one. Chosen over a damping factor
//    (a large enough gain still diverges) and over a cap of v_i by the map's
//    variance over the point's neighbourhood (the map is not an input here;
//    the prior cap below bounds the result instead).
//    Points without a data term are never flagged (v does not enter).
//  - The map's representation error (map_var_nT2, per point, nT²; empty =
//    none): the matcher reads the field between the grid's nodes by bilinear
//    interpolation, which misses the field's curvature inside a cell. That
//    error is not reading noise and is not in σ² (the rounds bend the path to
//    follow it, so the residuals do not show it: on the tuning paths at
//    0.5 nT the truth misfits the bilinear map by ≈ 1.5 σ² per point while
//    the fit's residuals are below σ²). It enters R beside σ²:
//    R_i = σ² + m_i + v_i, m_i = BilinearErrorBound(H_i, steps)², the
//    classical bound of the bilinear interpolant's error over the point's
//    cell from the grid's second differences (fast_msd.cc). EM's σ², τ² are
//    estimated without it (the residuals are what they are). The same
//    expression is the second-order term over half a cell, ½δᵀHδ, which the
//    linearisation at a position known to a fraction of a cell misses (the
//    bilinear gradient jumps at cell edges): on the generated paths the
//    term's gain is measured to come from that too (readings from the
//    bilinear map itself calibrate no better; docs/ACCURACY.md, "Fast MSD:
//    the map's own error in the covariance").
//  - Never wider than the prior: with prior_var_deg2 > 0 (fast_msd.cc: the
//    coarse search window's, w²/3 per axis for a uniform ±w) a point's
//    covariance whose larger eigenvalue exceeds it has its eigenvalues
//    clamped to it and is flagged prior-limited: what the method knew before
//    the readings bounds what it can claim after them. 0 = no cap.
//  Its diagonal blocks in O(N) time and memory (SandwichDiagonalBlocks
//  below), once per curvature pass; the EM needs only M(σ²/τ²)⁻¹'s diagonal
//  and first off-diagonal blocks (the selected-inverse recursion), O(N) per
//  EM iteration.
// e_lat/e_lon: the solution's corrections (deg) from the rounds' start;
// h_*: the map's Hessian per point (nT/deg²); the rest as above.
// Output s2_nT2 = σ², tau2_deg2 = τ²; edf as above (with the final λ);
// per point the curvature-limited and prior-limited flags (above; empty when
// the Laplace fallback is returned) and their counts.
struct ErrorCovariance {
  std::vector<double> lat_lat, lat_lon, lon_lon;
  double s2_nT2 = 0.0;
  double tau2_deg2 = 0.0;
  double edf = 0.0;
  std::vector<char> curvature_limited, prior_limited;
  int curvature_limited_points = 0;
  int prior_limited_points = 0;
};
ErrorCovariance FastMsdErrorCovariance(const std::vector<double>& g_lat, const std::vector<double>& g_lon,
                                       const std::vector<double>& resid, const std::vector<char>& data,
                                       const std::vector<double>& e_lat, const std::vector<double>& e_lon,
                                       const std::vector<double>& h_ll, const std::vector<double>& h_ln,
                                       const std::vector<double>& h_nn, double lambda,
                                       int curvature_iterations = 6, double prior_var_deg2 = 0.0,
                                       const std::vector<double>& map_var_nT2 = {});

// The path's two scales alone (the first step of FastMsdErrorCovariance, same inputs): σ² (nT²) and τ²
// (deg² per point and axis) by the EM above, from the residual σ² of FastMsdCovariance and τ² = 2σ²/λ.
// Both 0 when the path has no usable residual σ² (fewer than 2 points, no data term).
struct PathScales {
  double s2_nT2 = 0.0;
  double tau2_deg2 = 0.0;
};
PathScales EstimatePathScales(const std::vector<double>& g_lat, const std::vector<double>& g_lon,
                              const std::vector<double>& resid, const std::vector<char>& data,
                              const std::vector<double>& e_lat, const std::vector<double>& e_lon, double lambda);

// The bound of bilinear interpolation's error over a grid cell (nT) for the
// field's Hessian H (nT/deg²) and the grid steps (deg):
//   |f − I f| ≤ (Δlat²/8) |∂²f/∂lat²| + (Δlon²/8) |∂²f/∂lon²|
// (the 1-D linear interpolant's bound h²/8 |f''| along each axis of the
// tensor product; the bilinear interpolant reproduces the cross term lat·lon
// exactly, so ∂²f/∂lat∂lon does not enter). Leading order in the steps.
double BilinearErrorBound(const Eigen::Matrix2d& hessian, double step_lat_deg, double step_lon_deg);

// The curvature term's second moment v = ½ tr((H C)²) + ¼ tr(H C)² (nT²) for
// the map's Hessian H (nT/deg²) and a position covariance C (deg²).
double CurvatureSecondMoment(const Eigen::Matrix2d& hessian, const Eigen::Matrix2d& cov);
// The contraction rule above: may v (nT²) be replaced by next, its previous
// change having been last_change (+inf before the first), σ² = s2?
bool CurvatureUpdateContracts(double v, double next, double last_change, double s2);
// Clamps the eigenvalues of *cov (deg², symmetric) to prior_var_deg2 (> 0;
// non-finite ones too); true when it changed anything. 0 = no cap, false.
bool CapAtPrior(Eigen::Matrix2d* cov, double prior_var_deg2);

// A symmetric block-tridiagonal matrix with 2 × 2 blocks: diag[i] the block
// (i, i), upper[i] the block (i, i + 1) (size n − 1; block (i + 1, i) is its
// transpose).
struct BlockTridiagonal {
  std::vector<Eigen::Matrix2d> diag, upper;
};

// The diagonal 2 × 2 blocks of M⁻¹ A M⁻¹ for symmetric block-tridiagonal M
// (positive definite) and A, in O(N) time and memory, exact (no sampling).
//
// Route: the selected-inverse (Takahashi) recursion, differentiated.
// M⁻¹ A M⁻¹ = −d/dε (M + εA)⁻¹ at ε = 0, and M + εA is block tridiagonal
// too, so the diagonal blocks of the sandwich are the exact (forward-mode,
// not finite-difference) derivative of those of (M + εA)⁻¹. With D_i, B_i
// M's diagonal and upper blocks:
//   forward   S_0 = D_0,  S_i = D_i − Q_{i−1}ᵀ S_{i−1} Q_{i−1},  Q_i = S_i⁻¹ B_i
//             (M's Schur complements),
//             Ṡ_0 = A_00,  Ṡ_i = A_ii − A_{i−1,i}ᵀ Q_{i−1} − Q_{i−1}ᵀ A_{i−1,i}
//                                 + Q_{i−1}ᵀ Ṡ_{i−1} Q_{i−1}   (their derivative),
//             K_i = S_i⁻¹ Ṡ_i S_i⁻¹ (= −d S_i⁻¹/dε);
//   backward  Σ_{n−1} = S_{n−1}⁻¹,  Σ_i = S_i⁻¹ + Q_i Σ_{i+1} Q_iᵀ   (M⁻¹'s diagonal blocks),
//             X_{n−1} = K_{n−1},
//             X_i = K_i + Q_i X_{i+1} Q_iᵀ − (Q̇_i Σ_{i+1} Q_iᵀ + Q_i Σ_{i+1} Q̇_iᵀ),
//             Q̇_i = S_i⁻¹ A_{i,i+1} − K_i B_i,
// and X_i is block (i, i) of M⁻¹ A M⁻¹. (Equivalently: the selected inverse
// of the 4 × 4-block tridiagonal [[−A, M], [M, 0]], whose inverse holds
// M⁻¹ A M⁻¹ in its lower right.)
// Numerically: only 2 × 2 inverses of Schur complements, never a product of
// transfer matrices across the path (the semiseparable form U_i V_jᵀ, whose
// factors over- or underflow over 10⁴ points); both passes carry their state
// through one Q_i per step. For the smoother's M = Gᵀ W G + (λ/2) L (ends of
// weight 1), S_i ⪰ (λ/2) I for i < n − 1, so ‖Q_i‖ ≤ 1: rounding errors are
// not amplified along the path (tests/mapmatch/fast_msd_covariance_test.cc:
// against the dense product, and a 20 000-point path against columns solved
// one at a time).
// Requires m.diag.size() == a.diag.size() = n >= 1 and upper sizes n − 1.
std::vector<Eigen::Matrix2d> SandwichDiagonalBlocks(const BlockTridiagonal& m, const BlockTridiagonal& a);

}  // namespace magnav::mapmatch::internal
