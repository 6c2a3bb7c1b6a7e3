// core/nees.h: the run-averaged NEES interval against tabulated χ² quantiles,
// and ANEES / interval shares on draws with a right and a wrong covariance.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "magnav/core/nees.h"

namespace magnav {
namespace {

TEST(NeesInterval, MatchesChiSquareTables) {
  // χ²(2): 0.0506, 7.3778 (two-sided 95 %); χ²(40)/20: 24.433/20, 59.342/20.
  const NeesInterval one = RunAveragedNeesInterval(1, 2);
  EXPECT_NEAR(one.lo, 0.050636, 1e-5);
  EXPECT_NEAR(one.hi, 7.377759, 1e-5);
  const NeesInterval twenty = RunAveragedNeesInterval(20, 2);
  EXPECT_NEAR(twenty.lo, 24.4330 / 20, 1e-4);
  EXPECT_NEAR(twenty.hi, 59.3417 / 20, 1e-4);
  // χ²(60)/20 (3 dof): 40.4817, 83.2977.
  const NeesInterval three = RunAveragedNeesInterval(20, 3);
  EXPECT_NEAR(three.lo, 40.4817 / 20, 1e-4);
  EXPECT_NEAR(three.hi, 83.2977 / 20, 1e-4);
  EXPECT_THROW(RunAveragedNeesInterval(0, 2), std::invalid_argument);
  EXPECT_THROW(RunAveragedNeesInterval(5, 0), std::invalid_argument);
  EXPECT_THROW(RunAveragedNeesInterval(5, 2, 1.0), std::invalid_argument);
}

TEST(ChiSquareQuantile, MatchesTablesAndItsEdges) {
  EXPECT_NEAR(ChiSquareQuantile(0.9999, 2), -2.0 * std::log(1e-4), 1e-9);  // 18.42: the localizer's 2-dof gate
  EXPECT_NEAR(ChiSquareQuantile(0.9999, 3), 21.1075, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.95, 1), 3.8415, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.99, 16), 32.0, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.99, 276), 333.6, 0.2);  // the tracker's offset score test, 92 segments
  EXPECT_TRUE(std::isinf(ChiSquareQuantile(1.0, 3)));
  EXPECT_EQ(ChiSquareQuantile(0.0, 3), 0.0);
  EXPECT_EQ(ChiSquareQuantile(0.5, 0.0), 0.0);
  EXPECT_EQ(ChiSquareQuantile(std::nan(""), 3), 0.0);
}

// 2-D errors drawn with σ = 1 per axis; the estimator says σ = `claimed`.
std::vector<NeesSample> Draws(double claimed, int runs, int epochs, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<NeesSample> out;
  for (int r = 0; r < runs; ++r) {
    for (int k = 0; k < epochs; ++k) {
      const double ex = n(rng), ey = n(rng);
      out.push_back({r, k, k < epochs / 2 ? "converging" : "converged", (ex * ex + ey * ey) / (claimed * claimed),
                     ex * ex + ey * ey});
    }
  }
  return out;
}

TEST(NeesStats, AcceptsARightCovarianceAndRejectsOneTwiceTooSmallOrLarge) {
  const auto right = ComputeNeesStats(Draws(1.0, 20, 100, 1), 2);
  ASSERT_EQ(right.size(), 3u);  // converging, converged, all
  const NeesRegimeStats& all = right.at("all");
  EXPECT_EQ(all.samples, 2000u);
  EXPECT_EQ(all.runs, 20u);
  EXPECT_EQ(all.epochs, 100u);
  EXPECT_NEAR(all.anees, 2.0, 0.15);
  EXPECT_NEAR(all.rms, std::sqrt(2.0), 0.1);
  EXPECT_TRUE(all.anees_accepted);
  EXPECT_EQ(all.epochs_tested, 100u);
  EXPECT_GE(all.share_inside(), 0.85);  // 95 % expected
  EXPECT_EQ(right.at("converged").epochs, 50u);
  // σ claimed half the truth: NEES ×4 (ANEES 8 > 4); twice: ÷4 (0.5 < 1).
  const NeesRegimeStats small = ComputeNeesStats(Draws(0.5, 20, 100, 1), 2).at("all");
  EXPECT_FALSE(small.anees_accepted);
  EXPECT_LE(small.share_inside(), 0.05);
  const NeesRegimeStats large = ComputeNeesStats(Draws(2.0, 20, 100, 1), 2).at("all");
  EXPECT_FALSE(large.anees_accepted);
  EXPECT_LE(large.share_inside(), 0.05);
}

TEST(NeesStats, SingularCovarianceIsNotDropped) {
  std::vector<NeesSample> s = Draws(1.0, 3, 4, 2);
  s[0].nees = INFINITY;
  const NeesRegimeStats all = ComputeNeesStats(s, 2).at("all");
  EXPECT_TRUE(std::isinf(all.anees));
  EXPECT_FALSE(all.anees_accepted);
  EXPECT_THROW(ComputeNeesStats(s, 0), std::invalid_argument);
}

}  // namespace
}  // namespace magnav
