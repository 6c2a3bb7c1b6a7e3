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
                method.c_str(), converged ? "converged" : "NOT converged", iterations, initial_cost, final_cost,
                magnetometer_updates, gnss_updates, magnetometer_outliers, gnss_outliers, gate_probability, releases,
                solve_time_s, crlb_time_s, message.c_str());
  return buf;
}

}  // namespace magnav::localizer
