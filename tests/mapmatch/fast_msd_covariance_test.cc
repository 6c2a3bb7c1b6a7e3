// Fast MSD's covariance (mapmatch/src/fast_msd_covariance.h): the O(N)
// block-tridiagonal recursion gives the diagonal blocks of the dense inverse
// of the posterior precision, and its residual variance counts the smoother's
// effective parameters.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Dense>
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

}  // namespace
}  // namespace magnav::mapmatch
