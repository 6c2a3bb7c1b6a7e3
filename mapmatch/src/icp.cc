#include "magnav/mapmatch/icp.h"

#include <cmath>
#include <vector>

#include <Eigen/Dense>

#include "geometry.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/option_check.h"
#include "match_common.h"

namespace magnav::mapmatch {
namespace {

using Matrix3X = Eigen::Matrix<double, 3, Eigen::Dynamic>;
using Matrix2X = Eigen::Matrix<double, 2, Eigen::Dynamic>;

bool ValidIterations(double tau, int max_iterations, std::string* error) {
  if (!PositiveFinite(tau)) return Fail(error, "convergence_tau must be finite and > 0");
  if (max_iterations < 1) return Fail(error, "max_iterations must be >= 1");
  return true;
}

bool ValidScale(double scale, std::string* error) {
  if (!(std::isfinite(scale) && scale >= 0.0)) {
    return Fail(error, "field_scale_deg_per_nT must be finite and >= 0 (0 = from the map)");
  }
  return true;
}

// The scale in use and the note saying where it came from.
double FieldScale(const GeoGrid& grid, std::size_t layer, double given, MatchResult* r) {
  if (given > 0.0) {
    r->notes = "field scale " + FormatNumber(given) + " deg/nT (given)";
    return given;
  }
  const double g = grid.rms_gradient_nT_per_deg(layer);
  if (!(g > 0.0)) throw InputError("map: layer is flat (zero gradient): give the field scale");
  r->notes = "field scale " + FormatNumber(1.0 / g) + " deg/nT (1/rms gradient)";
  return 1.0 / g;
}

// The iteration ICP and ICCP share: the points P moved by (R, t), their
// closest points Y = closest(X) (fills each point's squared distance), the
// rigid increment fitted to the inliers and composed, until
// ‖R_k − I‖_F + ‖t_k‖ < τ or the cap. Robust residuals (match_common.h): a
// point whose closest distance is beyond outlier_sigmas robust sigmas of the
// distances (σ at least floor_deg) is left out of that iteration's fit. Sets
// the iterations, score (RMS closest distance over the inliers), converged
// flag and reason, and the outliers of the last iteration.
template <int D, typename Closest>
void IterateRigid(const Eigen::Matrix<double, D, Eigen::Dynamic>& P, double tau, int max_iterations,
                  double outlier_sigmas, double floor_deg, const Closest& closest, Eigen::Matrix<double, D, D>* R,
                  Eigen::Matrix<double, D, 1>* t, MatchResult* r) {
  using MatD = Eigen::Matrix<double, D, D>;
  using VecD = Eigen::Matrix<double, D, 1>;
  using MatX = Eigen::Matrix<double, D, Eigen::Dynamic>;
  *R = MatD::Identity();
  *t = VecD::Zero();
  MatX Y(D, P.cols());
  std::vector<double> dist2(static_cast<std::size_t>(P.cols()));
  int outliers = 0;
  for (r->iterations = 1; r->iterations <= max_iterations; ++r->iterations) {
    const MatX X = (*R * P).colwise() + *t;
    closest(X, &Y, &dist2);
    std::vector<double> dist(dist2.size());
    for (std::size_t c = 0; c < dist.size(); ++c) dist[c] = std::sqrt(dist2[c]);
    const internal::RobustSpread spread = internal::RobustSpreadOf(dist, floor_deg);
    std::vector<Eigen::Index> in;
    double sum2 = 0.0;
    for (std::size_t c = 0; c < dist.size(); ++c) {
      if (internal::IsOutlier(dist[c], spread, outlier_sigmas) && dist[c] > spread.median) continue;
      in.push_back(static_cast<Eigen::Index>(c));
      sum2 += dist2[c];
    }
    if (in.size() < static_cast<std::size_t>(D)) {  // too few inliers to fit: use every point
      in.clear();
      sum2 = 0.0;
      for (std::size_t c = 0; c < dist.size(); ++c) in.push_back(static_cast<Eigen::Index>(c)), sum2 += dist2[c];
    }
    outliers = static_cast<int>(dist.size() - in.size());
    r->score = std::sqrt(sum2 / static_cast<double>(in.size()));
    MatX Xi(D, static_cast<Eigen::Index>(in.size())), Yi(D, static_cast<Eigen::Index>(in.size()));
    for (std::size_t c = 0; c < in.size(); ++c) {
      Xi.col(static_cast<Eigen::Index>(c)) = X.col(in[c]);
      Yi.col(static_cast<Eigen::Index>(c)) = Y.col(in[c]);
    }
    MatD Rk;
    VecD tk;
    internal::FitRigid<D>(Xi, Yi, &Rk, &tk);
    *R = Rk * *R;
    *t = Rk * *t + tk;
    if ((Rk - MatD::Identity()).norm() + tk.norm() < tau) {
      r->converged = true;
      break;
    }
  }
  if (!r->converged) {
    r->iterations = max_iterations;
    r->reason = "transform increment still >= tau after " + std::to_string(max_iterations) + " iterations";
  }
  r->points_outlier += outliers;
  r->points_used -= outliers;
}

// σ floor of the closest-point distances: half the map's smaller step (the
// closest nodes quantise the distance by up to that much).
double DistanceFloor(const GeoGrid& grid) { return 0.5 * std::min(grid.lat().step_deg, grid.lon().step_deg); }

}  // namespace

bool ValidSubdivision(int subdivision, std::string* error) {
  if (subdivision < 1 || subdivision > 100) return Fail(error, "closest_point_subdivision must be in 1..100");
  return true;
}

bool IcpOptions::IsValid(std::string* error) const {
  return ValidScale(field_scale_deg_per_nT, error) && ValidIterations(convergence_tau, max_iterations, error) &&
         ValidSubdivision(closest_point_subdivision, error) && internal::ValidOutlierSigmas(outlier_sigmas, error);
}
bool IccpOptions::IsValid(std::string* error) const {
  return ValidIterations(convergence_tau, max_iterations, error) && internal::ValidOutlierSigmas(outlier_sigmas, error);
}
bool MmaOptions::IsValid(std::string* error) const {
  return ValidScale(field_scale_deg_per_nT, error) && ValidSubdivision(closest_point_subdivision, error) &&
         internal::ValidOutlierSigmas(outlier_sigmas, error);
}

MatchResult MatchIcp(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const IcpOptions& options) {
  internal::CheckInputs(grid, layer, path, options, "icp");
  MatchResult r = internal::StartResult("icp", "rms distance to the closest nodes, deg", path);
  const std::vector<std::size_t> used = internal::FiniteMeasurements(path, &r);
  if (!internal::EnoughPoints(used, 3, &r)) return r;
  const double s = FieldScale(grid, layer, options.field_scale_deg_per_nT, &r);
  Matrix3X D(3, used.size());
  for (std::size_t c = 0; c < used.size(); ++c) {
    const std::size_t p = used[c];
    D.col(c) << path.lat_deg[p], path.lon_deg[p], s * path.measured_nT[p];
  }
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  const auto closest = [&](const Matrix3X& X, Matrix3X* C, std::vector<double>* dist2) {
    for (Eigen::Index c = 0; c < X.cols(); ++c) {
      const internal::NodeHit h =
          internal::ClosestNode(grid, layer, X(0, c), X(1, c), X(2, c), s, options.closest_point_subdivision);
      C->col(c) << h.lat_deg, h.lon_deg, s * h.value_nT;
      (*dist2)[static_cast<std::size_t>(c)] = h.dist2;
    }
  };
  if (options.planar_motion) {
    // Only (lat, lon) move; each point keeps its measured field coordinate.
    Eigen::Matrix2d R2;
    Eigen::Vector2d t2;
    const auto closest2 = [&](const Matrix2X& X, Matrix2X* Y, std::vector<double>* dist2) {
      Matrix3X X3(3, X.cols()), C(3, X.cols());
      X3.topRows<2>() = X;
      X3.row(2) = D.row(2);
      closest(X3, &C, dist2);
      *Y = C.topRows<2>();
    };
    IterateRigid<2>(Matrix2X(D.topRows<2>()), options.convergence_tau, options.max_iterations, options.outlier_sigmas,
                    DistanceFloor(grid), closest2, &R2, &t2, &r);
    R.setIdentity();
    R.topLeftCorner<2, 2>() = R2;
    t << t2, 0.0;
  } else {
    IterateRigid<3>(D, options.convergence_tau, options.max_iterations, options.outlier_sigmas, DistanceFloor(grid),
                    closest, &R, &t, &r);
  }
  // Points without a measurement are moved at the mean field of the others.
  const double mean_field = D.row(2).mean();
  for (std::size_t p = 0; p < path.size(); ++p) {
    const double f = std::isfinite(path.measured_nT[p]) ? s * path.measured_nT[p] : mean_field;
    const Eigen::Vector3d x = R * Eigen::Vector3d(path.lat_deg[p], path.lon_deg[p], f) + t;
    r.lat_deg[p] = x(0);
    r.lon_deg[p] = x(1);
  }
  internal::CountOffMap(grid, &r);
  return r;
}

MatchResult MatchIccp(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const IccpOptions& options) {
  internal::CheckInputs(grid, layer, path, options, "iccp");
  MatchResult r = internal::StartResult("iccp", "rms distance to the contours, deg", path);
  const std::vector<std::size_t> finite = internal::FiniteMeasurements(path, &r);
  // Values the map never takes have no contour: left out, counted as off map.
  std::vector<std::size_t> used;
  int no_contour = 0;
  for (std::size_t p : finite) {
    const double m = path.measured_nT[p];
    if (m >= grid.min_value(layer) && m <= grid.max_value(layer)) {
      used.push_back(p);
    } else {
      ++no_contour;
    }
  }
  if (!internal::EnoughPoints(used, 2, &r)) return r;
  Matrix2X P(2, used.size());
  for (std::size_t c = 0; c < used.size(); ++c) P.col(c) << path.lat_deg[used[c]], path.lon_deg[used[c]];
  Eigen::Matrix2d R;
  Eigen::Vector2d t;
  const auto closest = [&](const Matrix2X& X, Matrix2X* Y, std::vector<double>* dist2) {
    for (Eigen::Index c = 0; c < X.cols(); ++c) {
      // The level is within the layer's range, so a contour point exists.
      Y->col(c) = *internal::ClosestOnContour(grid, layer, X(0, c), X(1, c), path.measured_nT[used[c]]);
      (*dist2)[static_cast<std::size_t>(c)] = (Y->col(c) - X.col(c)).squaredNorm();
    }
  };
  IterateRigid<2>(P, options.convergence_tau, options.max_iterations, options.outlier_sigmas, DistanceFloor(grid),
                  closest, &R, &t, &r);
  for (std::size_t p = 0; p < path.size(); ++p) {
    const Eigen::Vector2d x = R * Eigen::Vector2d(path.lat_deg[p], path.lon_deg[p]) + t;
    r.lat_deg[p] = x(0);
    r.lon_deg[p] = x(1);
  }
  internal::CountOffMap(grid, &r);
  if (no_contour > 0) {
    r.points_used -= no_contour;
    r.notes = std::to_string(no_contour) + " measured values outside the map's range (no contour)";
  }
  return r;
}

MatchResult MatchMma(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const MmaOptions& options) {
  internal::CheckInputs(grid, layer, path, options, "mma");
  MatchResult r = internal::StartResult("mma", "rms residual of the affine fit, deg", path);
  const std::vector<std::size_t> used = internal::FiniteMeasurements(path, &r);
  if (!internal::EnoughPoints(used, 4, &r)) return r;
  const double s = FieldScale(grid, layer, options.field_scale_deg_per_nT, &r);
  Eigen::Matrix<double, 4, Eigen::Dynamic> D(4, used.size()), C(4, used.size());
  for (std::size_t c = 0; c < used.size(); ++c) {
    const std::size_t p = used[c];
    D.col(c) << path.lat_deg[p], path.lon_deg[p], s * path.measured_nT[p], 1.0;
    const internal::NodeHit h =
        internal::ClosestNode(grid, layer, D(0, c), D(1, c), D(2, c), s, options.closest_point_subdivision);
    C.col(c) << h.lat_deg, h.lon_deg, s * h.value_nT, 1.0;
  }
  r.iterations = 1;
  // Robust residuals: a point whose closest-node distance is beyond
  // outlier_sigmas robust sigmas is left out of the fit.
  {
    std::vector<double> dist(used.size());
    for (std::size_t c = 0; c < used.size(); ++c) dist[c] = (C.col(c) - D.col(c)).norm();
    const internal::RobustSpread spread = internal::RobustSpreadOf(dist, DistanceFloor(grid));
    std::vector<Eigen::Index> in;
    for (std::size_t c = 0; c < used.size(); ++c) {
      if (!(internal::IsOutlier(dist[c], spread, options.outlier_sigmas) && dist[c] > spread.median)) {
        in.push_back(static_cast<Eigen::Index>(c));
      }
    }
    if (in.size() >= 4 && in.size() < used.size()) {
      Eigen::Matrix<double, 4, Eigen::Dynamic> Di(4, static_cast<Eigen::Index>(in.size())),
          Ci(4, static_cast<Eigen::Index>(in.size()));
      for (std::size_t c = 0; c < in.size(); ++c) {
        Di.col(static_cast<Eigen::Index>(c)) = D.col(in[c]);
        Ci.col(static_cast<Eigen::Index>(c)) = C.col(in[c]);
      }
      r.points_outlier = static_cast<int>(used.size() - in.size());
      r.points_used -= r.points_outlier;
      D = Di;
      C = Ci;
    }
  }
  // T = (C Dᵀ)(D Dᵀ)⁻¹ is the least-squares solution of T D ≈ C; solved as
  // Dᵀ Tᵀ ≈ Cᵀ by column-pivoting QR (same T, without squaring D's condition).
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(D.transpose());
  if (qr.rank() < 4) {
    r.reason = "D Dt is singular (a straight path over a constant field): path left as the INS gave it";
    return r;
  }
  const Eigen::Matrix4d T = qr.solve(Eigen::MatrixXd(C.transpose())).transpose();
  r.score = std::sqrt((C - T * D).topRows<3>().colwise().squaredNorm().mean());
  const double mean_field = D.row(2).mean();
  for (std::size_t p = 0; p < path.size(); ++p) {
    const double f = std::isfinite(path.measured_nT[p]) ? s * path.measured_nT[p] : mean_field;
    const Eigen::Vector4d x = T * Eigen::Vector4d(path.lat_deg[p], path.lon_deg[p], f, 1.0);
    r.lat_deg[p] = x(0);
    r.lon_deg[p] = x(1);
  }
  r.converged = true;  // a closed-form fit
  internal::CountOffMap(grid, &r);
  return r;
}

}  // namespace magnav::mapmatch
