#include "magnav/localizer/batch.h"

#include <ceres/problem.h>
#include <ceres/solver.h>

#include <chrono>

#include "graph.h"
#include "magnav/core/ceres_loss.h"
#include "magnav/core/error.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/ekf.h"

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
  if (start->trajectory.size() != static_cast<std::size_t>(g.num_epochs) ||
      start->sensors.size() != static_cast<std::size_t>(g.num_sensors)) {
    throw InputError("SolveBatch: the start has " + std::to_string(start->trajectory.size()) + " states and " +
                     std::to_string(start->sensors.size()) + " sensors, the pass " + std::to_string(g.num_epochs) +
                     " epochs and " + std::to_string(g.num_sensors) + " sensors");
  }
  std::vector<Eigen::Vector2d> s0;
  for (const auto& e : start->sensors) s0.push_back(e.p_SinW_m.head<2>());
  std::vector<double> params = internal::Pack(g, start->trajectory, s0);

  const std::unique_ptr<ceres::LossFunction> loss =
      MakeCeresLoss(options.magnetometer_loss, options.magnetometer_loss_scale_sigma);
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
    ceres::LossFunction* l = f.kind == internal::Factor::Kind::kMagnetometer ? loss.get() : nullptr;
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
  if (internal::Information(g, params, loss.get(), &H) && internal::SensorMarginalCovariance(g, H, &cov)) {
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
