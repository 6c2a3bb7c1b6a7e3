#include "geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

namespace magnav::mapmatch::internal {

template <int D>
void FitRigid(const Eigen::Matrix<double, D, Eigen::Dynamic>& d, const Eigen::Matrix<double, D, Eigen::Dynamic>& c,
              Eigen::Matrix<double, D, D>* R, Eigen::Matrix<double, D, 1>* t) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  const Vec d_mean = d.rowwise().mean();
  const Vec c_mean = c.rowwise().mean();
  const Mat W = (c.colwise() - c_mean) * (d.colwise() - d_mean).transpose();
  Eigen::JacobiSVD<Mat> svd(W, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat S = Mat::Identity();
  S(D - 1, D - 1) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  *R = svd.matrixU() * S * svd.matrixV().transpose();
  *t = c_mean - *R * d_mean;
}

template void FitRigid<2>(const Eigen::Matrix<double, 2, Eigen::Dynamic>&,
                          const Eigen::Matrix<double, 2, Eigen::Dynamic>&, Eigen::Matrix<double, 2, 2>*,
                          Eigen::Matrix<double, 2, 1>*);
template void FitRigid<3>(const Eigen::Matrix<double, 3, Eigen::Dynamic>&,
                          const Eigen::Matrix<double, 3, Eigen::Dynamic>&, Eigen::Matrix<double, 3, 3>*,
                          Eigen::Matrix<double, 3, 1>*);

NodeHit ClosestNode(const GeoGrid& grid, std::size_t layer, double lat_deg, double lon_deg, double scaled_field_deg,
                    double scale_deg_per_nT, int subdivision) {
  const GridAxis& la = grid.lat();
  const GridAxis& lo = grid.lon();
  const int sub = std::max(subdivision, 1);
  // The searched nodes: the grid's, or a grid `sub` times finer whose values
  // are the bilinear interpolant of the map.
  const int n_lat = (la.count - 1) * sub + 1, n_lon = (lo.count - 1) * sub + 1;
  const double step_lat = la.step_deg / sub, step_lon = lo.step_deg / sub;
  const int i0 = std::clamp(static_cast<int>(std::lround((lat_deg - la.first_deg) / step_lat)), 0, n_lat - 1);
  const int j0 = std::clamp(static_cast<int>(std::lround((lon_deg - lo.first_deg) / step_lon)), 0, n_lon - 1);
  const double* v = grid.values(layer).data();
  const double inv_sub = 1.0 / sub;
  auto value = [&](int i, int j) {
    if (sub == 1) return v[static_cast<std::size_t>(i) * lo.count + j];
    const int ci = std::min(i / sub, la.count - 2), cj = std::min(j / sub, lo.count - 2);
    const double u = (i - ci * sub) * inv_sub, w = (j - cj * sub) * inv_sub;
    const double* c = v + static_cast<std::size_t>(ci) * lo.count + cj;
    return (1 - u) * ((1 - w) * c[0] + w * c[1]) + u * ((1 - w) * c[lo.count] + w * c[lo.count + 1]);
  };
  NodeHit best;
  best.dist2 = std::numeric_limits<double>::infinity();
  auto visit = [&](int i, int j) {
    const double lat = la.first_deg + i * step_lat, lon = lo.first_deg + j * step_lon;
    const double a = lat - lat_deg, b = lon - lon_deg;
    const double d2_h = a * a + b * b;
    if (d2_h >= best.dist2) return;
    const double m = value(i, j);
    const double f = scale_deg_per_nT * m - scaled_field_deg;
    const double d2 = d2_h + f * f;
    if (d2 < best.dist2) best = NodeHit{lat, lon, m, d2};
  };
  const double step = std::min(step_lat, step_lon);
  const int r_max = std::max({i0, n_lat - 1 - i0, j0, n_lon - 1 - j0});
  visit(i0, j0);
  for (int r = 1; r <= r_max; ++r) {
    const double bound = (r - 0.5) * step;  // every node of ring r is at least this far horizontally
    if (bound * bound > best.dist2) break;
    const int ja = std::max(j0 - r, 0), jb = std::min(j0 + r, n_lon - 1);
    if (i0 - r >= 0) {
      for (int j = ja; j <= jb; ++j) visit(i0 - r, j);
    }
    if (i0 + r < n_lat) {
      for (int j = ja; j <= jb; ++j) visit(i0 + r, j);
    }
    const int ia = std::max(i0 - r + 1, 0), ib = std::min(i0 + r - 1, n_lat - 1);
    if (j0 - r >= 0) {
      for (int i = ia; i <= ib; ++i) visit(i, j0 - r);
    }
    if (j0 + r < n_lon) {
      for (int i = ia; i <= ib; ++i) visit(i, j0 + r);
    }
  }
  return best;
}

namespace {

// Closest point of segment ab to q.
Eigen::Vector2d ClosestOnSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& q) {
  const Eigen::Vector2d ab = b - a;
  const double n2 = ab.squaredNorm();
  if (n2 == 0.0) return a;
  return a + std::clamp((q - a).dot(ab) / n2, 0.0, 1.0) * ab;
}

}  // namespace

std::optional<Eigen::Vector2d> ClosestOnContour(const GeoGrid& grid, std::size_t layer, double lat_deg,
                                                double lon_deg, double level_nT) {
  if (!(level_nT >= grid.min_value(layer) && level_nT <= grid.max_value(layer))) return std::nullopt;
  const GridAxis& la = grid.lat();
  const GridAxis& lo = grid.lon();
  const int nci = la.count - 1, ncj = lo.count - 1;  // cells
  const int i0 = std::clamp(static_cast<int>(std::floor((lat_deg - la.first_deg) / la.step_deg)), 0, nci - 1);
  const int j0 = std::clamp(static_cast<int>(std::floor((lon_deg - lo.first_deg) / lo.step_deg)), 0, ncj - 1);
  const Eigen::Vector2d q(lat_deg, lon_deg);
  double best2 = std::numeric_limits<double>::infinity();
  Eigen::Vector2d best(0.0, 0.0);
  const double* v = grid.values(layer).data();
  auto visit = [&](int i, int j) {
    const std::size_t n = static_cast<std::size_t>(i) * lo.count + j;
    const double c[4] = {v[n], v[n + 1], v[n + lo.count + 1], v[n + lo.count]};  // counter-clockwise corners
    const double cmin = std::min({c[0], c[1], c[2], c[3]}), cmax = std::max({c[0], c[1], c[2], c[3]});
    if (level_nT < cmin || level_nT > cmax) return;
    if (cmin == cmax) {  // a flat cell on the level: the query clamped into it
      const Eigen::Vector2d x(std::clamp(lat_deg, la.at(i), la.at(i + 1)), std::clamp(lon_deg, lo.at(j), lo.at(j + 1)));
      if ((x - q).squaredNorm() < best2) {
        best2 = (x - q).squaredNorm();
        best = x;
      }
      return;
    }
    const Eigen::Vector2d p[4] = {{la.at(i), lo.at(j)}, {la.at(i), lo.at(j + 1)},
                                  {la.at(i + 1), lo.at(j + 1)}, {la.at(i + 1), lo.at(j)}};
    Eigen::Vector2d cross[4];
    int n_cross = 0;
    // Marching squares on the corners classified as >= level or < level: an
    // even number of edge crossings (0, 2 or 4 at a saddle), paired in order.
    for (int e = 0; e < 4; ++e) {
      const double va = c[e] - level_nT, vb = c[(e + 1) % 4] - level_nT;
      if ((va >= 0.0) == (vb >= 0.0)) continue;
      const double s = va / (va - vb);
      cross[n_cross++] = p[e] + s * (p[(e + 1) % 4] - p[e]);
    }
    for (int k = 0; k < n_cross; k += 2) {
      const Eigen::Vector2d x = ClosestOnSegment(cross[k], cross[k + 1], q);
      const double d2 = (x - q).squaredNorm();
      if (d2 < best2) {
        best2 = d2;
        best = x;
      }
    }
  };
  const double step = std::min(la.step_deg, lo.step_deg);
  const int r_max = std::max({i0, nci - 1 - i0, j0, ncj - 1 - j0});
  visit(i0, j0);
  for (int r = 1; r <= r_max; ++r) {
    const double bound = (r - 1) * step;  // every cell of ring r is at least this far
    if (bound * bound > best2) break;
    const int ja = std::max(j0 - r, 0), jb = std::min(j0 + r, ncj - 1);
    if (i0 - r >= 0) for (int j = ja; j <= jb; ++j) visit(i0 - r, j);
    if (i0 + r < nci) for (int j = ja; j <= jb; ++j) visit(i0 + r, j);
    const int ia = std::max(i0 - r + 1, 0), ib = std::min(i0 + r - 1, nci - 1);
    if (j0 - r >= 0) for (int i = ia; i <= ib; ++i) visit(i, j0 - r);
    if (j0 + r < ncj) for (int i = ia; i <= ib; ++i) visit(i, j0 + r);
  }
  if (!std::isfinite(best2)) return std::nullopt;
  return best;
}

}  // namespace magnav::mapmatch::internal
