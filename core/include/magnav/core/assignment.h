// Optimal assignment (the linear sum assignment problem): given a cost matrix
// C (rows × columns, finite), pair rows with columns one to one so that the
// sum of the paired costs is least. With fewer rows than columns every row is
// paired; with fewer columns every column is. Hungarian method (Kuhn–Munkres
// with row/column potentials, shortest augmenting paths), O(n² m) for
// n = min(rows, cols), m = max(rows, cols).
//
// Used by the scoring of `magnav evaluate` (GOSPA, core/gospa.h); written to
// serve track–measurement association as well (issue 24 item 4).
#pragma once

#include <vector>

#include <Eigen/Core>

namespace magnav {

struct Assignment {
  // row_to_col[i]: the column paired with row i, or -1 (only when rows > cols).
  std::vector<int> row_to_col;
  // col_to_row[j]: the row paired with column j, or -1 (only when cols > rows).
  std::vector<int> col_to_row;
  double cost = 0.0;  // sum of the paired costs
};

// Least-cost assignment of `cost`'s rows to its columns. An empty matrix (no
// rows or no columns) gives an empty pairing of cost 0. Throws
// std::invalid_argument on a non-finite cost.
Assignment SolveAssignment(const Eigen::MatrixXd& cost);

}  // namespace magnav
