// Fast MSD's other basins (mapmatch/src/fast_msd_basins.h): the pruned
// forward-backward gives what a dense one over the whole offset grid gives;
// on a map that repeats itself in latitude the posterior mass outside the
// published basin is the other copies' share, on a map without copies none.
#include <cmath>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "fast_msd_basins.h"

namespace magnav::mapmatch {
namespace {

struct Case {
  std::vector<double> lat, lon, meas, e_lat, e_lon, map_var;
  std::vector<char> data;
  std::vector<Eigen::Matrix2d> cov;
};

// A 60-point path along longitude (0.0008° steps, gently bending) measured on
// the map at the truth with ±0.3 nT of fixed pseudo-noise; published = truth;
// corrections constant (no drift in the published path); linearised covariance
// (3e-4°)² per axis.
Case PathOn(const GeoGrid& g) {
  Case c;
  double a = 0.06, b = 0.03;
  for (int k = 0; k < 60; ++k) {
    c.lat.push_back(a);
    c.lon.push_back(b);
    c.meas.push_back(g.Sample(0, a, b)->value_nT + 0.3 * std::sin(1.7 * k));
    c.e_lat.push_back(0.0);
    c.e_lon.push_back(0.0);
    c.map_var.push_back(0.0);
    c.data.push_back(k % 7 == 3 ? 0 : 1);  // some points without a data term
    c.cov.push_back(Eigen::Matrix2d::Identity() * 9e-8);
    a += 0.0002 * std::sin(0.1 * k);
    b += 0.0008;
  }
  return c;
}

// The same model on the whole (2R+1)² grid, no pruning: α, β dense.
std::vector<Eigen::Matrix2d> DenseFarMoment(const GeoGrid& g, const Case& c, double s2, double tau2, double step,
                                            int radius, double chi2) {
  const int side = 2 * radius + 1;
  const std::size_t n = c.lat.size(), S = static_cast<std::size_t>(side) * side;
  std::vector<std::vector<double>> like(n, std::vector<double>(S, 1.0)), alpha(n, std::vector<double>(S));
  for (std::size_t i = 0; i < n; ++i) {
    if (!c.data[i]) continue;
    for (int r = 0; r < side; ++r) {
      for (int q = 0; q < side; ++q) {
        const auto m = g.Sample(0, c.lat[i] + (r - radius) * step, c.lon[i] + (q - radius) * step);
        const double d = m ? m->value_nT - c.meas[i] : 1e9;
        like[i][r * side + q] = std::exp(-0.5 * d * d / s2);
      }
    }
  }
  const auto T = [&](int r, int q, int r2, int q2) {
    const double da = (r2 - r) * step, db = (q2 - q) * step;
    return std::exp(-0.5 * (da * da + db * db) / tau2);
  };
  const auto norm = [](std::vector<double>* v) {
    double s = 0.0;
    for (double x : *v) s += x;
    for (double& x : *v) x /= s;
  };
  alpha[0] = like[0];
  norm(&alpha[0]);
  for (std::size_t i = 1; i < n; ++i) {
    for (std::size_t s2i = 0; s2i < S; ++s2i) {
      double sum = 0.0;
      for (std::size_t s1 = 0; s1 < S; ++s1) {
        sum += alpha[i - 1][s1] * T(s1 / side, s1 % side, s2i / side, s2i % side);
      }
      alpha[i][s2i] = sum * like[i][s2i];
    }
    norm(&alpha[i]);
  }
  std::vector<Eigen::Matrix2d> out(n, Eigen::Matrix2d::Zero());
  std::vector<double> beta(S, 1.0), nb(S);
  for (std::size_t i = n; i-- > 0;) {
    if (i + 1 < n) {
      for (std::size_t s1 = 0; s1 < S; ++s1) {
        double sum = 0.0;
        for (std::size_t s2i = 0; s2i < S; ++s2i) {
          sum += T(s1 / side, s1 % side, s2i / side, s2i % side) * like[i + 1][s2i] * beta[s2i];
        }
        nb[s1] = sum;
      }
      beta = nb;
      norm(&beta);
    }
    double z = 0.0;
    for (std::size_t s = 0; s < S; ++s) z += alpha[i][s] * beta[s];
    const Eigen::Matrix2d inv = c.cov[i].inverse();
    for (std::size_t s = 0; s < S; ++s) {
      const Eigen::Vector2d d((static_cast<int>(s / side) - radius) * step, (static_cast<int>(s % side) - radius) * step);
      if (d.dot(inv * d) <= chi2) continue;
      out[i] += alpha[i][s] * beta[s] / z * (d * d.transpose() + step * step / 12.0 * Eigen::Matrix2d::Identity());
    }
  }
  return out;
}

GeoGrid Bumps() {
  return GeoGrid::FromFunction({0.0, 0.001, 121}, {0.0, 0.001, 121}, "a", [](double la, double lo) {
    return 80.0 * std::exp(-((la - 0.07) * (la - 0.07) + (lo - 0.05) * (lo - 0.05)) / (2 * 0.015 * 0.015)) +
           30.0 * std::sin(90.0 * la) * std::cos(70.0 * lo) + 20.0 * std::cos(150.0 * lo + 40.0 * la);
  });
}

TEST(FastMsdBasins, PrunedIsTheDenseForwardBackward) {
  const GeoGrid g = Bumps();
  const Case c = PathOn(g);
  const double s2 = 0.25, tau2 = 4e-8, step = 0.0005, chi2 = 9.21;
  const int radius = 6;
  const internal::BasinSpread b = internal::FastMsdBasinSpread(g, 0, c.lat, c.lon, c.meas, c.data, c.e_lat, c.e_lon,
                                                               c.cov, s2, c.map_var, tau2, 1e9, step, radius, chi2);
  const std::vector<Eigen::Matrix2d> dense = DenseFarMoment(g, c, s2, tau2, step, radius, chi2);
  double largest = 0.0;
  for (std::size_t i = 0; i < c.lat.size(); ++i) largest = std::max(largest, dense[i].norm());
  ASSERT_GT(largest, 0.0);
  for (std::size_t i = 0; i < c.lat.size(); ++i) {
    EXPECT_LE((b.far_moment[i] - dense[i]).norm(), 1e-6 * largest + 1e-9 * dense[i].norm()) << i;
  }
}

TEST(FastMsdBasins, OtherCopiesOfTheMapCarryTheirShare) {
  // The map repeats itself every 0.004° in latitude; the path runs along
  // longitude, so its latitude is known only up to a copy: inside ±0.012° the
  // copies at 0, ±0.004, ±0.008 and ±0.012° (the last on the grid's edge)
  // fit alike, and most of the mass lies outside the published basin.
  const double kTwoPi = 2.0 * M_PI;
  const GeoGrid periodic = GeoGrid::FromFunction({0.0, 0.001, 121}, {0.0, 0.001, 121}, "a", [&](double la, double lo) {
    return 60.0 * std::sin(kTwoPi * la / 0.004) + 40.0 * std::cos(kTwoPi * lo / 0.013) + 25.0 * std::sin(kTwoPi * lo / 0.007);
  });
  const Case c = PathOn(periodic);
  const internal::BasinSpread b = internal::FastMsdBasinSpread(periodic, 0, c.lat, c.lon, c.meas, c.data, c.e_lat,
                                                               c.e_lon, c.cov, 0.25, c.map_var, 4e-8, 1e9, 0.00025,
                                                               48);
  const std::size_t mid = c.lat.size() / 2;
  EXPECT_GT(b.far_mass[mid], 0.5);
  // At least half the mass at ≥ 0.004° in latitude: a spread ≥ 0.5 · 0.004².
  EXPECT_GT(b.far_moment[mid](0, 0), 0.5 * 0.004 * 0.004);
  EXPECT_LT(b.far_moment[mid](1, 1), 0.1 * b.far_moment[mid](0, 0));  // longitude stays known
  // The mixture's mean offset (basin_mean_shift): the first moment of that
  // outside mass, bounded by it (|m|² ≤ mass · trace S, Cauchy–Schwarz), along
  // latitude only; the copies lie symmetrically about the published point, so
  // it is well inside the copies' spacing; the grid's edge (the ±0.012° copies)
  // holds some of the mass.
  const Eigen::Vector2d& m = b.far_mean[mid];
  EXPECT_LE(m.squaredNorm(), b.far_mass[mid] * b.far_moment[mid].trace() * (1 + 1e-12));
  EXPECT_LT(std::abs(m(0)), 0.5 * 0.004);
  EXPECT_LT(std::abs(m(1)), 0.1 * 0.004);
  EXPECT_GT(b.edge_mass[mid], 0.0);

  // The bumps: no second place near the path, (almost) no mass outside the
  // basin — taken here as (0.001°)² per axis, a map cell (PathOn's 3e-4° is
  // narrower than this posterior's own basin).
  const GeoGrid bumps = Bumps();
  Case d = PathOn(bumps);
  for (auto& m : d.cov) m = Eigen::Matrix2d::Identity() * 1e-6;
  const internal::BasinSpread e = internal::FastMsdBasinSpread(bumps, 0, d.lat, d.lon, d.meas, d.data, d.e_lat,
                                                               d.e_lon, d.cov, 0.25, d.map_var, 4e-8, 1e9, 0.00025, 48);
  for (std::size_t i = 0; i < d.lat.size(); ++i) {
    EXPECT_LT(e.far_mass[i], 0.05) << i;
    // Nothing outside: (almost) no move, and nothing on the grid's edge.
    EXPECT_LT(e.far_mean[i].norm(), 0.05 * 0.012) << i;
    EXPECT_LT(e.edge_mass[i], 1e-3) << i;
  }
}

}  // namespace
}  // namespace magnav::mapmatch
