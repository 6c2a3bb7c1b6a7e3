// Global assignment for the multi-tracker's associator (issue 24 item 4):
// which of several competing tracks takes which piece of evidence, decided
// for all of them at once instead of track by track. Used by
// association.h's AssignEvidence (each cluster of tracks and single-sample
// fixes linked by their gates: rows the tracks' (track, sensor) slots,
// columns the fixes, cost χ² + ln det S), which MultiTracker calls every
// epoch and for every fix handed in.
//
// Problem: rows (tracks) and columns (evidence) with a cost per pair
// (kForbidden: the pair is never made, e.g. outside a gate). Each row takes
// at most one column and each column goes to at most one row; a row left
// without a column costs its `miss_cost` (a column left alone costs
// nothing). The assignment of least total cost is returned. Rectangular
// matrices (more rows or more columns) are fine.
//
// Solved by core's Hungarian method (magnav::SolveAssignment,
// core/assignment.h, which takes finite costs and pairs every row) on the
// (rows + columns)-square matrix that adds one "miss" column per row and one
// "unused" row per column, forbidden pairs priced above any feasible
// assignment. Costs are unitless (the caller's, e.g. χ²).
#pragma once

#include <limits>
#include <vector>

#include <Eigen/Core>

namespace magnav::tracker {

inline constexpr double kForbidden = std::numeric_limits<double>::infinity();

struct GatedAssignment {
  std::vector<int> column_of_row;  // per row: its column, or -1 (missed)
  double cost = 0.0;               // Σ assigned pair costs + Σ miss costs
};

// `cost`: rows × columns, finite or kForbidden (+inf; NaN counts as
// forbidden). `miss_cost`: one finite value per row (≥ 0 is usual; any
// finite value works). Throws std::invalid_argument on a size mismatch or a
// miss cost that is not finite.
GatedAssignment SolveGatedAssignment(const Eigen::MatrixXd& cost, const std::vector<double>& miss_cost);

}  // namespace magnav::tracker
