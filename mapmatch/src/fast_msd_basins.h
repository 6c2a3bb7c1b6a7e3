// Internal: the other basins a fast-MSD solution's points could be in
// (issue 25 item 4; docs/ACCURACY.md, "Fast MSD: the other basins in the
// covariance").
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "magnav/mapmatch/geo_grid.h"

namespace magnav::mapmatch::internal {

// The covariance of fast_msd_covariance.h is a linearisation at the published
// path: it describes the basin the rounds ended in. Where a stretch of the
// path was refined into a wrong local minimum of the map (generated paths
// 605, 606, 608, 626, 732: 0.002-0.02 deg off with σ 0.0003 deg), that basin's
// covariance cannot hold the right one. This computes, per point, the
// posterior over a grid of offsets d from the published position under the
// same model the covariance uses, without linearising:
//   readings  l_i = m(x̂_i + d_i) + n_i,  n_i ~ N(0, σ² + m_i)  (m: the bilinear
//             map the matcher reads; σ², m_i = the map-error bound², as in the
//             covariance; the squared residual capped at `cap_nT`², the
//             rounds' robust cap, off the map = the cap),
//   drift     the corrections e_i = x_i − start_i a random walk of τ² per step
//             and axis: d_{i+1} − d_i + (ê_{i+1} − ê_i) ~ N(0, τ² I),
// by forward-backward over the path (an HMM on the offset grid, the path's
// basin ambiguity carried along it, not per point). Points without a data
// term (data = 0) have no likelihood. Grid: offsets (a·h, b·h) in (lat, lon),
// |a|, |b| ≤ R.
// Output per point: the posterior's second moment about the published point
// over the offsets outside the published basin, i.e. dᵀ C_i⁻¹ d > chi2 (C_i
// the linearised covariance; those inside are that basin, which C_i
// describes), plus each such cell's own spread h²/12 per axis, and their mass.
// The published covariance is then C_i + far_moment_i (fast_msd.cc): the
// mixture's second moment about the published point, the published basin's
// weight taken as 1 (never narrower than C_i).
// Also the first moment of that outside mass, far_mean_i = Σ_outside p(d) d
// (deg; the published basin's mass counted at d = 0): the mixture's mean
// offset from the published point (fast_msd.cc, FastMsdOptions::
// basin_mean_shift).
struct BasinSpread {
  std::vector<Eigen::Matrix2d> far_moment;  // deg²
  std::vector<Eigen::Vector2d> far_mean;    // deg
  std::vector<double> far_mass;
  // The posterior mass on the grid's outermost ring of offsets (|a| or |b| =
  // R): where it is not small the grid truncates the posterior.
  std::vector<double> edge_mass;
  // The whole posterior's mean offset from the published point, Σ_all p(d) d (deg; the published basin's
  // mass where the grid puts it, not at d = 0), and its second moment about that mean, each cell's own
  // h²/12 per axis included (deg²): FastMsdOptions::basin_full_mean.
  std::vector<Eigen::Vector2d> mean;
  std::vector<Eigen::Matrix2d> spread;
  double step_deg = 0.0;
  int radius = 0;
};
BasinSpread FastMsdBasinSpread(const GeoGrid& grid, std::size_t layer, const std::vector<double>& lat_deg,
                               const std::vector<double>& lon_deg, const std::vector<double>& measured_nT,
                               const std::vector<char>& data, const std::vector<double>& e_lat,
                               const std::vector<double>& e_lon, const std::vector<Eigen::Matrix2d>& cov,
                               double s2_nT2, const std::vector<double>& map_var_nT2, double tau2_deg2,
                               double cap_nT, double step_deg, int radius, double chi2 = 9.21);

}  // namespace magnav::mapmatch::internal
