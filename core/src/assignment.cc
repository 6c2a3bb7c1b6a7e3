#include "magnav/core/assignment.h"

#include <limits>
#include <stdexcept>

namespace magnav {

Assignment SolveAssignment(const Eigen::MatrixXd& cost) {
  if (!cost.allFinite()) throw std::invalid_argument("SolveAssignment: the cost matrix has a non-finite entry");
  Assignment out;
  out.row_to_col.assign(static_cast<std::size_t>(cost.rows()), -1);
  out.col_to_row.assign(static_cast<std::size_t>(cost.cols()), -1);
  if (cost.rows() == 0 || cost.cols() == 0) return out;
  // The method below pairs every row of an n × m matrix with n ≤ m: work on
  // the transpose when there are more rows than columns.
  const bool transposed = cost.rows() > cost.cols();
  const Eigen::MatrixXd a = transposed ? Eigen::MatrixXd(cost.transpose()) : cost;
  const int n = static_cast<int>(a.rows()), m = static_cast<int>(a.cols());
  const double inf = std::numeric_limits<double>::infinity();
  // 1-based: index 0 is a virtual column through which each new row enters.
  std::vector<double> u(n + 1, 0.0), v(m + 1, 0.0);  // row and column potentials
  std::vector<int> p(m + 1, 0);                       // p[j]: row paired with column j (0: none)
  std::vector<int> way(m + 1, 0);                     // previous column on the shortest path
  for (int i = 1; i <= n; ++i) {
    p[0] = i;
    int j0 = 0;
    std::vector<double> minv(m + 1, inf);
    std::vector<char> used(m + 1, 0);
    do {
      used[j0] = 1;
      const int i0 = p[j0];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= m; ++j) {
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
      for (int j = 0; j <= m; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {  // augment along the path
      const int j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  for (int j = 1; j <= m; ++j) {
    if (p[j] == 0) continue;
    const int row = transposed ? j - 1 : p[j] - 1, col = transposed ? p[j] - 1 : j - 1;
    out.row_to_col[static_cast<std::size_t>(row)] = col;
    out.col_to_row[static_cast<std::size_t>(col)] = row;
    out.cost += cost(row, col);
  }
  return out;
}

}  // namespace magnav
