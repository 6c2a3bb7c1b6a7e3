#include "magnav/core/gospa.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "magnav/core/assignment.h"

namespace magnav {

GospaResult ComputeGospa(const std::vector<Eigen::Vector3d>& truth, const std::vector<Eigen::Vector3d>& estimates,
                         const GospaOptions& options) {
  if (!(options.c_m > 0.0) || !std::isfinite(options.c_m) || !(options.p >= 1.0) || !std::isfinite(options.p)) {
    throw std::invalid_argument("ComputeGospa: needs c > 0 and p >= 1");
  }
  const double cp = std::pow(options.c_m, options.p);
  const int n = static_cast<int>(truth.size()), m = static_cast<int>(estimates.size());
  Eigen::MatrixXd cost(n, m);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      const double d = (truth[i] - estimates[j]).norm();
      if (!std::isfinite(d)) throw std::invalid_argument("ComputeGospa: a position is not finite");
      cost(i, j) = std::pow(std::min(d, options.c_m), options.p);
    }
  }
  const Assignment a = SolveAssignment(cost);
  GospaResult r;
  r.truth_to_estimate.assign(truth.size(), -1);
  for (int i = 0; i < n; ++i) {
    const int j = a.row_to_col[static_cast<std::size_t>(i)];
    if (j < 0) continue;
    if ((truth[i] - estimates[j]).norm() < options.c_m) {
      r.truth_to_estimate[static_cast<std::size_t>(i)] = j;
      r.localisation += cost(i, j);
      ++r.num_paired;
    }
  }
  r.num_missed = n - r.num_paired;
  r.num_false = m - r.num_paired;
  r.missed = 0.5 * cp * r.num_missed;
  r.false_ = 0.5 * cp * r.num_false;
  r.gospa = std::pow(r.localisation + r.missed + r.false_, 1.0 / options.p);
  return r;
}

}  // namespace magnav
