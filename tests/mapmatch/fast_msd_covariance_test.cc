// Fast MSD's covariance (mapmatch/src/fast_msd_covariance.h): the O(N)
// block-tridiagonal recursion gives the diagonal blocks of the dense inverse
// of the posterior precision, and its residual variance counts the smoother's
// effective parameters; the error covariance fast MSD writes
// (FastMsdErrorCovariance) is the dense sandwich, and its O(N) recursion
// (SandwichDiagonalBlocks) gives what the O(N²) column sums it replaced gave.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <gtest/gtest.h>

#include "fast_msd_covariance.h"

namespace magnav::mapmatch {
namespace {

TEST(FastMsdCovariance, RecursionIsTheDenseInverse) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 1.2e4), res(0.0, 3.0);
  const std::size_t n = 40;
  const double lambda = 1e7;
  std::vector<double> gl(n), gn(n), r(n);
  std::vector<char> data(n, 1);
  for (std::size_t i = 0; i < n; ++i) gl[i] = g(rng), gn[i] = g(rng), r[i] = res(rng);
  data[5] = data[17] = 0;  // points without a data term (off the map)
  const internal::PathCovariance c = internal::FastMsdCovariance(gl, gn, r, data, lambda);
  // Dense: P = Gᵀ W G + (λ/2) L, w = 1/2 at the ends.
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double w = (i == 0 || i == n - 1) ? 0.5 : 1.0;
    if (data[i]) {
      const Eigen::Vector2d v(gl[i], gn[i]);
      P.block<2, 2>(2 * i, 2 * i) += w * v * v.transpose();
    }
    if (i + 1 < n) {
      const Eigen::Matrix2d h = 0.5 * lambda * Eigen::Matrix2d::Identity();
      P.block<2, 2>(2 * i, 2 * i) += h;
      P.block<2, 2>(2 * i + 2, 2 * i + 2) += h;
      P.block<2, 2>(2 * i, 2 * i + 2) -= h;
      P.block<2, 2>(2 * i + 2, 2 * i) -= h;
    }
  }
  const Eigen::MatrixXd C = P.inverse();
  double sw = 0.0, swr2 = 0.0, edf = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!data[i]) continue;
    const double w = (i == 0 || i == n - 1) ? 0.5 : 1.0;
    const Eigen::Vector2d v(gl[i], gn[i]);
    sw += w;
    swr2 += w * r[i] * r[i];
    edf += w * v.dot(C.block<2, 2>(2 * i, 2 * i) * v);
  }
  EXPECT_NEAR(c.edf, edf, 1e-9 * edf);
  const double s2 = swr2 / std::max(sw - edf, 1.0);  // at least one residual degree of freedom
  EXPECT_NEAR(c.s2_nT2, s2, 1e-9 * s2);
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_NEAR(c.lat_lat[i], s2 * C(2 * i, 2 * i), 1e-7 * c.lat_lat[i]) << i;
    EXPECT_NEAR(c.lat_lon[i], s2 * C(2 * i, 2 * i + 1), 1e-7 * c.lat_lat[i]) << i;
    EXPECT_NEAR(c.lon_lon[i], s2 * C(2 * i + 1, 2 * i + 1), 1e-7 * c.lon_lon[i]) << i;
  }
}

TEST(FastMsdCovariance, NoDataTermIsInfinite) {
  const std::vector<double> z(5, 0.0);
  const internal::PathCovariance c = internal::FastMsdCovariance(z, z, z, std::vector<char>(5, 0), 1e7);
  for (double v : c.lat_lat) EXPECT_TRUE(std::isinf(v));
}

// The error covariance (FastMsdErrorCovariance) is the dense sandwich
// M⁻¹ (Gᵀ W R W G + (λ/2)² τ² L) M⁻¹ with its own σ², τ² and no curvature,
// R = diag(σ² + m_i) with m the map's representation error per reading (nT²;
// none when map_var is empty).
void ExpectDenseSandwich(bool with_map_error) {
  std::mt19937 rng(11);
  std::normal_distribution<double> gd(0.0, 2e4), res(0.0, 0.5), e(0.0, 1e-3);
  const std::size_t n = 9;
  const double lambda = 1e7, h = 0.5 * lambda;
  std::vector<double> gl(n), gn(n), r(n), el(n), en(n), zero(n, 0.0);
  std::vector<char> data(n, 1);
  data[4] = 0;  // a point without a data term
  for (std::size_t i = 0; i < n; ++i) gl[i] = gd(rng), gn[i] = gd(rng), r[i] = res(rng), el[i] = e(rng), en[i] = e(rng);
  std::vector<double> map_var;
  if (with_map_error) {
    std::uniform_real_distribution<double> mv(0.0, 0.5);  // up to twice the readings' 0.25 nT²
    for (std::size_t i = 0; i < n; ++i) map_var.push_back(mv(rng));
  }
  const internal::ErrorCovariance c =
      internal::FastMsdErrorCovariance(gl, gn, r, data, el, en, zero, zero, zero, lambda, 6, 0.0, map_var);
  ASSERT_GT(c.s2_nT2, 0.0);
  ASSERT_GT(c.tau2_deg2, 0.0);
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(2 * n, 2 * n), A = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double w = !data[i] ? 0.0 : (i == 0 || i == n - 1) ? 0.5 : 1.0;
    const Eigen::Vector2d g(gl[i], gn[i]);
    M.block<2, 2>(2 * i, 2 * i) += w * g * g.transpose();
    const double reading_var = c.s2_nT2 + (with_map_error ? map_var[i] : 0.0);
    A.block<2, 2>(2 * i, 2 * i) += reading_var * w * w * g * g.transpose();
    if (i + 1 < n) {
      for (int k = 0; k < 2; ++k) {
        for (auto [m, f] : {std::pair{&M, h}, std::pair{&A, h * h * c.tau2_deg2}}) {
          (*m)(2 * i + k, 2 * i + k) += f;
          (*m)(2 * i + 2 + k, 2 * i + 2 + k) += f;
          (*m)(2 * i + k, 2 * i + 2 + k) -= f;
          (*m)(2 * i + 2 + k, 2 * i + k) -= f;
        }
      }
    }
  }
  const Eigen::MatrixXd Mi = M.inverse();
  const Eigen::MatrixXd C = Mi * A * Mi;
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_NEAR(c.lat_lat[i], C(2 * i, 2 * i), 1e-6 * C(2 * i, 2 * i)) << i;
    EXPECT_NEAR(c.lat_lon[i], C(2 * i, 2 * i + 1), 1e-6 * std::sqrt(C(2 * i, 2 * i) * C(2 * i + 1, 2 * i + 1))) << i;
    EXPECT_NEAR(c.lon_lon[i], C(2 * i + 1, 2 * i + 1), 1e-6 * C(2 * i + 1, 2 * i + 1)) << i;
  }
}

TEST(FastMsdCovariance, ErrorCovarianceIsTheDenseSandwich) { ExpectDenseSandwich(false); }

// The map's representation error enters each reading's variance beside σ²
// (and σ², τ² are the same as without it: the EM does not see it).
TEST(FastMsdCovariance, MapErrorIsInTheReadingVariance) {
  ExpectDenseSandwich(true);
  std::mt19937 rng(3);
  std::normal_distribution<double> gd(0.0, 2e4), res(0.0, 0.5), e(0.0, 1e-3);
  const std::size_t n = 30;
  std::vector<double> gl(n), gn(n), r(n), el(n), en(n), zero(n, 0.0), map_var(n, 0.25);
  for (std::size_t i = 0; i < n; ++i) {
    gl[i] = gd(rng), gn[i] = gd(rng), r[i] = res(rng), el[i] = e(rng), en[i] = e(rng);
  }
  const std::vector<char> data(n, 1);
  const internal::ErrorCovariance a =
      internal::FastMsdErrorCovariance(gl, gn, r, data, el, en, zero, zero, zero, 1e7);
  const internal::ErrorCovariance b =
      internal::FastMsdErrorCovariance(gl, gn, r, data, el, en, zero, zero, zero, 1e7, 6, 0.0, map_var);
  EXPECT_EQ(a.s2_nT2, b.s2_nT2);
  EXPECT_EQ(a.tau2_deg2, b.tau2_deg2);
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_GT(b.lat_lat[i] + b.lon_lon[i], a.lat_lat[i] + a.lon_lon[i]) << i;
  }
}

// The bilinear interpolant's error bound: (Δlat²/8)|H_ll| + (Δlon²/8)|H_nn|, the cross term left out
// (bilinear reproduces lat·lon), and it bounds the error of a quadratic's interpolant over a cell.
TEST(FastMsdCovariance, BilinearErrorBound) {
  Eigen::Matrix2d H;
  H << -4e5, 7e5, 7e5, 2e5;  // nT/deg²
  EXPECT_NEAR(internal::BilinearErrorBound(H, 0.001, 0.002), (1e-6 * 4e5 + 4e-6 * 2e5) / 8.0, 1e-15);
  // f = ½ xᵀ H x on the cell [0, 0.001] × [0, 0.002]: the bound holds at every point and is reached at the
  // centre when both curvatures have the same sign.
  const auto f = [](const Eigen::Matrix2d& h, double x, double y) {
    return 0.5 * (h(0, 0) * x * x + 2.0 * h(0, 1) * x * y + h(1, 1) * y * y);
  };
  for (const Eigen::Matrix2d& h : {H, Eigen::Matrix2d(Eigen::Vector2d(3e5, 5e5).asDiagonal())}) {
    const double dx = 0.001, dy = 0.002, bound = internal::BilinearErrorBound(h, dx, dy);
    double worst = 0.0;
    for (int a = 0; a <= 10; ++a) {
      for (int b = 0; b <= 10; ++b) {
        const double s = a / 10.0, t = b / 10.0;
        const double bil = (1 - s) * (1 - t) * f(h, 0, 0) + s * (1 - t) * f(h, dx, 0) +
                           (1 - s) * t * f(h, 0, dy) + s * t * f(h, dx, dy);
        worst = std::max(worst, std::abs(f(h, s * dx, t * dy) - bil));
      }
    }
    EXPECT_LE(worst, bound * (1.0 + 1e-12));
    if (h(0, 1) == 0.0) {
      EXPECT_NEAR(worst, bound, 1e-12 * bound);
    }
  }
}


// ---- The O(N) sandwich (SandwichDiagonalBlocks) ----

using M2 = Eigen::Matrix2d;
using V2 = Eigen::Vector2d;

Eigen::MatrixXd Dense(const internal::BlockTridiagonal& t) {
  const std::size_t n = t.diag.size();
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  for (std::size_t i = 0; i < n; ++i) {
    d.block<2, 2>(2 * i, 2 * i) = t.diag[i];
    if (i + 1 < n) {
      d.block<2, 2>(2 * i, 2 * i + 2) = t.upper[i];
      d.block<2, 2>(2 * i + 2, 2 * i) = t.upper[i].transpose();
    }
  }
  return d;
}

// The smoother's M (gradients ~2e4 nT/deg, λ = 1e7, every 7th point and the `gap` points from n/3 on
// without data) and a middle factor of its form (σ² = 0.3 nT², τ² = 1e-7 deg²) plus, when `generic`,
// random perturbations of every block (A then need not be of the smoother's form, nor definite).
std::pair<internal::BlockTridiagonal, internal::BlockTridiagonal> RandomPair(std::size_t n, unsigned seed,
                                                                              bool generic, std::size_t gap) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gd(0.0, 2e4), u(0.0, 1.0);
  const double h = 0.5e7, kt2 = h * h * 1e-7;
  internal::BlockTridiagonal m, a;
  for (std::size_t i = 0; i < n; ++i) {
    const double d = (i == 0 || i == n - 1) ? 1.0 : 2.0;
    const bool none = i % 7 == 3 || (i >= n / 3 && i < n / 3 + gap);
    const double w = none ? 0.0 : (i == 0 || i == n - 1) ? 0.5 : 1.0;
    const V2 g(gd(rng), gd(rng));
    m.diag.push_back(h * d * M2::Identity() + w * g * g.transpose());
    a.diag.push_back(kt2 * d * M2::Identity() + w * w * 0.3 * g * g.transpose());
    if (i + 1 < n) {
      m.upper.push_back(-h * M2::Identity());
      a.upper.push_back(-kt2 * M2::Identity());
    }
    if (generic) {
      M2 e;
      e << u(rng), u(rng), u(rng), u(rng);
      const M2 sym = 0.2 * h * (e + e.transpose());
      m.diag.back() += sym * sym / (4.0 * h);  // M stays positive definite
      a.diag.back() += 0.5 * kt2 * (e + e.transpose());
      if (i + 1 < n) {
        M2 f;
        f << u(rng), u(rng), u(rng), u(rng);
        a.upper.back() += 0.5 * kt2 * f;
      }
    }
  }
  return {m, a};
}

TEST(FastMsdSandwich, DiagonalBlocksAreTheDenseProduct) {
  for (const std::size_t n : {1u, 2u, 3u, 8u, 41u, 300u}) {
    for (const bool generic : {false, true}) {
      const auto [m, a] = RandomPair(n, 100 + static_cast<unsigned>(n), generic, n / 10);
      const std::vector<M2> x = internal::SandwichDiagonalBlocks(m, a);
      const Eigen::MatrixXd mi = Dense(m).ldlt().solve(Eigen::MatrixXd::Identity(2 * n, 2 * n));
      const Eigen::MatrixXd c = mi * Dense(a) * mi;
      ASSERT_EQ(x.size(), n);
      for (std::size_t i = 0; i < n; ++i) {
        const M2 ref = c.block<2, 2>(2 * i, 2 * i);
        EXPECT_LE((x[i] - ref).norm(), 1e-9 * ref.norm())
            << "n " << n << " generic " << generic << " i " << i;
      }
    }
  }
}

// The O(N²) computation the recursion replaced (one block-tridiagonal solve per reading and per random-walk
// step and axis, summed over the columns of a square root of A), kept as the oracle: the same EM, the same
// curvature passes.
struct Tridiag {
  std::vector<M2> s_inv;
  double h = 0.0;
  Tridiag(const std::vector<V2>& g, const std::vector<double>& omega, double h_) : s_inv(g.size()), h(h_) {
    const std::size_t n = g.size();
    for (std::size_t i = 0; i < n; ++i) {
      M2 D = h * ((i == 0 || i == n - 1) ? 1.0 : 2.0) * M2::Identity() + omega[i] * g[i] * g[i].transpose();
      if (i > 0) D -= h * h * s_inv[i - 1];
      s_inv[i] = D.inverse();
    }
  }
  void Solve(std::vector<V2>* b, std::vector<V2>* x) const {
    const std::size_t n = s_inv.size();
    for (std::size_t i = 1; i < n; ++i) (*b)[i] += h * (s_inv[i - 1] * (*b)[i - 1]);
    (*x)[n - 1] = s_inv[n - 1] * (*b)[n - 1];
    for (std::size_t i = n - 1; i-- > 0;) (*x)[i] = s_inv[i] * ((*b)[i] + h * (*x)[i + 1]);
  }
  void Blocks(std::vector<M2>* diag, std::vector<M2>* off) const {
    const std::size_t n = s_inv.size();
    diag->assign(n, M2::Zero());
    off->assign(n, M2::Zero());
    (*diag)[n - 1] = s_inv[n - 1];
    for (std::size_t i = n - 1; i-- > 0;) {
      (*off)[i] = h * s_inv[i] * (*diag)[i + 1];
      (*diag)[i] = s_inv[i] + h * (*off)[i] * s_inv[i].transpose();
      (*diag)[i] = 0.5 * ((*diag)[i] + (*diag)[i].transpose());
    }
  }
};

internal::ErrorCovariance ErrorCovarianceByColumns(
    const std::vector<double>& g_lat, const std::vector<double>& g_lon, const std::vector<double>& resid,
    const std::vector<char>& data, const std::vector<double>& e_lat, const std::vector<double>& e_lon,
    const std::vector<double>& h_ll, const std::vector<double>& h_ln, const std::vector<double>& h_nn,
    double lambda, int curvature_iterations) {
  const std::size_t n = g_lat.size();
  internal::ErrorCovariance out;
  const internal::PathCovariance laplace = internal::FastMsdCovariance(g_lat, g_lon, resid, data, lambda);
  const double h = 0.5 * lambda;
  std::vector<V2> g(n, V2::Zero());
  std::vector<double> w(n, 0.0), y(n, 0.0);
  double sw = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!data[i]) continue;
    g[i] = V2(g_lat[i], g_lon[i]);
    w[i] = (i == 0 || i == n - 1) ? 0.5 : 1.0;
    y[i] = g[i].dot(V2(e_lat[i], e_lon[i])) - resid[i];
    sw += w[i];
  }
  double s2 = laplace.s2_nT2, tau2 = s2 / h;
  std::vector<M2> diag, off;
  std::vector<V2> mu(n), b(n);
  for (int it = 0; it < 100; ++it) {
    const Tridiag t(g, w, s2 / tau2);
    for (std::size_t i = 0; i < n; ++i) b[i] = w[i] * y[i] * g[i];
    t.Solve(&b, &mu);
    t.Blocks(&diag, &off);
    double rs = 0.0, ds = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (w[i] > 0.0) {
        const double r = y[i] - g[i].dot(mu[i]);
        rs += w[i] * (r * r + s2 * g[i].dot(diag[i] * g[i]));
      }
      if (i + 1 < n) {
        ds += (mu[i + 1] - mu[i]).squaredNorm() +
              s2 * (diag[i].trace() + diag[i + 1].trace() - 2.0 * off[i].trace());
      }
    }
    const double s2_new = rs / sw, tau2_new = ds / (2.0 * static_cast<double>(n - 1));
    if (!(s2_new > 0.0) || !(tau2_new > 0.0) || !std::isfinite(s2_new) || !std::isfinite(tau2_new)) break;
    const bool done = std::abs(s2_new - s2) <= 1e-9 * s2 && std::abs(tau2_new - tau2) <= 1e-9 * tau2;
    s2 = s2_new;
    tau2 = tau2_new;
    if (done) break;
  }
  out.s2_nT2 = s2;
  out.tau2_deg2 = tau2;
  out.edf = laplace.edf;
  const Tridiag m(g, w, h);
  std::vector<double> v(n, 0.0), last_change(n, std::numeric_limits<double>::infinity());
  std::vector<char> held(n, 0);  // the contraction rule (fast_msd_covariance.h)
  std::vector<M2> cov(n);
  std::vector<V2> x(n);
  const double kt = h * std::sqrt(tau2);
  for (int pass = 0; pass <= std::max(curvature_iterations - 1, 0); ++pass) {
    std::fill(cov.begin(), cov.end(), M2::Zero());
    const auto accumulate = [&]() {
      m.Solve(&b, &x);
      for (std::size_t i = 0; i < n; ++i) cov[i] += x[i] * x[i].transpose();
    };
    for (std::size_t j = 0; j < n; ++j) {
      if (w[j] == 0.0) continue;
      std::fill(b.begin(), b.end(), V2::Zero());
      b[j] = w[j] * std::sqrt(s2 + v[j]) * g[j];
      accumulate();
    }
    for (std::size_t j = 0; j + 1 < n; ++j) {
      for (int axis = 0; axis < 2; ++axis) {
        std::fill(b.begin(), b.end(), V2::Zero());
        b[j + 1](axis) = kt;
        b[j](axis) = -kt;
        accumulate();
      }
    }
    if (pass + 1 >= curvature_iterations) break;
    for (std::size_t i = 0; i < n; ++i) {
      if (held[i]) continue;
      M2 H;
      H << h_ll[i], h_ln[i], h_ln[i], h_nn[i];
      const M2 a = H * cov[i];
      const double next = 0.5 * (a(0, 0) * a(0, 0) + 2.0 * a(0, 1) * a(1, 0) + a(1, 1) * a(1, 1)) +
                          0.25 * a.trace() * a.trace();
      if (!internal::CurvatureUpdateContracts(v[i], next, last_change[i], s2) && w[i] > 0.0) {
        held[i] = 1;
        continue;
      }
      last_change[i] = std::abs(next - v[i]);
      if (std::isfinite(next)) v[i] = next;
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    out.lat_lat.push_back(cov[i](0, 0));
    out.lat_lon.push_back(0.5 * (cov[i](0, 1) + cov[i](1, 0)));
    out.lon_lon.push_back(cov[i](1, 1));
  }
  return out;
}

// A path of the generated kind: gradients of a few 1e4 nT/deg, residuals of σ ≈ 0.5 nT, corrections a
// random walk of ~3e-4 deg per point, the map's curvature ~1e6 nT/deg² (enough that the curvature passes
// change the result), stretches without a data term.
struct LinearisedPath {
  std::vector<double> gl, gn, r, el, en, hll, hln, hnn;
  std::vector<char> data;
};
LinearisedPath RandomPath(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gd(0.0, 2e4), res(0.0, 0.5), step(0.0, 3e-4), hd(0.0, 1e6);
  LinearisedPath p;
  double el = 0.0, en = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    el += step(rng);
    en += step(rng);
    p.gl.push_back(gd(rng));
    p.gn.push_back(gd(rng));
    p.r.push_back(res(rng));
    p.el.push_back(el);
    p.en.push_back(en);
    p.hll.push_back(hd(rng));
    p.hln.push_back(hd(rng));
    p.hnn.push_back(hd(rng));
    p.data.push_back((i % 11 == 5 || (i >= n / 3 && i < n / 3 + n / 10)) ? 0 : 1);
  }
  if (n > 3) p.data[0] = 0;  // a first point without data as well
  return p;
}

TEST(FastMsdSandwich, ErrorCovarianceIsTheColumnSums) {
  for (const std::size_t n : {2u, 3u, 9u, 60u, 250u}) {
    const LinearisedPath p = RandomPath(n, 500 + static_cast<unsigned>(n));
    for (const int passes : {1, 6}) {
      const internal::ErrorCovariance c = internal::FastMsdErrorCovariance(
          p.gl, p.gn, p.r, p.data, p.el, p.en, p.hll, p.hln, p.hnn, 1e7, passes);
      const internal::ErrorCovariance o =
          ErrorCovarianceByColumns(p.gl, p.gn, p.r, p.data, p.el, p.en, p.hll, p.hln, p.hnn, 1e7, passes);
      ASSERT_GT(c.s2_nT2, 0.0);
      ASSERT_GT(c.tau2_deg2, 0.0);
      EXPECT_NEAR(c.s2_nT2, o.s2_nT2, 1e-12 * o.s2_nT2);  // the same EM
      EXPECT_NEAR(c.tau2_deg2, o.tau2_deg2, 1e-12 * o.tau2_deg2);
      ASSERT_EQ(c.lat_lat.size(), n);
      ASSERT_EQ(o.lat_lat.size(), n);
      for (std::size_t i = 0; i < n; ++i) {
        const double s = std::sqrt(o.lat_lat[i] * o.lon_lon[i]);
        const auto where = [&] { return "n " + std::to_string(n) + " passes " + std::to_string(passes); };
        EXPECT_NEAR(c.lat_lat[i], o.lat_lat[i], 1e-9 * o.lat_lat[i]) << where() << " i " << i;
        EXPECT_NEAR(c.lat_lon[i], o.lat_lon[i], 1e-9 * s) << where() << " i " << i;
        EXPECT_NEAR(c.lon_lon[i], o.lon_lon[i], 1e-9 * o.lon_lon[i]) << where() << " i " << i;
      }
    }
  }
}

// 20 000 points (a 2 000-point stretch without data among them): every block finite and positive definite,
// and at sampled points equal to eᵀ M⁻¹ A M⁻¹ e from two sparse solves (Eigen's LDLᵀ of the whole M).
TEST(FastMsdSandwich, LongPathIsFiniteAndMatchesSampledColumns) {
  const std::size_t n = 20000;
  const auto [m, a] = RandomPair(n, 7, false, 2000);
  const std::vector<M2> x = internal::SandwichDiagonalBlocks(m, a);
  ASSERT_EQ(x.size(), n);
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_TRUE(x[i].allFinite()) << i;
    ASSERT_GT(x[i](0, 0), 0.0) << i;
    ASSERT_GT(x[i].determinant(), 0.0) << i;
  }
  const auto sparse = [n](const internal::BlockTridiagonal& t) {
    std::vector<Eigen::Triplet<double>> e;
    for (std::size_t i = 0; i < n; ++i) {
      for (int r = 0; r < 2; ++r) {
        for (int c = 0; c < 2; ++c) {
          const auto I = static_cast<int>(2 * i);
          e.emplace_back(I + r, I + c, t.diag[i](r, c));
          if (i + 1 < n) {
            e.emplace_back(I + r, I + 2 + c, t.upper[i](r, c));
            e.emplace_back(I + 2 + c, I + r, t.upper[i](r, c));
          }
        }
      }
    }
    Eigen::SparseMatrix<double> s(static_cast<int>(2 * n), static_cast<int>(2 * n));
    s.setFromTriplets(e.begin(), e.end());
    return s;
  };
  const Eigen::SparseMatrix<double> ms = sparse(m), as = sparse(a);
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(ms);
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  for (const std::size_t i : {0u, 1u, 2u, 4321u, 6665u, 6666u, 7666u, 8665u, 8666u, 12345u, 19998u, 19999u}) {
    Eigen::MatrixXd e = Eigen::MatrixXd::Zero(static_cast<int>(2 * n), 2);
    e(static_cast<int>(2 * i), 0) = 1.0;
    e(static_cast<int>(2 * i) + 1, 1) = 1.0;
    const Eigen::MatrixXd c = ldlt.solve(e);
    const M2 ref = c.transpose() * (as * c);
    EXPECT_LE((x[i] - ref).norm(), 1e-9 * ref.norm()) << i;
  }
}

// Near a map extremum (gradient small, curvature large) the curvature passes' loop gains more than 1:
// v_i grows as C_i², C_i with v_i. Without the contraction rule (main before 2026-11-26 07:00) the six
// passes write σ = 8.8e10° on this path (2 passes: 0.023°; generated map paths: up to 2.3e8°). With it
// (fast_msd_covariance.h) every point's term is held at its last contracting pass: the covariance is
// linear in σ² + v and each v is at most (passes − 1) × the first correction (every change no larger
// than the first), so trace C ≤ 5 × the two-pass trace; the held points are counted.
LinearisedPath NearAnExtremum(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gd(0.0, 300.0), res(0.0, 3.0), step(0.0, 3e-4), hd(0.0, 5e4);
  LinearisedPath p;
  double el = 0.0, en = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    el += step(rng);
    en += step(rng);
    p.gl.push_back(gd(rng));
    p.gn.push_back(gd(rng));
    p.r.push_back(res(rng));
    p.el.push_back(el);
    p.en.push_back(en);
    const double hh = hd(rng);
    p.hll.push_back(hh);
    p.hln.push_back(0.1 * hh);
    p.hnn.push_back(hh);
    p.data.push_back(1);
  }
  return p;
}

TEST(FastMsdCurvature, PassesThatDoNotContractAreHeld) {
  const LinearisedPath p = NearAnExtremum(40, 91);
  const internal::ErrorCovariance two =
      internal::FastMsdErrorCovariance(p.gl, p.gn, p.r, p.data, p.el, p.en, p.hll, p.hln, p.hnn, 1e5, 2);
  const internal::ErrorCovariance six =
      internal::FastMsdErrorCovariance(p.gl, p.gn, p.r, p.data, p.el, p.en, p.hll, p.hln, p.hnn, 1e5, 6);
  ASSERT_EQ(six.lat_lat.size(), p.gl.size());
  EXPECT_GT(six.curvature_limited_points, 0);
  EXPECT_EQ(two.curvature_limited_points, 0);  // one correction: nothing to compare a change with
  double largest = 0.0;
  for (std::size_t i = 0; i < p.gl.size(); ++i) {
    const double t6 = six.lat_lat[i] + six.lon_lon[i], t2 = two.lat_lat[i] + two.lon_lon[i];
    ASSERT_TRUE(std::isfinite(t6)) << i;
    EXPECT_LE(t6, 5.0 * t2 * (1.0 + 1e-9)) << i;
    EXPECT_GT(six.lat_lat[i] * six.lon_lon[i] - six.lat_lon[i] * six.lat_lon[i], 0.0) << i;
    largest = std::max(largest, std::sqrt(t6));
  }
  EXPECT_LT(largest, 0.1);  // deg; without the rule 8.8e10 here
}

// The contraction rule itself: a shrinking change is taken, a growing or non-finite one is not, a change
// below 1e-9 of σ² + v is convergence either way.
TEST(FastMsdCurvature, ContractionRule) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(internal::CurvatureUpdateContracts(0.0, 5.0, inf, 1.0));    // the first correction
  EXPECT_TRUE(internal::CurvatureUpdateContracts(5.0, 7.0, 5.0, 1.0));    // 2 <= 5
  EXPECT_FALSE(internal::CurvatureUpdateContracts(5.0, 11.0, 5.0, 1.0));  // 6 > 5
  EXPECT_FALSE(internal::CurvatureUpdateContracts(5.0, inf, 5.0, 1.0));
  EXPECT_TRUE(internal::CurvatureUpdateContracts(5.0, 5.0 + 1e-10, 1e-12, 1.0));
}

// Never wider than the prior: eigenvalues above the cap are clamped to it (the eigenvectors kept), one
// inside is untouched, a non-finite covariance becomes the prior.
TEST(FastMsdCurvature, CovarianceIsCappedAtThePrior) {
  const double cap = 0.15 * 0.15 / 3.0;
  M2 c;
  c << 1e6, 0.5, 0.5, 1e-6;  // eigenvalues ≈ 1e6 and 7.5e-7
  ASSERT_TRUE(internal::CapAtPrior(&c, cap));
  const Eigen::SelfAdjointEigenSolver<M2> es(c);
  EXPECT_NEAR(es.eigenvalues()(1), cap, 1e-9 * cap);
  EXPECT_NEAR(es.eigenvalues()(0), 7.5e-7, 1e-9);
  M2 inside;
  inside << 1e-6, 2e-7, 2e-7, 3e-6;
  const M2 before = inside;
  EXPECT_FALSE(internal::CapAtPrior(&inside, cap));
  EXPECT_EQ(inside, before);
  EXPECT_FALSE(internal::CapAtPrior(&inside, 0.0));  // no prior, no cap
  M2 bad;
  bad << std::numeric_limits<double>::infinity(), 0.0, 0.0, 1.0;
  ASSERT_TRUE(internal::CapAtPrior(&bad, cap));
  EXPECT_TRUE(bad.allFinite());
  EXPECT_LE(bad.trace(), 2.0 * cap * (1.0 + 1e-12));
  // Through FastMsdErrorCovariance: the runaway path above, capped.
  const LinearisedPath p = NearAnExtremum(40, 91);
  const internal::ErrorCovariance e = internal::FastMsdErrorCovariance(p.gl, p.gn, p.r, p.data, p.el, p.en,
                                                                       p.hll, p.hln, p.hnn, 1e5, 6, 1e-8);
  int capped = 0;
  for (std::size_t i = 0; i < p.gl.size(); ++i) {
    EXPECT_LE(e.lat_lat[i] + e.lon_lon[i], 2e-8 * (1.0 + 1e-9)) << i;
    capped += e.prior_limited[i];
  }
  EXPECT_EQ(capped, e.prior_limited_points);
}

}  // namespace
}  // namespace magnav::mapmatch
