#include <cstdio>

#include "magnav/localizer/types.h"

namespace magnav::localizer {

std::string Summary::BriefReport() const {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "method %s, %s, iterations %d, cost %.6g -> %.6g, magnetometer samples %d, gnss fixes %d, "
                "time %.3g s (+ bound %.3g s): %s",
                method.c_str(), converged ? "converged" : "NOT converged", iterations, initial_cost, final_cost,
                magnetometer_updates, gnss_updates, solve_time_s, crlb_time_s, message.c_str());
  return buf;
}

}  // namespace magnav::localizer
