// Robust-loss continuation: the passes of one solve, from a wide loss scale
// down to the nominal one.
#include <algorithm>
#include <limits>

#include "factors.h"

namespace magnav::tracker::internal {

double NextLossScale(const std::vector<Factor*>& measurements, double nominal, double previous) {
  std::vector<double> norms;
  norms.reserve(measurements.size());
  for (const Factor* f : measurements) {
    Eigen::VectorXd e(f->cost->num_residuals());
    std::vector<const double*> params(f->blocks.begin(), f->blocks.end());
    if (f->cost->Evaluate(params.data(), e.data(), nullptr)) norms.push_back(e.norm());
  }
  if (norms.empty()) return nominal;
  const std::size_t mid = norms.size() / 2;
  std::nth_element(norms.begin(), norms.begin() + static_cast<std::ptrdiff_t>(mid), norms.end());
  return std::max(nominal, std::min(previous / 10.0, 3.0 * norms[mid]));
}

PassResult SolveWithContinuation(const TrackerOptions& options, int max_iterations_per_pass,
                                 bool intermediate, const std::vector<Factor*>& measurements,
                                 bool warm_up_turn_rate, const std::function<ChainProblem(bool warm_turn)>& build) {
  ceres::Solver::Options so = SparseSolverOptions(options, max_iterations_per_pass, options.function_tolerance);
  ChainSolverOptions co;
  co.max_num_iterations = max_iterations_per_pass;
  co.gradient_tolerance = options.gradient_tolerance;
  co.parameter_tolerance = options.parameter_tolerance;
  co.num_threads = options.num_threads;
  PassResult out;
  const double nominal = options.measurement_loss_scale_sigma;
  const bool robust = options.measurement_loss != LossType::kTrivial;
  double scale =
      robust ? NextLossScale(measurements, nominal, std::numeric_limits<double>::infinity()) : nominal;
  bool warm = warm_up_turn_rate;
  for (int pass = 0; pass < 12; ++pass) {
    const bool final_pass = !warm && scale <= nominal;
    // Passes whose result is only a starting point stop early.
    so.function_tolerance = (intermediate || !final_pass) ? std::max(options.function_tolerance,
                                                                     options.intermediate_function_tolerance)
                                                          : options.function_tolerance;
    co.function_tolerance = so.function_tolerance;
    out.final_loss = MakeCeresLoss(options.measurement_loss, scale);
    for (Factor* f : measurements) f->loss = out.final_loss.get();
    const ChainProblem chain = build(warm);
    if (options.batch_solver == TrackerOptions::BatchSolver::kChainLevenbergMarquardt) {
      SolveChainLevenbergMarquardt(co, chain, &out.last);
    } else {
      ceres::Problem problem(NonOwningProblemOptions());
      AddToProblem(chain, &problem);
      ceres::Solve(so, &problem, &out.last);
    }
    if (pass == 0) out.first_initial_cost = out.last.initial_cost;
    out.iterations += static_cast<int>(out.last.iterations.size()) - 1;
    out.solve_time_s += out.last.total_time_in_seconds;
    if (final_pass) {
      out.reached_final_pass = true;
      break;
    }
    warm = false;
    if (robust) scale = NextLossScale(measurements, nominal, scale);
  }
  return out;
}

}  // namespace magnav::tracker::internal
