#include "magnav/tracker/assignment.h"

#include <cmath>
#include <stdexcept>

#include "magnav/core/assignment.h"

namespace magnav::tracker {

GatedAssignment SolveGatedAssignment(const Eigen::MatrixXd& cost, const std::vector<double>& miss_cost) {
  const int nr = static_cast<int>(cost.rows()), nc = static_cast<int>(cost.cols());
  if (static_cast<int>(miss_cost.size()) != nr) throw std::invalid_argument("SolveGatedAssignment: one miss cost per row");
  for (double m : miss_cost) {
    if (!std::isfinite(m)) throw std::invalid_argument("SolveGatedAssignment: a miss cost is not finite");
  }
  GatedAssignment out;
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
  const std::vector<int> col = magnav::SolveAssignment(a).row_to_col;
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
