#include "magnav/tracker/assignment.h"

#include <cmath>
#include <stdexcept>

namespace magnav::tracker {

namespace {

// Minimum-cost perfect matching of a square matrix (Hungarian method with
// row and column potentials, 1-based internally). Returns the column of
// each row.
std::vector<int> Hungarian(const Eigen::MatrixXd& a) {
  const int n = static_cast<int>(a.rows());
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> u(n + 1, 0.0), v(n + 1, 0.0);
  std::vector<int> p(n + 1, 0), way(n + 1, 0);
  for (int i = 1; i <= n; ++i) {
    p[0] = i;
    int j0 = 0;
    std::vector<double> minv(n + 1, inf);
    std::vector<bool> used(n + 1, false);
    do {
      used[j0] = true;
      const int i0 = p[j0];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= n; ++j) {
        if (used[j]) continue;
        const double cur = a(i0 - 1, j - 1) - u[i0] - v[j];
        if (cur < minv[j]) {
          minv[j] = cur;
          way[j] = j0;
        }
        if (minv[j] < delta) {
          delta = minv[j];
          j1 = j;
        }
      }
      for (int j = 0; j <= n; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {
      const int j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  std::vector<int> col(n, -1);
  for (int j = 1; j <= n; ++j) col[p[j] - 1] = j - 1;
  return col;
}

}  // namespace

Assignment SolveAssignment(const Eigen::MatrixXd& cost, const std::vector<double>& miss_cost) {
  const int nr = static_cast<int>(cost.rows()), nc = static_cast<int>(cost.cols());
  if (static_cast<int>(miss_cost.size()) != nr) throw std::invalid_argument("SolveAssignment: one miss cost per row");
  for (double m : miss_cost) {
    if (!std::isfinite(m)) throw std::invalid_argument("SolveAssignment: a miss cost is not finite");
  }
  Assignment out;
  out.column_of_row.assign(nr, -1);
  if (nr == 0) return out;
  // A cost above any finite assignment's: every row has a finite miss, so
  // the optimum never takes a pair that costs this much.
  double big = 1.0;
  for (int i = 0; i < nr; ++i) {
    big += std::abs(miss_cost[i]);
    for (int j = 0; j < nc; ++j) {
      if (std::isfinite(cost(i, j))) big += std::abs(cost(i, j));
    }
  }
  big *= 2.0;
  // [ cost        | miss (diagonal) ]
  // [ 0 (unused)  | 0               ]
  const int n = nr + nc;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < nr; ++i) {
    for (int j = 0; j < nc; ++j) a(i, j) = std::isfinite(cost(i, j)) ? cost(i, j) : big;
    for (int k = 0; k < nr; ++k) a(i, nc + k) = k == i ? miss_cost[i] : big;
  }
  const std::vector<int> col = Hungarian(a);
  for (int i = 0; i < nr; ++i) {
    const int j = col[i];
    if (j < nc && std::isfinite(cost(i, j))) {
      out.column_of_row[i] = j;
      out.cost += cost(i, j);
    } else {
      out.cost += miss_cost[i];
    }
  }
  return out;
}

}  // namespace magnav::tracker
