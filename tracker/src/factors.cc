// The tracker's factors and their assembly: measurement and
// process factors of an epoch, and a chain problem as a ceres::Problem.
#include "factors.h"

#include "magnav/tracker/cost_functions.h"
#include "magnav/tracker/initialize.h"

namespace magnav::tracker::internal {

double DepthWalk(const Epoch& from, const TrackerOptions& options) {
  const ProcessNoise& q = options.process;
  if (!(q.depth_weak_m_per_sqrt_s > 0.0)) return q.depth_m_per_sqrt_s;
  for (const auto& s : from.samples) {
    if (s.T.norm() >= q.depth_weak_tensor_snr * SigmaT(s, options)) return q.depth_m_per_sqrt_s;
  }
  return q.depth_weak_m_per_sqrt_s;
}

ceres::Problem::Options NonOwningProblemOptions() {
  ceres::Problem::Options o;
  o.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return o;
}

ceres::Solver::Options SparseSolverOptions(const TrackerOptions& options, int max_iterations,
                                           double function_tolerance) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = max_iterations;
  so.function_tolerance = function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
  return so;
}

void AddToProblem(const Factor& f, ceres::Problem* problem) {
  problem->AddResidualBlock(f.cost.get(), const_cast<ceres::LossFunction*>(f.loss), f.blocks);
}

void AddMeasurementFactors(const Epoch& epoch, const Eigen::Vector3d& B0_W, const TrackerOptions& options,
                           double moment_scale, double* state, double* moment, std::vector<Factor>* out) {
  for (const GradiometerSample& s : epoch.samples) {
    const SqrtInfo8 L =
        MeasurementSqrtInfo(SigmaB(s, options), SigmaT(s, options), options.tensor_noise_trace_free);
    Factor f;
    f.cost = std::make_unique<MeasurementCost>(s, B0_W, L, moment_scale);
    f.blocks = {state, moment};
    out->push_back(std::move(f));
  }
}

void AddProcessFactors(double dt_s, const ProcessNoise& q, const ceres::LossFunction* turn_loss, double* s0,
                       double* s1, std::vector<Factor>* out) {
  Factor kin;
  kin.kind = Factor::Kind::kKinematic;
  kin.cost = std::make_unique<KinematicCost>(dt_s, q.position_m_per_sqrt_s, q.speed_mps_per_sqrt_s,
                                             q.heading_rad_per_sqrt_s, q.depth_m_per_sqrt_s);
  kin.blocks = {s0, s1};
  out->push_back(std::move(kin));
  Factor turn;
  turn.kind = Factor::Kind::kTurnRate;
  turn.cost = std::make_unique<TurnRateCost>(dt_s, q.turn_rate_radps_per_sqrt_s);
  turn.loss = turn_loss;
  turn.blocks = {s0, s1};
  out->push_back(std::move(turn));
}

void AddToProblem(const ChainProblem& chain, ceres::Problem* problem) {
  for (double* x : chain.states) problem->AddParameterBlock(x, 6);
  problem->AddParameterBlock(chain.moment, 3);
  for (const auto& group : chain.groups) {
    for (const Factor* f : group) AddToProblem(*f, problem);
  }
}


}  // namespace magnav::tracker::internal
