// Internal geometry shared by ICP, ICCP and MMA: the rigid (Procrustes) fit
// and the two closest-point searches on a grid (ring searches around the
// query's cell, pruned by the horizontal distance of the next ring).
#pragma once

#include <cstddef>
#include <optional>

#include <Eigen/Core>

#include "magnav/mapmatch/geo_grid.h"

namespace magnav::mapmatch::internal {

// Rigid transform y ≈ R x + t minimising Σ |c_j − (R d_j + t)|² (Besl–McKay /
// Kabsch): W = Σ (c − c̄)(d − d̄)ᵀ (centred), W = U Σ Vᵀ, R = U S Vᵀ with
// S = diag(1, …, det(U Vᵀ)) (no reflection), t = c̄ − R d̄.
template <int D>
void FitRigid(const Eigen::Matrix<double, D, Eigen::Dynamic>& d, const Eigen::Matrix<double, D, Eigen::Dynamic>& c,
              Eigen::Matrix<double, D, D>* R, Eigen::Matrix<double, D, 1>* t);

// Closest node to (lat, lon, field·scale) in the metric
// Δlat² + Δlon² + (scale·Δfield)² (deg²), exact, among the grid's nodes
// (subdivision 1) or the nodes of a grid `subdivision` times finer carrying
// the map's bilinear values.
struct NodeHit {
  double lat_deg = 0.0, lon_deg = 0.0, value_nT = 0.0;
  double dist2 = 0.0;
};
NodeHit ClosestNode(const GeoGrid& grid, std::size_t layer, double lat_deg, double lon_deg, double scaled_field_deg,
                    double scale_deg_per_nT, int subdivision);

// Closest point (lat, lon) to the query on the iso-contour value = level_nT
// of the bilinear map, the contour taken piecewise linear in each cell
// (marching squares). nullopt if the level is outside the layer's range.
std::optional<Eigen::Vector2d> ClosestOnContour(const GeoGrid& grid, std::size_t layer, double lat_deg,
                                                double lon_deg, double level_nT);

}  // namespace magnav::mapmatch::internal
