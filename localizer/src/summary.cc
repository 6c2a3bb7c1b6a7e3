#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Cholesky>

#include "magnav/core/nees.h"
#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer {

std::string Summary::BriefReport() const {
  char releases[64] = "";
  if (gate_releases > 0) std::snprintf(releases, sizeof releases, ", %d applied beyond it after a run of refusals", gate_releases);
  char smoother[96] = "";
  if (!std::isnan(smoother_nees)) {
    std::snprintf(smoother, sizeof smoother, ", against the batch: NEES %.3g (sensor %lld)", smoother_nees,
                  static_cast<long long>(smoother_nees_sensor));
  }
  char buf[896];
  std::snprintf(buf, sizeof buf,
                "method %s, %s, iterations %d, cost %.6g -> %.6g, magnetometer samples %d, gnss fixes %d, "
                "outliers: magnetometer %d, gnss %d (gate p %.6g%s)%s, time %.3g s (+ bound %.3g s): %s",
                method.c_str(), Status().c_str(), iterations, initial_cost, final_cost,
                magnetometer_updates, gnss_updates, magnetometer_outliers, gnss_outliers, gate_probability, releases,
                smoother, solve_time_s, crlb_time_s, message.c_str());
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

void CheckAgainstSmoother(const Localization& smoother, double gate_probability, Localization* filter) {
  if (smoother.summary.Status() != "converged" || smoother.sensors.size() != filter->sensors.size()) return;
  double worst = 0.0;
  std::int64_t worst_id = -1;
  for (std::size_t j = 0; j < filter->sensors.size(); ++j) {
    const SensorEstimate& f = filter->sensors[j];
    const SensorEstimate& s = smoother.sensors[j];
    if (f.sensor_id != s.sensor_id) return;
    const Eigen::Vector2d d = f.p_SinW_m.head<2>() - s.p_SinW_m.head<2>();
    const Eigen::LLT<Eigen::Matrix2d> llt(f.cov_xy_m2);
    double q = llt.info() == Eigen::Success ? d.dot(llt.solve(d)) : std::numeric_limits<double>::infinity();
    if (std::isnan(q)) q = std::numeric_limits<double>::infinity();
    if (!(q <= worst)) {
      worst = q;
      worst_id = f.sensor_id;
    }
  }
  filter->summary.smoother_nees = worst;
  filter->summary.smoother_nees_sensor = worst_id;
  if (worst > ChiSquareQuantile(gate_probability, 2)) {
    filter->summary.diverged = true;
    filter->summary.converged = false;
  }
}

}  // namespace magnav::localizer
