// Shape matchers of METHODS.md §4 (thesis ch. 3–5): ICP, ICCP and the
// modified Menq's algorithm (MMA).
//
// Frames and units: points are (lat, lon) in degrees (WGS84, used as a plane)
// and, for ICP and MMA, a third coordinate field·scale, where the scale
// (deg/nT) turns nT into degrees. It is explicit: either given, or — when
// field_scale_deg_per_nT = 0 — derived from the map as 1 / (RMS |∇value|)
// (a field difference then weighs as much as the distance that typically
// produces it); the value used is reported in MatchResult::notes.
//
// Every point with a non-finite measurement is left out of the fit and moved
// with the path's transform (counted).
#pragma once

#include <cstddef>
#include <string>

#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"

namespace magnav::mapmatch {

// Iterative closest point (Besl–McKay, SVD variant) in (lat, lon, scale·field):
// closest map nodes C of the transformed path D (rigid motion in the plane
// by default, see planar_motion); W = Σ (c − c̄)(d − d̄)ᵀ
// (centred — the thesis appendix forgets the centring); W = U Σ Vᵀ;
// R = U diag(1, 1, det(U Vᵀ)) Vᵀ; t = c̄ − R d̄; the increments are composed
// until ‖R_k − I‖_F + ‖t_k‖ < convergence_tau. Score: RMS distance to the
// closest nodes (deg).
struct IcpOptions {
  // deg per nT; 0 = 1 / (RMS gradient of the layer).
  double field_scale_deg_per_nT = 0.0;
  // The thesis' τ = 1e-5 (on the increment, deg units).
  double convergence_tau = 1e-5;
  int max_iterations = 100;
  // Closest points among the nodes of a grid this many times finer than the
  // map (bilinear values); 1 = the map's own nodes, as in the thesis.
  int closest_point_subdivision = 1;
  // true (default): the closest points are found in (lat, lon, scale·field)
  // as above, but the transform is a rigid 2-D one of (lat, lon) only, each
  // point keeping its measured field — the INS error moves positions, not
  // measurements. false: the thesis' rigid 3-D transform of (lat, lon,
  // scale·field). Chosen after measuring both on every reference path
  // (docs/ACCURACY.md): the planar motion has the smaller final error on 12
  // of the 16 WMM rows (WMM 0.5° F: 0.40° against 0.80°), a larger one on
  // the 4 WMM 0.5° X rows and from the crustal 0.1° offset.
  bool planar_motion = true;
  // Robust residuals (trimmed ICP): in each iteration a point whose closest
  // distance is beyond outlier_sigmas robust sigmas (1.4826·MAD of the
  // distances, at least half a grid step) above the median is left out of
  // that iteration's fit (a +1000 nT spike puts its point 1000·scale deg off
  // every node); counted in MatchResult::points_outlier. 0 = off.
  double outlier_sigmas = 5.0;

  bool IsValid(std::string* error) const;
};

MatchResult MatchIcp(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const IcpOptions& options = {});

// Iterative closest contour point: each point's closest point on the map's
// iso-contour of its measured value (piecewise linear per cell), then a rigid
// 2-D transform (same centred SVD fit), composed until the increment is below
// convergence_tau. A point whose value is not on the map (outside the layer's
// range) is left out (counted as off map). Score: RMS distance to the
// contours (deg).
struct IccpOptions {
  double convergence_tau = 1e-5;
  int max_iterations = 100;
  double outlier_sigmas = 5.0;  // as IcpOptions (distances to the contours)

  bool IsValid(std::string* error) const;
};

MatchResult MatchIccp(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                      const IccpOptions& options = {});

// Modified Menq's algorithm: C = the closest map nodes (as ICP, one pass from
// the INS positions) of D = (lat, lon, scale·field, 1); one affine least-squares
// fit in homogeneous coordinates T = (C Dᵀ)(D Dᵀ)⁻¹ (4 × 4, not rigid, no
// iteration); the matched point is T d. Score: RMS residual |C − T D| (deg).
struct MmaOptions {
  double field_scale_deg_per_nT = 0.0;  // as IcpOptions
  int closest_point_subdivision = 1;    // as IcpOptions
  // Robust residuals: a point whose closest-node distance is beyond this many
  // robust sigmas (as IcpOptions) is left out of the affine fit. 0 = off.
  double outlier_sigmas = 5.0;

  bool IsValid(std::string* error) const;
};

MatchResult MatchMma(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const MmaOptions& options = {});

}  // namespace magnav::mapmatch
