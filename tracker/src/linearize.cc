#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>

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

namespace {

// JᵀJ and Jᵀe of a two-block factor with fixed sizes (no heap, fixed-size
// products): M residuals, blocks of N0 and N1 parameters.
template <int M, int N0, int N1>
bool AccumulateFixed(const Factor& f, const std::function<int(const double*)>& offset, LocalH* H, LocalG* g) {
  Eigen::Matrix<double, M, 1> e;
  Eigen::Matrix<double, M, N0, Eigen::RowMajor> J0;
  Eigen::Matrix<double, M, N1, (N1 == 1 ? Eigen::ColMajor : Eigen::RowMajor)> J1;
  double* jac[2] = {J0.data(), J1.data()};
  const double* params[2] = {f.blocks[0], f.blocks[1]};
  if (!f.cost->Evaluate(params, e.data(), jac)) return false;
  if (f.loss != nullptr) {
    double rho[3];
    f.loss->Evaluate(e.squaredNorm(), rho);
    const double w = std::sqrt(std::max(rho[1], 0.0));
    e *= w;
    J0 *= w;
    J1 *= w;
  }
  const int o0 = offset(f.blocks[0]), o1 = offset(f.blocks[1]);
  if (o0 >= 0) {
    H->block<N0, N0>(o0, o0) += J0.transpose().lazyProduct(J0);
    g->segment<N0>(o0).noalias() += J0.transpose() * e;
  }
  if (o1 >= 0) {
    H->block<N1, N1>(o1, o1) += J1.transpose().lazyProduct(J1);
    g->segment<N1>(o1).noalias() += J1.transpose() * e;
  }
  if (o0 >= 0 && o1 >= 0) {
    const Eigen::Matrix<double, N0, N1> X = J0.transpose().lazyProduct(J1);
    H->block<N0, N1>(o0, o1) += X;
    H->block<N1, N0>(o1, o0) += X.transpose();
  }
  return true;
}

}  // namespace

bool AccumulateFactor(const Factor& f, const std::function<int(const double*)>& offset, LocalH* H,
                      LocalG* g) {
  const auto& sizes = f.cost->parameter_block_sizes();
  if (sizes.size() != 2 || f.blocks.size() != 2) return false;
  const int m = f.cost->num_residuals();
  if (sizes[0] == 6 && sizes[1] == 3 && m == 8) return AccumulateFixed<8, 6, 3>(f, offset, H, g);
  if (sizes[0] == 6 && sizes[1] == 3 && m == 9) return AccumulateFixed<9, 6, 3>(f, offset, H, g);
  if (sizes[0] == 6 && sizes[1] == 6 && m == 5) return AccumulateFixed<5, 6, 6>(f, offset, H, g);
  if (sizes[0] == 6 && sizes[1] == 6 && m == 1) return AccumulateFixed<1, 6, 6>(f, offset, H, g);
  return false;  // not a tracker factor shape
}

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
                                 bool warm_up_turn_rate,
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
  double scale =
      robust ? NextLossScale(measurements, nominal, std::numeric_limits<double>::infinity()) : nominal;
  bool warm = warm_up_turn_rate;
  for (int pass = 0; pass < 12; ++pass) {
    const bool final_pass = !warm && scale <= nominal;
    // Passes whose result is only a starting point stop early.
    so.function_tolerance = (intermediate || !final_pass) ? std::max(options.function_tolerance,
                                                                     options.intermediate_function_tolerance)
                                                          : options.function_tolerance;
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

bool FactorizeChain(const std::vector<double*>& x, const double* m,
                    const std::vector<std::vector<const Factor*>>& groups, ChainFactorization* out) {
  const std::size_t n = x.size();
  if (n == 0 || groups.size() != n) return false;
  using Mat99 = Eigen::Matrix<double, 9, 9>;
  out->D_inv.resize(n);
  out->C.resize(n);
  out->g.resize(n);
  Mat99 carried = Mat99::Zero();  // information on (x_k, m) from eliminated states
  Eigen::Matrix<double, 9, 1> carried_g = Eigen::Matrix<double, 9, 1>::Zero();
  LocalH H;
  LocalG g;
  for (std::size_t k = 0; k < n; ++k) {
    const double* xk = x[k];
    const double* xn = k + 1 < n ? x[k + 1] : nullptr;
    const auto offset = [&](const double* p) -> int {
      if (p == xk) return 0;
      if (xn != nullptr && p == xn) return 6;
      if (p == m) return 12;
      return -1;
    };
    H.setZero();
    g.setZero();
    for (const Factor* f : groups[k]) {
      if (!AccumulateFactor(*f, offset, &H, &g)) return false;
    }
    H.topLeftCorner<6, 6>() += carried.topLeftCorner<6, 6>();
    H.block<6, 3>(0, 12) += carried.topRightCorner<6, 3>();
    H.block<3, 6>(12, 0) += carried.bottomLeftCorner<3, 6>();
    H.block<3, 3>(12, 12) += carried.bottomRightCorner<3, 3>();
    g.head<6>() += carried_g.head<6>();
    g.tail<3>() += carried_g.tail<3>();
    const StateCovariance D = H.topLeftCorner<6, 6>();
    const Eigen::LLT<StateCovariance> llt(D);
    if (llt.info() != Eigen::Success) return false;
    out->D_inv[k] = llt.solve(StateCovariance::Identity());
    out->C[k] = H.topRightCorner<6, 9>();
    out->g[k] = g.head<6>();
    // lazyProduct: coefficient-based kernels for these small fixed sizes.
    const Eigen::Matrix<double, 9, 6> CtDinv = out->C[k].transpose().lazyProduct(out->D_inv[k]);
    carried = H.bottomRightCorner<9, 9>() - CtDinv.lazyProduct(out->C[k]);
    carried = 0.5 * (carried + carried.transpose()).eval();
    carried_g = g.tail<9>() - CtDinv * out->g[k];
  }
  // After the last state only the moment part of `carried` is meaningful.
  out->S = carried.bottomRightCorner<3, 3>();
  out->g_m = carried_g.tail<3>();
  return Eigen::LLT<Eigen::Matrix3d>(out->S).info() == Eigen::Success;
}

bool ChainCovariance(const ChainFactorization& f, std::vector<StateCovariance>* P_x, Eigen::Matrix3d* P_m) {
  using Mat99 = Eigen::Matrix<double, 9, 9>;
  const std::size_t n = f.D_inv.size();
  *P_m = Eigen::LLT<Eigen::Matrix3d>(f.S).solve(Eigen::Matrix3d::Identity());
  P_x->assign(n, StateCovariance::Zero());
  Mat99 sigma = Mat99::Zero();  // Cov(x_{k+1}, m)
  sigma.bottomRightCorner<3, 3>() = *P_m;
  for (std::size_t k = n; k-- > 0;) {
    const Mat69 G = -f.D_inv[k].lazyProduct(f.C[k]);
    const Mat69 GS = G.lazyProduct(sigma);
    (*P_x)[k] = f.D_inv[k] + GS.lazyProduct(G.transpose());
    (*P_x)[k] = 0.5 * ((*P_x)[k] + (*P_x)[k].transpose()).eval();
    sigma.topLeftCorner<6, 6>() = (*P_x)[k];
    sigma.topRightCorner<6, 3>() = GS.rightCols<3>();
    sigma.bottomLeftCorner<3, 6>() = GS.rightCols<3>().transpose();
  }
  for (const auto& P : *P_x) {
    if (!P.allFinite()) return false;
  }
  return P_m->allFinite();
}

void ChainStep(const ChainFactorization& f, std::vector<StateVector>* dx, Eigen::Vector3d* dm) {
  const std::size_t n = f.D_inv.size();
  *dm = -Eigen::LLT<Eigen::Matrix3d>(f.S).solve(f.g_m);
  dx->assign(n, StateVector::Zero());
  Eigen::Matrix<double, 9, 1> y;  // (Δx_{k+1}, Δm)
  y << StateVector::Zero(), *dm;
  for (std::size_t k = n; k-- > 0;) {
    (*dx)[k] = -f.D_inv[k] * (f.g[k] + f.C[k] * y);
    y.head<6>() = (*dx)[k];
  }
}

double TotalCost(const std::vector<std::vector<const Factor*>>& groups) {
  double cost = 0.0;
  for (const auto& group : groups) {
    for (const Factor* f : group) {
      // Tracker factors have two blocks and at most 9 residuals.
      const int m = f->cost->num_residuals();
      if (m > 9 || f->blocks.size() != 2) return std::numeric_limits<double>::infinity();
      Eigen::Matrix<double, 9, 1> e = Eigen::Matrix<double, 9, 1>::Zero();
      const double* params[2] = {f->blocks[0], f->blocks[1]};
      if (!f->cost->Evaluate(params, e.data(), nullptr)) return std::numeric_limits<double>::infinity();
      double rho[3] = {e.squaredNorm(), 1.0, 0.0};
      if (f->loss != nullptr) f->loss->Evaluate(e.squaredNorm(), rho);
      cost += 0.5 * rho[0];
    }
  }
  return cost;
}

bool ChainCovariance(const std::vector<double*>& x, const double* m,
                     const std::vector<std::vector<const Factor*>>& groups, std::vector<StateCovariance>* P_x,
                     Eigen::Matrix3d* P_m) {
  ChainFactorization f;
  return FactorizeChain(x, m, groups, &f) && ChainCovariance(f, P_x, P_m);
}

}  // namespace magnav::tracker::internal
