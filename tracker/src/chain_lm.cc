// Levenberg-Marquardt on the chain (Ceres' trust-region step rules), with the
// rotation-aware moment update.
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "factors.h"

namespace magnav::tracker::internal {

namespace {

// gᵀδ and δᵀHδ of the linearised problem for a step δ = (dx, dm).
void QuadraticModel(const ChainLinearization& lin, const std::vector<StateVector>& dx, const Eigen::Vector3d& dm,
                    double* g_dot, double* curvature) {
  *g_dot = 0.0;
  *curvature = 0.0;
  const std::size_t n = lin.H.size();
  LocalG d;
  for (std::size_t k = 0; k < n; ++k) {
    d << dx[k], (k + 1 < n ? dx[k + 1] : StateVector::Zero()), dm;
    *g_dot += lin.g[k].dot(d);
    *curvature += d.dot(lin.H[k].lazyProduct(d));
  }
}

// max |g_i| of the full gradient, assembled from the groups' local gradients.
double GradientMaxNorm(const ChainLinearization& lin) {
  const std::size_t n = lin.g.size();
  double worst = 0.0;
  Eigen::Vector3d g_m = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    StateVector gk = lin.g[k].head<6>();
    if (k > 0) gk += lin.g[k - 1].segment<6>(6);
    worst = std::max(worst, gk.cwiseAbs().maxCoeff());
    g_m += lin.g[k].tail<3>();
  }
  return std::max(worst, g_m.cwiseAbs().maxCoeff());
}

}  // namespace

Eigen::Vector3d RetractMoment(const Eigen::Vector3d& m, const Eigen::Vector3d& dm) {
  const double rho = m.head<2>().norm();
  if (!(rho > 1e-9 * m.norm())) return m + dm;  // no horizontal part: plain addition
  const Eigen::Vector2d radial = m.head<2>() / rho;
  const Eigen::Vector2d tangential(-radial.y(), radial.x());
  const double d_radial = radial.dot(dm.head<2>());
  const double angle = tangential.dot(dm.head<2>()) / rho;
  const Eigen::Vector2d h = (rho + d_radial) * Eigen::Rotation2Dd(angle).toRotationMatrix() * radial;
  return {h.x(), h.y(), m.z() + dm.z()};
}

void SolveChainLevenbergMarquardt(const ChainSolverOptions& options, const ChainProblem& chain,
                                  ceres::Solver::Summary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  *summary = ceres::Solver::Summary();
  summary->minimizer_type = ceres::TRUST_REGION;
  summary->trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  const std::size_t n = chain.states.size();
  const auto finish = [&](ceres::TerminationType type, std::string message) {
    summary->termination_type = type;
    summary->message = std::move(message);
    summary->total_time_in_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  double cost = TotalCost(chain.groups, options.num_threads);
  summary->initial_cost = cost;
  summary->final_cost = cost;
  ceres::IterationSummary it0;
  it0.cost = cost;
  summary->iterations.push_back(it0);
  ChainLinearization lin;
  if (!std::isfinite(cost) || !LinearizeChain(chain, &lin, options.num_threads)) {
    finish(ceres::FAILURE, "chain Levenberg-Marquardt: the initial point could not be evaluated");
    return;
  }
  ChainFactorization f;
  std::vector<StateVector> dx, x0(n);
  Eigen::Vector3d dm;
  double radius = options.initial_trust_region_radius;
  double decrease_factor = 2.0;
  for (int iteration = 1;; ++iteration) {
    ceres::IterationSummary it;
    it.iteration = iteration;
    it.gradient_max_norm = GradientMaxNorm(lin);
    it.trust_region_radius = radius;
    if (it.gradient_max_norm <= options.gradient_tolerance) {
      finish(ceres::CONVERGENCE, "Gradient tolerance reached.");
      return;
    }
    if (iteration > options.max_num_iterations) {
      finish(ceres::NO_CONVERGENCE, "Maximum number of iterations reached.");
      return;
    }
    bool ok = EliminateChain(lin, 1.0 / radius, &f);
    double model_change = 0.0;
    if (ok) {
      ChainStep(f, &dx, &dm);
      double g_dot = 0.0, curvature = 0.0;
      QuadraticModel(lin, dx, dm, &g_dot, &curvature);
      model_change = -(g_dot + 0.5 * curvature);
      double step_sq = dm.squaredNorm();
      double x_sq = Eigen::Map<const Eigen::Vector3d>(chain.moment).squaredNorm();
      for (std::size_t k = 0; k < n; ++k) {
        step_sq += dx[k].squaredNorm();
        x_sq += Eigen::Map<const StateVector>(chain.states[k]).squaredNorm();
      }
      it.step_norm = std::sqrt(step_sq);
      if (it.step_norm <= options.parameter_tolerance * (std::sqrt(x_sq) + options.parameter_tolerance)) {
        finish(ceres::CONVERGENCE, "Parameter tolerance reached.");
        return;
      }
      ok = std::isfinite(model_change) && model_change > 0.0;
    }
    bool accepted = false;
    bool converged = false;
    if (ok) {
      const Eigen::Vector3d m0 = Eigen::Map<const Eigen::Vector3d>(chain.moment);
      for (std::size_t k = 0; k < n; ++k) {
        Eigen::Map<StateVector> x(chain.states[k]);
        x0[k] = x;
        x += dx[k];
      }
      Eigen::Map<Eigen::Vector3d>(chain.moment) = RetractMoment(m0, dm);
      const double new_cost = TotalCost(chain.groups, options.num_threads);
      it.cost_change = cost - new_cost;
      it.relative_decrease = it.cost_change / model_change;
      accepted = std::isfinite(new_cost) && it.relative_decrease > options.min_relative_decrease;
      converged = std::isfinite(new_cost) && std::abs(it.cost_change) <= options.function_tolerance * cost;
      bool relinearize = false;
      if (accepted) {
        // The new point counts only once it can be linearised.
        if (LinearizeChain(chain, &lin, options.num_threads)) {
          cost = new_cost;
        } else {
          accepted = converged = false;
          relinearize = true;  // lin holds a partial linearisation: redo it at x0
        }
      }
      if (!accepted) {
        for (std::size_t k = 0; k < n; ++k) Eigen::Map<StateVector>(chain.states[k]) = x0[k];
        Eigen::Map<Eigen::Vector3d>(chain.moment) = m0;
        if (relinearize && !LinearizeChain(chain, &lin, options.num_threads)) {
          finish(ceres::FAILURE, "chain Levenberg-Marquardt: the current point could no longer be linearised");
          return;
        }
      }
    }
    it.cost = cost;
    it.step_is_successful = accepted;
    summary->iterations.push_back(it);
    summary->final_cost = cost;
    if (converged) {
      finish(ceres::CONVERGENCE, "Function tolerance reached.");
      return;
    }
    if (accepted) {
      const double r = 2.0 * it.relative_decrease - 1.0;
      radius = std::min(options.max_trust_region_radius, radius / std::max(1.0 / 3.0, 1.0 - r * r * r));
      decrease_factor = 2.0;
    } else {
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      if (radius < options.min_trust_region_radius) {
        finish(ceres::CONVERGENCE, "Minimum trust region radius reached.");
        return;
      }
    }
  }
}

}  // namespace magnav::tracker::internal
