#include "magnav/localizer/batch.h"

#include <ceres/problem.h>
#include <ceres/solver.h>

#include <chrono>
#include <cmath>

#include "graph.h"
#include "magnav/core/ceres_loss.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/nees.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/ekf.h"
#include "magnav/localizer/input.h"
#include "magnav/localizer/models.h"

namespace magnav::localizer {

Localization SolveBatch(const Pass& pass, const LocalizerOptions& options, const Localization* start) {
  std::string why;
  if (!options.IsValid(&why)) throw InputError("localizer options: " + why);
  const auto t0 = std::chrono::steady_clock::now();
  Localization init;
  if (start == nullptr) {
    init = RunEkf(pass, options);
    start = &init;
  }
  const internal::Graph g = internal::BuildGraph(pass, options);
  // A step no trajectory of one pass makes (t = 1e300 s): the solver would
  // stop at once on the relative step of a 1e300 m state and call it converged.
  for (std::size_t k = 1; k < g.timeline.t.size(); ++k) {
    if (!(g.timeline.t[k] - g.timeline.t[k - 1] <= MaxAbs(kLimitTimeStep))) {
      throw InputError("SolveBatch: the pass jumps from t = " + FormatNumber(g.timeline.t[k - 1]) + " s to " +
                       FormatNumber(g.timeline.t[k]) + " s (more than " + FormatNumber(MaxAbs(kLimitTimeStep)) +
                       " s between epochs: a broken time)");
    }
  }
  const std::vector<VesselVector>* trajectory = &start->trajectory;
  std::vector<VesselVector> mapped;
  if (start->trajectory.size() != static_cast<std::size_t>(g.num_epochs) && !start->trajectory.empty() &&
      start->trajectory_t_s.size() == start->trajectory.size()) {
    // The start has fewer epochs (the EKF leaves out an epoch whose only
    // item it refused, e.g. a GNSS outlier): each epoch starts from the
    // start's last state at or before it, predicted to its time.
    std::size_t k = 0;
    for (double t : g.timeline.t) {
      while (k + 1 < start->trajectory_t_s.size() && start->trajectory_t_s[k + 1] <= t) ++k;
      mapped.push_back(PropagateVessel(start->trajectory[k], t - start->trajectory_t_s[k]));
    }
    trajectory = &mapped;
  }
  if (trajectory->size() != static_cast<std::size_t>(g.num_epochs) ||
      start->sensors.size() != static_cast<std::size_t>(g.num_sensors)) {
    throw InputError("SolveBatch: the start has " + std::to_string(start->trajectory.size()) + " states and " +
                     std::to_string(start->sensors.size()) + " sensors, the pass " + std::to_string(g.num_epochs) +
                     " epochs and " + std::to_string(g.num_sensors) + " sensors");
  }
  std::vector<Eigen::Vector2d> s0;
  for (const auto& e : start->sensors) s0.push_back(e.p_SinW_m.head<2>());
  std::vector<double> params = internal::Pack(g, *trajectory, s0);
  for (double v : params) {
    if (!std::isfinite(v)) throw InputError("SolveBatch: the start is not finite (the EKF run failed)");
  }

  const std::unique_ptr<ceres::LossFunction> loss =
      MakeCeresLoss(options.magnetometer_loss, options.magnetometer_loss_scale_sigma);
  const std::unique_ptr<ceres::LossFunction> gnss_loss = MakeCeresLoss(options.gnss_loss, options.gnss_loss_scale_sigma);
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (int b = 0; b < g.num_epochs + g.num_sensors; ++b) {
    problem.AddParameterBlock(&params[static_cast<std::size_t>(g.offset(b))], g.size(b));
  }
  for (const internal::Factor& f : g.factors) {
    std::vector<double*> blocks;
    for (int b : f.blocks) blocks.push_back(&params[static_cast<std::size_t>(g.offset(b))]);
    ceres::LossFunction* l = f.kind == internal::Factor::Kind::kMagnetometer ? loss.get()
                             : f.kind == internal::Factor::Kind::kGnss       ? gnss_loss.get()
                                                                             : nullptr;
    problem.AddResidualBlock(f.cost.get(), l, blocks);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = options.max_num_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
  ceres::Solver::Summary cs;
  ceres::Solve(so, &problem, &cs);

  Localization out;
  out.summary.method = "batch";
  out.summary.iterations = static_cast<int>(cs.iterations.size()) - 1;
  out.summary.initial_cost = cs.initial_cost;
  out.summary.final_cost = cs.final_cost;
  out.summary.converged = cs.termination_type == ceres::CONVERGENCE;
  out.summary.message = cs.message;
  out.summary.magnetometer_updates = static_cast<int>(pass.samples.size());
  out.summary.gnss_updates = static_cast<int>(pass.gnss.size());
  out.summary.gate_probability = options.gate_probability;
  out.summary.magnetometer_outliers = internal::CountBeyond(g, params, internal::Factor::Kind::kMagnetometer,
                                                            ChiSquareQuantile(options.gate_probability, 3));
  out.summary.gnss_outliers =
      internal::CountBeyond(g, params, internal::Factor::Kind::kGnss, ChiSquareQuantile(options.gate_probability, 2));
  MarkDivergence(&out.summary);
  out.trajectory_t_s = g.timeline.t;
  for (int k = 0; k < g.num_epochs; ++k) {
    out.trajectory.push_back(Eigen::Map<const VesselVector>(&params[static_cast<std::size_t>(5 * k)]));
  }
  for (int j = 0; j < g.num_sensors; ++j) {
    SensorEstimate e;
    const SensorPrior& p = pass.sensors[static_cast<std::size_t>(j)];
    e.sensor_id = p.sensor_id;
    const Eigen::Map<const Eigen::Vector2d> xy(&params[static_cast<std::size_t>(g.offset(g.num_epochs + j))]);
    e.p_SinW_m = {xy.x(), xy.y(), p.p_SinW_m.z()};
    out.sensors.push_back(e);
  }
  // Covariance: Gauss-Newton information at the solution with the loss's
  // reweighting, marginalised onto the sensors.
  Eigen::SparseMatrix<double> H;
  Eigen::MatrixXd cov;
  if (internal::Information(g, params, loss.get(), gnss_loss.get(), &H) && internal::SensorMarginalCovariance(g, H, &cov)) {
    out.cov_sensors_m2 = cov;
    for (int j = 0; j < g.num_sensors; ++j) out.sensors[static_cast<std::size_t>(j)].cov_xy_m2 = cov.block<2, 2>(2 * j, 2 * j);
  } else {
    out.summary.converged = false;
    out.summary.message += " (covariance: information not positive definite)";
  }
  const auto t1 = std::chrono::steady_clock::now();
  out.summary.solve_time_s = std::chrono::duration<double>(t1 - t0).count();
  out.crlb_joint_m2 = AttachCrlb(pass, options, out.trajectory, &out.sensors).joint_full;
  out.summary.crlb_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  return out;
}

}  // namespace magnav::localizer
