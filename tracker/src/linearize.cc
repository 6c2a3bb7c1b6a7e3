#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "factors.h"
#include "magnav/tracker/cost_functions.h"
#include "magnav/tracker/initialize.h"

namespace magnav::tracker::internal {

std::unique_ptr<ceres::LossFunction> MakeLoss(LossType type, double scale_sigma) {
  switch (type) {
    case LossType::kTrivial:
      return nullptr;
    case LossType::kHuber:
      return std::make_unique<ceres::HuberLoss>(scale_sigma);
    case LossType::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(scale_sigma);
  }
  return nullptr;
}

ceres::Problem::Options NonOwningProblemOptions() {
  ceres::Problem::Options o;
  o.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return o;
}

void AddToProblem(const Factor& f, ceres::Problem* problem) {
  problem->AddResidualBlock(f.cost.get(), const_cast<ceres::LossFunction*>(f.loss), f.blocks);
}

void AddMeasurementFactors(const Epoch& epoch, const Eigen::Vector3d& B0_W, const TrackerOptions& options,
                           double moment_scale, double* state, double* moment, std::vector<Factor>* out) {
  for (const GradiometerSample& s : epoch.samples) {
    const SqrtInfo8 L = MeasurementSqrtInfo(SigmaB(s, options), SigmaT(s, options), options.tensor_noise_trace_free);
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
  kin.cost.reset(KinematicResidual::Create(dt_s, q.position_m_per_sqrt_s, q.speed_mps_per_sqrt_s,
                                           q.heading_rad_per_sqrt_s));
  kin.blocks = {s0, s1};
  out->push_back(std::move(kin));
  Factor turn;
  turn.kind = Factor::Kind::kTurnRate;
  turn.cost = std::make_unique<TurnRateCost>(dt_s, q.turn_rate_radps_per_sqrt_s);
  turn.loss = turn_loss;
  turn.blocks = {s0, s1};
  out->push_back(std::move(turn));
}

bool AccumulateFactor(const Factor& f, const std::function<int(const double*)>& offset, Eigen::MatrixXd* H,
                      Eigen::VectorXd* g) {
  const int m = f.cost->num_residuals();
  const auto& sizes = f.cost->parameter_block_sizes();
  const std::size_t nb = sizes.size();
  Eigen::VectorXd e(m);
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(nb);
  std::vector<double*> jac(nb);
  for (std::size_t b = 0; b < nb; ++b) {
    J[b].resize(m, sizes[b]);
    jac[b] = J[b].data();
  }
  std::vector<const double*> params(f.blocks.begin(), f.blocks.end());
  if (!f.cost->Evaluate(params.data(), e.data(), jac.data())) return false;
  if (f.loss != nullptr) {
    double rho[3];
    f.loss->Evaluate(e.squaredNorm(), rho);
    const double w = std::sqrt(std::max(rho[1], 0.0));
    e *= w;
    for (auto& Jb : J) Jb *= w;
  }
  for (std::size_t a = 0; a < nb; ++a) {
    const int oa = offset(f.blocks[a]);
    if (oa < 0) continue;
    g->segment(oa, sizes[a]) += J[a].transpose() * e;
    for (std::size_t b = 0; b < nb; ++b) {
      const int ob = offset(f.blocks[b]);
      if (ob < 0) continue;
      H->block(oa, ob, sizes[a], sizes[b]) += J[a].transpose() * J[b];
    }
  }
  return true;
}

}  // namespace magnav::tracker::internal

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
                                 const std::vector<Factor*>& measurements, bool warm_up_turn_rate,
                                 const std::function<void(ceres::Problem*, bool warm_turn)>& build) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = max_iterations_per_pass;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
  PassResult out;
  const double nominal = options.measurement_loss_scale_sigma;
  const bool robust = options.measurement_loss != LossType::kTrivial;
  double scale = robust ? NextLossScale(measurements, nominal, std::numeric_limits<double>::infinity()) : nominal;
  bool warm = warm_up_turn_rate;
  for (int pass = 0; pass < 12; ++pass) {
    const bool final_pass = !warm && scale <= nominal;
    out.final_loss = MakeLoss(options.measurement_loss, scale);
    for (Factor* f : measurements) f->loss = out.final_loss.get();
    {
      ceres::Problem problem(NonOwningProblemOptions());
      build(&problem, warm);
      ceres::Solve(so, &problem, &out.last);
    }
    if (pass == 0) out.first_initial_cost = out.last.initial_cost;
    out.iterations += static_cast<int>(out.last.iterations.size()) - 1;
    out.solve_time_s += out.last.total_time_in_seconds;
    if (final_pass) break;
    warm = false;
    if (robust) scale = NextLossScale(measurements, nominal, scale);
  }
  return out;
}

bool ChainCovariance(const std::vector<double*>& x, const double* m,
                     const std::vector<std::vector<const Factor*>>& groups, std::vector<StateCovariance>* P_x,
                     Eigen::Matrix3d* P_m) {
  const std::size_t n = x.size();
  if (n == 0 || groups.size() != n) return false;
  using Mat69 = Eigen::Matrix<double, 6, 9>;
  using Mat99 = Eigen::Matrix<double, 9, 9>;
  std::vector<StateCovariance> D_inv(n);
  std::vector<Mat69> C(n);
  Mat99 carried = Mat99::Zero();  // information on (x_k, m) from eliminated states
  for (std::size_t k = 0; k < n; ++k) {
    const double* xk = x[k];
    const double* xn = k + 1 < n ? x[k + 1] : nullptr;
    const auto offset = [&](const double* p) -> int {
      if (p == xk) return 0;
      if (xn != nullptr && p == xn) return 6;
      if (p == m) return 12;
      return -1;
    };
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(15, 15);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(15);
    for (const Factor* f : groups[k]) {
      if (!AccumulateFactor(*f, offset, &H, &g)) return false;
    }
    H.topLeftCorner<6, 6>() += carried.topLeftCorner<6, 6>();
    H.block<6, 3>(0, 12) += carried.topRightCorner<6, 3>();
    H.block<3, 6>(12, 0) += carried.bottomLeftCorner<3, 6>();
    H.block<3, 3>(12, 12) += carried.bottomRightCorner<3, 3>();
    const StateCovariance D = H.topLeftCorner<6, 6>();
    const Eigen::LLT<StateCovariance> llt(D);
    if (llt.info() != Eigen::Success) return false;
    D_inv[k] = llt.solve(StateCovariance::Identity());
    C[k] = H.topRightCorner<6, 9>();
    carried = H.bottomRightCorner<9, 9>() - C[k].transpose() * D_inv[k] * C[k];
    carried = 0.5 * (carried + carried.transpose()).eval();
  }
  // After the last state only the moment block of `carried` is meaningful.
  const Eigen::Matrix3d S = carried.bottomRightCorner<3, 3>();
  const Eigen::LLT<Eigen::Matrix3d> llt_m(S);
  if (llt_m.info() != Eigen::Success) return false;
  *P_m = llt_m.solve(Eigen::Matrix3d::Identity());

  P_x->assign(n, StateCovariance::Zero());
  Mat99 sigma = Mat99::Zero();  // Cov(x_{k+1}, m)
  sigma.bottomRightCorner<3, 3>() = *P_m;
  for (std::size_t k = n; k-- > 0;) {
    const Mat69 G = -D_inv[k] * C[k];
    const Mat69 GS = G * sigma;
    (*P_x)[k] = D_inv[k] + GS * G.transpose();
    (*P_x)[k] = 0.5 * ((*P_x)[k] + (*P_x)[k].transpose()).eval();
    Mat99 next = Mat99::Zero();
    next.topLeftCorner<6, 6>() = (*P_x)[k];
    next.topRightCorner<6, 3>() = GS.rightCols<3>();
    next.bottomLeftCorner<3, 6>() = GS.rightCols<3>().transpose();
    next.bottomRightCorner<3, 3>() = *P_m;
    sigma = next;
  }
  for (const auto& P : *P_x) {
    if (!P.allFinite()) return false;
  }
  return true;
}

}  // namespace magnav::tracker::internal
