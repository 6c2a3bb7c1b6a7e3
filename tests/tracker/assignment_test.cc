// The gated assignment (tracker/assignment.h) against brute force on random
// cost matrices: square and rectangular, with forbidden pairs and misses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>

#include "magnav/tracker/assignment.h"

namespace magnav::tracker {
namespace {

// Least total cost over every partial one-to-one assignment (rows may miss).
double BruteForce(const Eigen::MatrixXd& c, const std::vector<double>& miss) {
  const int nr = static_cast<int>(c.rows()), nc = static_cast<int>(c.cols());
  std::vector<bool> taken(nc, false);
  std::function<double(int)> best = [&](int i) -> double {
    if (i == nr) return 0.0;
    double b = miss[i] + best(i + 1);
    for (int j = 0; j < nc; ++j) {
      if (taken[j] || !std::isfinite(c(i, j))) continue;
      taken[j] = true;
      b = std::min(b, c(i, j) + best(i + 1));
      taken[j] = false;
    }
    return b;
  };
  return best(0);
}

// The answer is a valid assignment whose cost is the one it reports.
void ExpectConsistent(const Eigen::MatrixXd& c, const std::vector<double>& miss, const GatedAssignment& a) {
  ASSERT_EQ(a.column_of_row.size(), static_cast<std::size_t>(c.rows()));
  std::vector<bool> used(c.cols(), false);
  double total = 0.0;
  for (int i = 0; i < c.rows(); ++i) {
    const int j = a.column_of_row[i];
    if (j < 0) {
      total += miss[i];
      continue;
    }
    ASSERT_LT(j, c.cols());
    EXPECT_TRUE(std::isfinite(c(i, j))) << "a forbidden pair was made";
    EXPECT_FALSE(used[j]) << "column " << j << " given twice";
    used[j] = true;
    total += c(i, j);
  }
  EXPECT_NEAR(total, a.cost, 1e-9 * (1.0 + std::abs(total)));
}

TEST(GatedAssignment, MatchesBruteForceOnRandomMatrices) {
  std::mt19937_64 rng(2411);
  std::uniform_int_distribution<int> size(0, 6);
  std::uniform_real_distribution<double> u(0.0, 10.0);
  int rectangular = 0, with_forbidden = 0, with_miss = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const int nr = size(rng), nc = size(rng);
    const double p_forbidden = (trial % 3) * 0.3;  // 0, 0.3, 0.6
    Eigen::MatrixXd c(nr, nc);
    bool any_forbidden = false;
    for (int i = 0; i < nr; ++i) {
      for (int j = 0; j < nc; ++j) {
        const bool forbid = u(rng) < 10.0 * p_forbidden;
        c(i, j) = forbid ? kForbidden : u(rng) - (trial % 5 == 0 ? 5.0 : 0.0);  // some negative costs
        any_forbidden = any_forbidden || forbid;
      }
    }
    std::vector<double> miss(nr);
    for (double& m : miss) m = trial % 2 == 0 ? u(rng) : 1e3;  // cheap misses, or misses never worth it
    const GatedAssignment a = SolveGatedAssignment(c, miss);
    ExpectConsistent(c, miss, a);
    const double want = BruteForce(c, miss);
    EXPECT_NEAR(a.cost, want, 1e-9 * (1.0 + std::abs(want))) << "trial " << trial << " " << nr << "x" << nc;
    rectangular += nr != nc ? 1 : 0;
    with_forbidden += any_forbidden ? 1 : 0;
    for (int j : a.column_of_row) with_miss += j < 0 ? 1 : 0;
  }
  // The random draws cover the cases the header promises.
  EXPECT_GT(rectangular, 1000);
  EXPECT_GT(with_forbidden, 1000);
  EXPECT_GT(with_miss, 1000);
}

TEST(GatedAssignment, TwoTracksCompetingForOneCloseFix) {
  // Track 0 is 1 (χ²) from fix 0 and 2 from fix 1; track 1 is 1.5 from fix 0
  // and 50 from fix 1. Greedy (track 0 first) would give track 0 fix 0 and
  // leave track 1 with 50; the global answer gives fix 0 to track 1.
  Eigen::MatrixXd c(2, 2);
  c << 1.0, 2.0, 1.5, 50.0;
  const GatedAssignment a = SolveGatedAssignment(c, {100.0, 100.0});
  EXPECT_EQ(a.column_of_row, (std::vector<int>{1, 0}));
  EXPECT_DOUBLE_EQ(a.cost, 3.5);
}

TEST(GatedAssignment, EveryPairForbiddenMissesEveryRow) {
  Eigen::MatrixXd c = Eigen::MatrixXd::Constant(3, 2, kForbidden);
  c(1, 0) = std::nan("");
  const GatedAssignment a = SolveGatedAssignment(c, {1.0, 2.0, 3.0});
  EXPECT_EQ(a.column_of_row, (std::vector<int>{-1, -1, -1}));
  EXPECT_DOUBLE_EQ(a.cost, 6.0);
}

TEST(GatedAssignment, RefusesBadMissCosts) {
  const Eigen::MatrixXd c = Eigen::MatrixXd::Zero(2, 2);
  EXPECT_THROW(SolveGatedAssignment(c, {1.0}), std::invalid_argument);
  EXPECT_THROW(SolveGatedAssignment(c, {1.0, kForbidden}), std::invalid_argument);
}

}  // namespace
}  // namespace magnav::tracker
