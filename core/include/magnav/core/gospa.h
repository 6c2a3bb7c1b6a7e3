// GOSPA, the generalized optimal sub-pattern assignment metric
// (Rahmathullah, García-Fernández, Svensson 2017, arXiv:1601.05585), with
// α = 2, as Stone Soup computes it (stonesoup/metricgenerator/ospametric.py):
// between a set of true positions X and a set of estimates Y at one instant,
//
//   GOSPA = ( min over assignments γ  Σ_{(i,j)∈γ} d(x_i, y_j)^p
//             + c^p/2 · (|X| − |γ|)  +  c^p/2 · (|Y| − |γ|) )^(1/p)
//
// where γ pairs truths with estimates one to one using only pairs closer than
// the cut-off c (d: Euclidean distance, m). The optimum is the least-cost
// assignment of the matrix min(d, c)^p (core/assignment.h): a pair at d ≥ c
// costs c^p, the same as leaving both unpaired, and is counted as one missed
// truth and one false estimate. Components (in m^p, before the 1/p power;
// GOSPA^p is their sum): localisation = Σ d^p over the pairs closer than c,
// missed = c^p/2 per truth left unpaired, false = c^p/2 per estimate left
// unpaired. Empty X and Y: GOSPA 0.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace magnav {

struct GospaOptions {
  double c_m = 10.0;  // cut-off distance, m (> 0)
  double p = 2.0;     // order (>= 1)
};

struct GospaResult {
  double gospa = 0.0;         // (localisation + missed + false)^(1/p), m
  double localisation = 0.0;  // m^p
  double missed = 0.0;        // m^p
  double false_ = 0.0;        // m^p
  int num_paired = 0, num_missed = 0, num_false = 0;
  // truth_to_estimate[i]: the estimate paired with truth i (closer than c), or -1.
  std::vector<int> truth_to_estimate;
};

// GOSPA between `truth` and `estimates` (positions, m). Throws
// std::invalid_argument on options out of range or a non-finite position.
GospaResult ComputeGospa(const std::vector<Eigen::Vector3d>& truth, const std::vector<Eigen::Vector3d>& estimates,
                         const GospaOptions& options = {});

}  // namespace magnav
