#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "factors.h"
#include "magnav/tracker/cost_functions.h"
#include "magnav/tracker/initialize.h"

namespace magnav::tracker::internal {

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
  kin.cost = std::make_unique<KinematicCost>(dt_s, q.position_m_per_sqrt_s, q.speed_mps_per_sqrt_s,
                                             q.heading_rad_per_sqrt_s);
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
bool AccumulateFixed(const Factor& f, const LocalOffset& offset, LocalH* H, LocalG* g) {
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
    g->segment<N0>(o0).noalias() += J0.transpose().lazyProduct(e);
  }
  if (o1 >= 0) {
    H->block<N1, N1>(o1, o1) += J1.transpose().lazyProduct(J1);
    g->segment<N1>(o1).noalias() += J1.transpose().lazyProduct(e);
  }
  if (o0 >= 0 && o1 >= 0) {
    const Eigen::Matrix<double, N0, N1> X = J0.transpose().lazyProduct(J1);
    H->block<N0, N1>(o0, o1) += X;
    H->block<N1, N0>(o1, o0) += X.transpose();
  }
  return true;
}

}  // namespace

bool AccumulateFactor(const Factor& f, const LocalOffset& offset, LocalH* H,
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

void AddToProblem(const ChainProblem& chain, ceres::Problem* problem) {
  for (double* x : chain.states) problem->AddParameterBlock(x, 6);
  problem->AddParameterBlock(chain.moment, 3);
  for (const auto& group : chain.groups) {
    for (const Factor* f : group) AddToProblem(*f, problem);
  }
}

PassResult SolveWithContinuation(const TrackerOptions& options, int max_iterations_per_pass,
                                 bool intermediate, const std::vector<Factor*>& measurements,
                                 bool warm_up_turn_rate, const std::function<ChainProblem(bool warm_turn)>& build) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = max_iterations_per_pass;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
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
    if (final_pass) break;
    warm = false;
    if (robust) scale = NextLossScale(measurements, nominal, scale);
  }
  return out;
}

namespace {

// Inverse of a symmetric positive-definite 6×6 matrix A = LLᵀ (and L⁻¹) by
// Cholesky with fixed-size loops (Eigen's LLT::solve takes its dynamic-size triangular
// path for a matrix right-hand side, a third of the chain elimination's
// time). False if A is not positive definite.
bool InvertSpd6(const StateCovariance& A, StateCovariance* A_inv, StateCovariance* L_inv_out) {
  StateCovariance L = StateCovariance::Zero();
  for (int j = 0; j < 6; ++j) {
    double d = A(j, j);
    for (int p = 0; p < j; ++p) d -= L(j, p) * L(j, p);
    if (!(d > 0.0)) return false;
    L(j, j) = std::sqrt(d);
    for (int i = j + 1; i < 6; ++i) {
      double v = A(i, j);
      for (int p = 0; p < j; ++p) v -= L(i, p) * L(j, p);
      L(i, j) = v / L(j, j);
    }
  }
  StateCovariance& L_inv = *L_inv_out;  // lower triangular
  L_inv.setZero();
  for (int j = 0; j < 6; ++j) {
    L_inv(j, j) = 1.0 / L(j, j);
    for (int i = j + 1; i < 6; ++i) {
      double v = 0.0;
      for (int p = j; p < i; ++p) v -= L(i, p) * L_inv(p, j);
      L_inv(i, j) = v / L(i, i);
    }
  }
  *A_inv = L_inv.transpose().lazyProduct(L_inv);
  return A_inv->allFinite();
}

}  // namespace

namespace {

// Number of chunks ParallelFor splits n items into.
std::size_t NumChunks(std::size_t n, int num_threads) {
  return std::max<std::size_t>(1, std::min<std::size_t>(n, static_cast<std::size_t>(std::max(num_threads, 1))));
}

// Runs body(chunk, begin, end) over [0, n) split into NumChunks contiguous
// chunks, chunk 0 in the calling thread. Returns false if any chunk did.
bool ParallelFor(std::size_t n, int num_threads,
                 const std::function<bool(std::size_t, std::size_t, std::size_t)>& body) {
  const std::size_t chunks = NumChunks(n, num_threads);
  if (chunks == 1) return body(0, 0, n);
  std::vector<char> ok(chunks, 0);
  std::vector<std::thread> workers;
  for (std::size_t c = 1; c < chunks; ++c) {
    workers.emplace_back([&, c] { ok[c] = body(c, c * n / chunks, (c + 1) * n / chunks); });
  }
  ok[0] = body(0, 0, n / chunks);
  for (auto& w : workers) w.join();
  return std::all_of(ok.begin(), ok.end(), [](char b) { return b != 0; });
}

// ½ ρ(‖e‖²) of one factor; +∞ if it cannot be evaluated.
double FactorCost(const Factor& f) {
  // Tracker factors have two blocks and at most 9 residuals.
  const int m = f.cost->num_residuals();
  if (m > 9 || f.blocks.size() != 2) return std::numeric_limits<double>::infinity();
  Eigen::Matrix<double, 9, 1> e = Eigen::Matrix<double, 9, 1>::Zero();
  const double* params[2] = {f.blocks[0], f.blocks[1]};
  if (!f.cost->Evaluate(params, e.data(), nullptr)) return std::numeric_limits<double>::infinity();
  double rho[3] = {e.squaredNorm(), 1.0, 0.0};
  if (f.loss != nullptr) f.loss->Evaluate(e.squaredNorm(), rho);
  return 0.5 * rho[0];
}

}  // namespace

bool LinearizeChain(const ChainProblem& chain, ChainLinearization* out, int num_threads) {
  const std::size_t n = chain.states.size();
  if (n == 0 || chain.groups.size() != n) return false;
  out->H.resize(n);
  out->g.resize(n);
  return ParallelFor(n, num_threads, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      const LocalOffset offset{chain.states[k], k + 1 < n ? chain.states[k + 1] : nullptr, chain.moment};
      LocalH& H = out->H[k];
      LocalG& g = out->g[k];
      H.setZero();
      g.setZero();
      for (const Factor* f : chain.groups[k]) {
        if (!AccumulateFactor(*f, offset, &H, &g)) return false;
      }
    }
    return true;
  });
}

bool EliminateChain(const ChainLinearization& lin, double lambda, ChainFactorization* out) {
  const std::size_t n = lin.H.size();
  if (n == 0 || lin.g.size() != n) return false;
  const auto damping = [lambda](const auto& diagonal) {
    return (lambda * diagonal.array().max(1e-6).min(1e32)).matrix().eval();
  };
  using Mat99 = Eigen::Matrix<double, 9, 9>;
  out->D_inv.resize(n);
  out->C.resize(n);
  out->g.resize(n);
  Mat99 carried = Mat99::Zero();  // information on (x_k, m) from eliminated states
  Eigen::Matrix<double, 9, 1> carried_g = Eigen::Matrix<double, 9, 1>::Zero();
  StateVector diag_next = StateVector::Zero();  // undamped diag(H) of x_k from group k−1
  Eigen::Vector3d diag_m = Eigen::Vector3d::Zero();
  StateCovariance L_inv;
  for (std::size_t k = 0; k < n; ++k) {
    // Blocks of group k over [x_k; x_{k+1}; m], plus what the eliminated
    // states carried onto (x_k, m): D (x_k), C (x_k with (x_{k+1}, m)), B.
    const LocalH& H = lin.H[k];
    const LocalG& g = lin.g[k];
    StateCovariance D = H.topLeftCorner<6, 6>() + carried.topLeftCorner<6, 6>();
    diag_m += H.diagonal().tail<3>();
    if (lambda > 0.0) {
      D.diagonal() += damping((H.diagonal().head<6>() + diag_next).eval());
      diag_next = H.diagonal().segment<6>(6);
    }
    Mat69& C = out->C[k];
    C.leftCols<6>() = H.block<6, 6>(0, 6);
    C.rightCols<3>() = H.block<6, 3>(0, 12) + carried.topRightCorner<6, 3>();
    out->g[k] = g.head<6>() + carried_g.head<6>();
    if (!InvertSpd6(D, &out->D_inv[k], &L_inv)) return false;
    // Schur complement B − Cᵀ D⁻¹ C = B − WᵀW with W = L⁻¹ C (symmetric by
    // construction); lazyProduct: coefficient-based kernels for small sizes.
    const Mat69 W = L_inv.lazyProduct(C);
    const Eigen::Matrix<double, 6, 1> w = L_inv.lazyProduct(out->g[k]);
    const Eigen::Matrix3d carried_mm = carried.bottomRightCorner<3, 3>();
    const Eigen::Vector3d carried_gm = carried_g.tail<3>();
    carried = H.bottomRightCorner<9, 9>();
    carried.bottomRightCorner<3, 3>() += carried_mm;
    carried.noalias() -= W.transpose().lazyProduct(W);
    carried_g = g.tail<9>();
    carried_g.tail<3>() += carried_gm;
    carried_g.noalias() -= W.transpose().lazyProduct(w);
  }
  // After the last state only the moment part of `carried` is meaningful.
  out->S = carried.bottomRightCorner<3, 3>();
  if (lambda > 0.0) out->S.diagonal() += damping(diag_m);
  out->g_m = carried_g.tail<3>();
  return out->S.allFinite() && Eigen::LLT<Eigen::Matrix3d>(out->S).info() == Eigen::Success;
}

bool FactorizeChain(const ChainProblem& chain, ChainFactorization* out, int num_threads) {
  ChainLinearization lin;
  return LinearizeChain(chain, &lin, num_threads) && EliminateChain(lin, 0.0, out);
}

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
      if (accepted) {
        cost = new_cost;
        accepted = LinearizeChain(chain, &lin, options.num_threads);
      }
      if (!accepted) {
        for (std::size_t k = 0; k < n; ++k) Eigen::Map<StateVector>(chain.states[k]) = x0[k];
        Eigen::Map<Eigen::Vector3d>(chain.moment) = m0;
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
    (*dx)[k] = -f.D_inv[k].lazyProduct((f.g[k] + f.C[k].lazyProduct(y)).eval());
    y.head<6>() = (*dx)[k];
  }
}

double TotalCost(const std::vector<std::vector<const Factor*>>& groups, int num_threads) {
  std::vector<double> partial(NumChunks(groups.size(), num_threads), 0.0);
  ParallelFor(groups.size(), num_threads, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      for (const Factor* f : groups[k]) partial[chunk] += FactorCost(*f);
    }
    return true;
  });
  double cost = 0.0;
  for (double c : partial) cost += c;  // fixed order: the same sum on every run
  return cost;
}

bool ChainCovariance(const ChainProblem& chain, std::vector<StateCovariance>* P_x, Eigen::Matrix3d* P_m) {
  ChainFactorization f;
  return FactorizeChain(chain, &f) && ChainCovariance(f, P_x, P_m);
}

}  // namespace magnav::tracker::internal
