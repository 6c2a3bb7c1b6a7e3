#include <algorithm>
#include <cstdio>

#include "magnav/localizer/types.h"

namespace magnav::localizer {

std::string Summary::BriefReport() const {
  char releases[64] = "";
  if (gate_releases > 0) std::snprintf(releases, sizeof releases, ", %d applied beyond it after a run of refusals", gate_releases);
  char buf[768];
  std::snprintf(buf, sizeof buf,
                "method %s, %s, iterations %d, cost %.6g -> %.6g, magnetometer samples %d, gnss fixes %d, "
                "outliers: magnetometer %d, gnss %d (gate p %.6g%s), time %.3g s (+ bound %.3g s): %s",
                method.c_str(), Status().c_str(), iterations, initial_cost, final_cost,
                magnetometer_updates, gnss_updates, magnetometer_outliers, gnss_outliers, gate_probability, releases,
                solve_time_s, crlb_time_s, message.c_str());
  return buf;
}

std::string Summary::Status() const { return diverged ? "diverged" : converged ? "converged" : "NOT converged"; }

void MarkDivergence(Summary* s) {
  const auto beyond = [](double count, double items, double share) { return count > std::max(10.0, share * items); };
  bool lost = false;
  if (s->method == "batch") {
    lost = beyond(s->magnetometer_outliers, s->magnetometer_updates, 0.01) ||
           beyond(s->gnss_outliers, s->gnss_updates, 0.01);
  } else {
    // EKF: *_updates count the applied updates (releases included), the
    // outliers the refused ones.
    const double refused = s->magnetometer_outliers + s->gnss_outliers;
    lost = beyond(refused + s->gate_releases, s->magnetometer_updates + s->gnss_updates + refused, 0.02);
  }
  if (lost) {
    s->diverged = true;
    s->converged = false;
  }
}

}  // namespace magnav::localizer
