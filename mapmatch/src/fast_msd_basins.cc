#include "fast_msd_basins.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/LU>

namespace magnav::mapmatch::internal {
namespace {

// Forward values below this fraction of the step's largest are dropped (the
// posterior mass they could carry, ≤ 1e-10 per cell times d² ≤ (0.012°)², is
// far below any covariance written): the recursion runs over the bounding box
// of what remains, not the whole grid.
constexpr double kPrune = 1e-10;

// A rectangle of grid indices [r0, r1] × [c0, c1] (rows: latitude offsets,
// columns: longitude offsets), with values stored row-major inside it.
struct Box {
  int r0 = 0, r1 = -1, c0 = 0, c1 = -1;
  int rows() const { return r1 - r0 + 1; }
  int cols() const { return c1 - c0 + 1; }
  std::size_t size() const { return r1 < r0 || c1 < c0 ? 0 : static_cast<std::size_t>(rows()) * cols(); }
};

Box Grow(const Box& b, int dr, int dc, int side) {
  return {std::max(0, b.r0 - dr), std::min(side - 1, b.r1 + dr), std::max(0, b.c0 - dc), std::min(side - 1, b.c1 + dc)};
}

// The 1-D transition kernel over index differences k = j_next − j (|k| ≤ half):
// exp(−(k·h + shift)² / (2 τ²)), shift = the published correction's increment.
std::vector<double> Kernel(double shift_deg, double step_deg, double tau2_deg2, int half) {
  std::vector<double> k(2 * half + 1);
  for (int i = -half; i <= half; ++i) {
    const double x = i * step_deg + shift_deg;
    k[i + half] = std::exp(-0.5 * x * x / tau2_deg2);
  }
  return k;
}

// Dense scratch grids (side × side) and the transition between two points:
// `in` (values on box `from`, the rest of the grid ignored) goes through the
// separable kernel (forward: out[s + k] += in[s] K[k]; backward, the
// transpose: out[s] += in[s + k] K[k]) and the result is returned on `to`.
class Transition {
 public:
  explicit Transition(int side) : side_(side), a_(static_cast<std::size_t>(side) * side), b_(a_.size()) {}

  void Apply(const std::vector<double>& in, const Box& from, const std::vector<double>& ka, int ha,
             const std::vector<double>& kb, int hb, bool forward, const Box& to, std::vector<double>* out) {
    // Rows (latitude): from `from` into a region grown by ha rows.
    const Box mid = Grow(from, ha, 0, side_);
    Zero(&a_, mid);
    for (int r = from.r0; r <= from.r1; ++r) {
      const double* src = &in[static_cast<std::size_t>(r - from.r0) * from.cols()];
      for (int k = -ha; k <= ha; ++k) {
        const int rr = forward ? r + k : r - k;
        if (rr < mid.r0 || rr > mid.r1) continue;
        const double w = ka[k + ha];
        double* dst = &a_[static_cast<std::size_t>(rr) * side_];
        for (int c = from.c0; c <= from.c1; ++c) dst[c] += w * src[c - from.c0];
      }
    }
    // Columns (longitude): into a region grown by hb columns.
    const Box end = Grow(mid, 0, hb, side_);
    Zero(&b_, end);
    for (int r = mid.r0; r <= mid.r1; ++r) {
      const double* src = &a_[static_cast<std::size_t>(r) * side_];
      double* dst = &b_[static_cast<std::size_t>(r) * side_];
      for (int k = -hb; k <= hb; ++k) {
        const double w = kb[k + hb];
        const int lo = std::max(mid.c0, (forward ? end.c0 - k : end.c0 + k));
        const int hi = std::min(mid.c1, (forward ? end.c1 - k : end.c1 + k));
        if (forward) {
          for (int c = lo; c <= hi; ++c) dst[c + k] += w * src[c];
        } else {
          for (int c = lo; c <= hi; ++c) dst[c - k] += w * src[c];
        }
      }
    }
    out->assign(to.size(), 0.0);
    for (int r = std::max(to.r0, end.r0); r <= std::min(to.r1, end.r1); ++r) {
      for (int c = std::max(to.c0, end.c0); c <= std::min(to.c1, end.c1); ++c) {
        (*out)[static_cast<std::size_t>(r - to.r0) * to.cols() + (c - to.c0)] = b_[static_cast<std::size_t>(r) * side_ + c];
      }
    }
  }

 private:
  void Zero(std::vector<double>* g, const Box& b) const {
    for (int r = b.r0; r <= b.r1; ++r) {
      std::fill(g->begin() + static_cast<std::ptrdiff_t>(r) * side_ + b.c0,
                g->begin() + static_cast<std::ptrdiff_t>(r) * side_ + b.c1 + 1, 0.0);
    }
  }
  int side_;
  std::vector<double> a_, b_;
};

// Where one axis's offsets fall on the map's grid: for each offset index, the
// lower node and the fraction towards the next (GeoGrid::Sample's bilinear
// rule, the same rounding), or node −1 off the map.
void AxisCells(const GridAxis& axis, double centre_deg, double step_deg, int radius, int lo, int hi,
               std::vector<int>* node, std::vector<double>* frac) {
  node->assign(hi - lo + 1, -1);
  frac->assign(hi - lo + 1, 0.0);
  constexpr double kEdge = 1e-9;  // as GeoGrid::Contains
  for (int a = lo; a <= hi; ++a) {
    const double f = (centre_deg + (a - radius) * step_deg - axis.first_deg) / axis.step_deg;
    if (!(f >= -kEdge && f <= axis.count - 1 + kEdge)) continue;
    const int i = std::clamp(static_cast<int>(std::floor(f)), 0, axis.count - 2);
    (*node)[a - lo] = i;
    (*frac)[a - lo] = f - i;
  }
}

}  // namespace

BasinSpread FastMsdBasinSpread(const GeoGrid& grid, std::size_t layer, const std::vector<double>& lat_deg,
                               const std::vector<double>& lon_deg, const std::vector<double>& measured_nT,
                               const std::vector<char>& data, const std::vector<double>& e_lat,
                               const std::vector<double>& e_lon, const std::vector<Eigen::Matrix2d>& cov,
                               double s2_nT2, const std::vector<double>& map_var_nT2, double tau2_deg2,
                               double cap_nT, double step_deg, int radius, double chi2) {
  const std::size_t n = lat_deg.size();
  BasinSpread out;
  out.step_deg = step_deg;
  out.radius = radius;
  out.far_moment.assign(n, Eigen::Matrix2d::Zero());
  out.far_mean.assign(n, Eigen::Vector2d::Zero());
  out.far_mass.assign(n, 0.0);
  out.edge_mass.assign(n, 0.0);
  out.mean.assign(n, Eigen::Vector2d::Zero());
  out.spread.assign(n, Eigen::Matrix2d::Zero());
  if (n < 2 || !(tau2_deg2 > 0.0) || !(s2_nT2 > 0.0) || !(step_deg > 0.0) || radius < 1) return out;
  const int side = 2 * radius + 1;
  const double cap2 = cap_nT * cap_nT;
  const double tau = std::sqrt(tau2_deg2);
  const auto half_for = [&](double shift) {
    return std::min(side - 1, static_cast<int>(std::ceil((std::abs(shift) + 5.0 * tau) / step_deg)));
  };
  // Per point: the box its forward values live on, those values (normalised) and its likelihood there.
  std::vector<Box> box(n);
  std::vector<std::vector<double>> alpha(n), like(n);
  Transition transition(side);
  std::vector<double> pred, row_frac, col_frac;
  std::vector<int> row_node, col_node;
  // Multiplies the prediction on `b` by point i's likelihood (scaled to a largest of 1 on b), prunes and
  // shrinks the box to what remains; stores α_i, L_i.
  const auto update = [&](std::size_t i, const Box& b, const std::vector<double>& prediction) {
    std::vector<double> L(b.size(), 1.0);
    if (data[i]) {
      const double var = s2_nT2 + (map_var_nT2.empty() ? 0.0 : map_var_nT2[i]);
      double best = std::numeric_limits<double>::infinity();
      AxisCells(grid.lat(), lat_deg[i], step_deg, radius, b.r0, b.r1, &row_node, &row_frac);
      AxisCells(grid.lon(), lon_deg[i], step_deg, radius, b.c0, b.c1, &col_node, &col_frac);
      const std::vector<double>& values = grid.values(layer);
      const int stride = grid.lon().count;
      for (int r = b.r0; r <= b.r1; ++r) {
        const int ni = row_node[r - b.r0];
        const double u = row_frac[r - b.r0];
        for (int c = b.c0; c <= b.c1; ++c) {
          const std::size_t s = static_cast<std::size_t>(r - b.r0) * b.cols() + (c - b.c0);
          const int nj = col_node[c - b.c0];
          if (prediction[s] == 0.0) {
            L[s] = std::numeric_limits<double>::infinity();
            continue;
          }
          double d2 = cap2;  // off the map: the cap
          if (ni >= 0 && nj >= 0) {
            const double v = col_frac[c - b.c0];
            const double* row0 = values.data() + static_cast<std::size_t>(ni) * stride + nj;
            const double* row1 = row0 + stride;
            const double m = (1 - u) * ((1 - v) * row0[0] + v * row0[1]) + u * ((1 - v) * row1[0] + v * row1[1]);
            d2 = std::min(cap2, (m - measured_nT[i]) * (m - measured_nT[i]));
          }
          L[s] = d2 / var;
          best = std::min(best, L[s]);
        }
      }
      // exp(−700) ≈ 1e-304: beyond it the value is 0 for every purpose (and exp's underflow path is slow).
      for (double& x : L) x = x - best > 1400.0 ? 0.0 : std::exp(-0.5 * (x - best));
    }
    double top = 0.0;
    std::vector<double> a(b.size());
    for (std::size_t s = 0; s < a.size(); ++s) top = std::max(top, a[s] = prediction[s] * L[s]);
    Box nb{b.r1 + 1, b.r0 - 1, b.c1 + 1, b.c0 - 1};
    for (int r = b.r0; r <= b.r1; ++r) {
      for (int c = b.c0; c <= b.c1; ++c) {
        if (a[static_cast<std::size_t>(r - b.r0) * b.cols() + (c - b.c0)] > kPrune * top) {
          nb.r0 = std::min(nb.r0, r), nb.r1 = std::max(nb.r1, r), nb.c0 = std::min(nb.c0, c), nb.c1 = std::max(nb.c1, c);
        }
      }
    }
    if (nb.size() == 0) nb = b;  // nothing left (cannot happen with top > 0): keep the box
    box[i] = nb;
    alpha[i].assign(nb.size(), 0.0);
    like[i].assign(nb.size(), 1.0);
    double sum = 0.0;
    for (int r = nb.r0; r <= nb.r1; ++r) {
      for (int c = nb.c0; c <= nb.c1; ++c) {
        const std::size_t s = static_cast<std::size_t>(r - b.r0) * b.cols() + (c - b.c0);
        const std::size_t t = static_cast<std::size_t>(r - nb.r0) * nb.cols() + (c - nb.c0);
        const double v = a[s] > kPrune * top ? a[s] : 0.0;
        alpha[i][t] = v;
        like[i][t] = L[s];
        sum += v;
      }
    }
    if (sum > 0.0) {
      for (double& x : alpha[i]) x /= sum;
    }
  };
  // Forward: a uniform start over the grid.
  const Box full{0, side - 1, 0, side - 1};
  update(0, full, std::vector<double>(full.size(), 1.0));
  for (std::size_t i = 1; i < n; ++i) {
    const double sa = e_lat[i] - e_lat[i - 1], sb = e_lon[i] - e_lon[i - 1];
    const int ha = half_for(sa), hb = half_for(sb);
    const Box to = Grow(box[i - 1], ha, hb, side);
    transition.Apply(alpha[i - 1], box[i - 1], Kernel(sa, step_deg, tau2_deg2, ha), ha,
                     Kernel(sb, step_deg, tau2_deg2, hb), hb, true, to, &pred);
    update(i, to, pred);
  }
  // Backward: β_{n−1} = 1; β_i = Tᵀ (L_{i+1} β_{i+1}) on box i; posterior ∝ α β.
  std::vector<double> beta(box[n - 1].size(), 1.0), next, x;
  const double cell = step_deg * step_deg / 12.0;
  for (std::size_t i = n; i-- > 0;) {
    if (i + 1 < n) {
      x.resize(beta.size());
      for (std::size_t s = 0; s < beta.size(); ++s) x[s] = beta[s] * like[i + 1][s];
      const double sa = e_lat[i + 1] - e_lat[i], sb = e_lon[i + 1] - e_lon[i];
      const int ha = half_for(sa), hb = half_for(sb);
      transition.Apply(x, box[i + 1], Kernel(sa, step_deg, tau2_deg2, ha), ha, Kernel(sb, step_deg, tau2_deg2, hb),
                       hb, false, box[i], &next);
      double top = 0.0;
      for (double v : next) top = std::max(top, v);
      if (top > 0.0) {
        for (double& v : next) v /= top;
      }
      beta.swap(next);
    }
    const Box& b = box[i];
    double sum = 0.0;
    for (std::size_t s = 0; s < b.size(); ++s) sum += alpha[i][s] * beta[s];
    if (!(sum > 0.0)) continue;
    const Eigen::Matrix2d inv = cov[i].inverse();
    if (!inv.allFinite()) continue;
    // Σ p d dᵀ over the cells outside the published basin (dᵀ C⁻¹ d > chi2), with each cell's own h²/12.
    double saa = 0.0, sab = 0.0, sbb = 0.0, sa = 0.0, sb = 0.0, mass = 0.0, edge = 0.0;
    double taa = 0.0, tab = 0.0, tbb = 0.0, ta = 0.0, tb = 0.0;  // the same sums over every cell
    for (int r = b.r0; r <= b.r1; ++r) {
      const double da = (r - radius) * step_deg;
      for (int c = b.c0; c <= b.c1; ++c) {
        const std::size_t s = static_cast<std::size_t>(r - b.r0) * b.cols() + (c - b.c0);
        const double p = alpha[i][s] * beta[s];
        if (p == 0.0) continue;
        const double db = (c - radius) * step_deg;
        if (r == 0 || r == side - 1 || c == 0 || c == side - 1) edge += p;
        taa += p * da * da;
        tab += p * da * db;
        tbb += p * db * db;
        ta += p * da;
        tb += p * db;
        if (inv(0, 0) * da * da + 2.0 * inv(0, 1) * da * db + inv(1, 1) * db * db <= chi2) continue;
        saa += p * da * da;
        sab += p * da * db;
        sbb += p * db * db;
        sa += p * da;
        sb += p * db;
        mass += p;
      }
    }
    mass /= sum;
    out.far_moment[i] << saa / sum + mass * cell, sab / sum, sab / sum, sbb / sum + mass * cell;
    out.far_mean[i] << sa / sum, sb / sum;
    out.far_mass[i] = mass;
    out.edge_mass[i] = edge / sum;
    const Eigen::Vector2d mu(ta / sum, tb / sum);
    out.mean[i] = mu;
    out.spread[i] << taa / sum - mu(0) * mu(0) + cell, tab / sum - mu(0) * mu(1), tab / sum - mu(0) * mu(1),
        tbb / sum - mu(1) * mu(1) + cell;
  }
  return out;
}

}  // namespace magnav::mapmatch::internal
