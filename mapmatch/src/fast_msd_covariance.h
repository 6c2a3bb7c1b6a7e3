// Internal: the covariance of a fast-MSD solution (fast_msd.h), by the
// Laplace approximation of the cost its fixed point minimises.
#pragma once

#include <cstddef>
#include <vector>

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

}  // namespace magnav::mapmatch::internal
