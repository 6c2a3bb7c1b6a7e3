// The optimal assignment (core/assignment.h) against brute force over every
// pairing of random small matrices, square and rectangular, with ties; and
// GOSPA (core/gospa.h) on cases worked out by hand and against its definition
// enumerated over every partial pairing.
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

#include "magnav/core/assignment.h"
#include "magnav/core/gospa.h"

namespace magnav {
namespace {

// Least cost over every pairing of min(rows, cols) rows with distinct columns.
double BruteForceCost(const Eigen::MatrixXd& c) {
  const bool t = c.rows() > c.cols();
  const Eigen::MatrixXd a = t ? Eigen::MatrixXd(c.transpose()) : c;  // rows <= cols
  std::vector<int> cols(static_cast<std::size_t>(a.cols()));
  for (std::size_t j = 0; j < cols.size(); ++j) cols[j] = static_cast<int>(j);
  double best = std::numeric_limits<double>::infinity();
  // Every ordered choice of a.rows() distinct columns: permutations of all
  // columns, the first a.rows() of each.
  do {
    double s = 0.0;
    for (int i = 0; i < a.rows(); ++i) s += a(i, cols[static_cast<std::size_t>(i)]);
    best = std::min(best, s);
  } while (std::next_permutation(cols.begin(), cols.end()));
  return a.rows() == 0 ? 0.0 : best;
}

void ExpectValidPairing(const Eigen::MatrixXd& c, const Assignment& a) {
  ASSERT_EQ(a.row_to_col.size(), static_cast<std::size_t>(c.rows()));
  ASSERT_EQ(a.col_to_row.size(), static_cast<std::size_t>(c.cols()));
  int paired = 0;
  double sum = 0.0;
  for (int i = 0; i < c.rows(); ++i) {
    const int j = a.row_to_col[static_cast<std::size_t>(i)];
    if (j < 0) continue;
    ++paired;
    ASSERT_LT(j, c.cols());
    EXPECT_EQ(a.col_to_row[static_cast<std::size_t>(j)], i);
    sum += c(i, j);
  }
  EXPECT_EQ(paired, std::min(c.rows(), c.cols()));
  EXPECT_NEAR(sum, a.cost, 1e-9 * (1.0 + std::abs(sum)));
}

TEST(SolveAssignment, EqualsBruteForceOnRandomSmallMatrices) {
  std::mt19937 rng(24);
  std::uniform_int_distribution<int> size(0, 6), small_int(0, 4);
  std::uniform_real_distribution<double> real(-50.0, 100.0);
  int compared = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const int rows = size(rng), cols = size(rng);
    Eigen::MatrixXd c(rows, cols);
    const bool ties = trial % 3 == 0;  // integer costs 0..4: many equal optima
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j < cols; ++j) c(i, j) = ties ? small_int(rng) : real(rng);
    }
    const Assignment a = SolveAssignment(c);
    ExpectValidPairing(c, a);
    ASSERT_NEAR(a.cost, BruteForceCost(c), 1e-9 * (1.0 + std::abs(a.cost))) << "trial " << trial << "\n" << c;
    ++compared;
  }
  EXPECT_EQ(compared, 3000);
}

TEST(SolveAssignment, GreedyIsNotOptimalHere) {
  // Row 0 takes column 0 greedily (1), leaving row 1 with 100: 101. Optimal: 2 + 3.
  Eigen::MatrixXd c(2, 2);
  c << 1, 2, 3, 100;
  const Assignment a = SolveAssignment(c);
  EXPECT_EQ(a.row_to_col, (std::vector<int>{1, 0}));
  EXPECT_DOUBLE_EQ(a.cost, 5.0);
}

TEST(SolveAssignment, EmptyAndNonFinite) {
  EXPECT_EQ(SolveAssignment(Eigen::MatrixXd(0, 3)).col_to_row, (std::vector<int>{-1, -1, -1}));
  EXPECT_EQ(SolveAssignment(Eigen::MatrixXd(2, 0)).row_to_col, (std::vector<int>{-1, -1}));
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(2, 2);
  c(1, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(SolveAssignment(c), std::invalid_argument);
}

// Worked by hand (c = 10 m, p = 2: a missed or false object costs c²/2 = 50 m²).
TEST(Gospa, HandWorkedCases) {
  using V = Eigen::Vector3d;
  // Truth 0 paired with the estimate 5 m away (25 m²); truth 1's nearest
  // estimate is 12 m away (beyond c): missed, as is truth 2; two false
  // estimates. 25 + 2·50 + 2·50 = 225 m² → GOSPA 15 m.
  GospaResult r = ComputeGospa({V(0, 0, 0), V(20, 0, 0), V(50, 0, 0)}, {V(3, 4, 0), V(20, 0, 12), V(100, 0, 0)});
  EXPECT_DOUBLE_EQ(r.gospa, 15.0);
  EXPECT_DOUBLE_EQ(r.localisation, 25.0);
  EXPECT_DOUBLE_EQ(r.missed, 100.0);
  EXPECT_DOUBLE_EQ(r.false_, 100.0);
  EXPECT_EQ(r.num_paired, 1);
  EXPECT_EQ(r.num_missed, 2);
  EXPECT_EQ(r.num_false, 2);
  EXPECT_EQ(r.truth_to_estimate, (std::vector<int>{0, -1, -1}));

  // Nearest-first would pair truth (0,0,0) with (3,0,0) (9 m²) and leave
  // truth (6,0,0) with (-4,0,0) 10 m away (capped: 100 m²), 109 m². The
  // optimum crosses over: 4² + 3² = 25 m² → GOSPA 5 m, nothing missed or false.
  r = ComputeGospa({V(0, 0, 0), V(6, 0, 0)}, {V(3, 0, 0), V(-4, 0, 0)});
  EXPECT_DOUBLE_EQ(r.gospa, 5.0);
  EXPECT_EQ(r.truth_to_estimate, (std::vector<int>{1, 0}));
  EXPECT_EQ(r.num_missed + r.num_false, 0);

  // Two vessels, no estimate: 2 · 50 = 100 m² → 10 m. One estimate, no vessel: √50.
  r = ComputeGospa({V(0, 0, 0), V(1, 1, 1)}, {});
  EXPECT_DOUBLE_EQ(r.gospa, 10.0);
  EXPECT_DOUBLE_EQ(r.missed, 100.0);
  r = ComputeGospa({}, {V(0, 0, 0)});
  EXPECT_DOUBLE_EQ(r.gospa, std::sqrt(50.0));
  EXPECT_DOUBLE_EQ(r.false_, 50.0);
  EXPECT_EQ(ComputeGospa({}, {}).gospa, 0.0);

  // p = 1, c = 4: one pair 3 m apart, one false estimate (c/2 = 2): 5 m.
  r = ComputeGospa({V(0, 0, 0)}, {V(0, 3, 0), V(40, 0, 0)}, GospaOptions{4.0, 1.0});
  EXPECT_DOUBLE_EQ(r.gospa, 5.0);
  EXPECT_THROW(ComputeGospa({}, {}, GospaOptions{0.0, 2.0}), std::invalid_argument);
}

// GOSPA from its definition: the least, over every partial one-to-one
// pairing, of Σ min(d, c)^p over the pairs plus c^p/2 per unpaired object.
double GospaByEnumeration(const std::vector<Eigen::Vector3d>& x, const std::vector<Eigen::Vector3d>& y, double c,
                          double p) {
  double best = std::numeric_limits<double>::infinity();
  std::vector<char> taken(y.size(), 0);
  std::function<void(std::size_t, double, int)> rec = [&](std::size_t i, double sum, int paired) {
    if (i == x.size()) {
      const double unpaired = static_cast<double>(x.size() + y.size()) - 2.0 * paired;
      best = std::min(best, sum + 0.5 * std::pow(c, p) * unpaired);
      return;
    }
    rec(i + 1, sum, paired);  // x_i unpaired
    for (std::size_t j = 0; j < y.size(); ++j) {
      if (taken[j]) continue;
      taken[j] = 1;
      rec(i + 1, sum + std::pow(std::min((x[i] - y[j]).norm(), c), p), paired + 1);
      taken[j] = 0;
    }
  };
  rec(0, 0.0, 0);
  return std::pow(best, 1.0 / p);
}

TEST(Gospa, EqualsItsDefinitionOnRandomSets) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> count(0, 5);
  std::uniform_real_distribution<double> coord(-15.0, 15.0);
  for (int trial = 0; trial < 1000; ++trial) {
    std::vector<Eigen::Vector3d> x(static_cast<std::size_t>(count(rng))), y(static_cast<std::size_t>(count(rng)));
    for (auto& v : x) v = {coord(rng), coord(rng), coord(rng)};
    for (auto& v : y) v = {coord(rng), coord(rng), coord(rng)};
    const GospaOptions o{trial % 2 == 0 ? 10.0 : 5.0, trial % 4 < 2 ? 2.0 : 1.0};
    const GospaResult r = ComputeGospa(x, y, o);
    ASSERT_NEAR(r.gospa, GospaByEnumeration(x, y, o.c_m, o.p), 1e-9) << "trial " << trial;
    EXPECT_NEAR(std::pow(r.gospa, o.p), r.localisation + r.missed + r.false_, 1e-9);
    EXPECT_EQ(r.num_paired + r.num_missed, static_cast<int>(x.size()));
    EXPECT_EQ(r.num_paired + r.num_false, static_cast<int>(y.size()));
  }
}

}  // namespace
}  // namespace magnav
