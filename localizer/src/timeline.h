// Internal: the epochs of a pass (samples and fixes grouped by time), shared
// by the EKF run, the batch smoother and the bounds so that all three put the
// trajectory at the same instants.
#pragma once

#include <vector>

#include "magnav/localizer/types.h"

namespace magnav::localizer::internal {

struct Timeline {
  std::vector<double> t;                    // epoch times, increasing (s)
  std::vector<std::vector<int>> samples_at;  // per epoch: indices into Pass::samples, file order
  std::vector<std::vector<int>> gnss_at;     // per epoch: indices into Pass::gnss
};

// An epoch starts at the earliest remaining time and takes everything within
// tolerance_s of it. Samples and fixes must each be in time order.
Timeline BuildTimeline(const Pass& pass, double tolerance_s);

}  // namespace magnav::localizer::internal
