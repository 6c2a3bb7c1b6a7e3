// Internal: residual blocks held outside ceres::Problem so that the window
// tracker can rebuild problems and linearise factors for marginalisation.
#pragma once

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <vector>

#include "magnav/core/ceres_loss.h"
#include "magnav/tracker/options.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker::internal {

struct Factor {
  enum class Kind { kMeasurement, kKinematic, kTurnRate, kPrior };
  Kind kind = Kind::kMeasurement;
  std::unique_ptr<ceres::CostFunction> cost;
  const ceres::LossFunction* loss = nullptr;  // not owned; null = squared loss
  std::vector<double*> blocks;
};

// Losses: MakeCeresLoss (core/ceres_loss.h), shared with the localizer.

// Adds a factor to a problem that does not own costs or losses.
void AddToProblem(const Factor& f, ceres::Problem* problem);

// Problem options that leave cost and loss functions to their owner.
ceres::Problem::Options NonOwningProblemOptions();

// Solver options of the track's Ceres solves (the batch's continuation passes
// and joint solve, the window's Ceres solve): sparse normal Cholesky, at most
// max_iterations, the given function tolerance and the gradient and parameter
// tolerances and threads of `options`.
ceres::Solver::Options SparseSolverOptions(const TrackerOptions& options, int max_iterations,
                                           double function_tolerance);

// Measurement factors of one epoch.
void AddMeasurementFactors(const Epoch& epoch, const Eigen::Vector3d& B0_W, const TrackerOptions& options,
                           double moment_scale, double* state, double* moment, std::vector<Factor>* out);
// The depth random walk from `from` to the next epoch: ProcessNoise's
// depth_weak_m_per_sqrt_s if it is on and every measured tensor of `from` is
// below depth_weak_tensor_snr σ_T (the depth not observed), else
// depth_m_per_sqrt_s.
double DepthWalk(const Epoch& from, const TrackerOptions& options);
// Process factors (kinematic + turn rate) between two epochs.
void AddProcessFactors(double dt_s, const ProcessNoise& q, const ceres::LossFunction* turn_loss, double* s0,
                       double* s1, std::vector<Factor>* out);

// Gauss-Newton contribution of one factor at the current parameter values,
// robust loss applied by iteratively-reweighted scaling (√ρ'(‖e‖²)).
// `offset(block)` gives the block's index in the local 15-dim system
// [x_k (6); x_{k+1} (6); m (3)]: 0, 6, 12, or −1 = skip. Every tracker factor
// has two parameter blocks. Returns false if the factor could not be evaluated.
using LocalH = Eigen::Matrix<double, 15, 15>;
using LocalG = Eigen::Matrix<double, 15, 1>;
struct LocalOffset {
  const double* xk = nullptr;
  const double* xn = nullptr;  // null: no next state
  const double* m = nullptr;
  int operator()(const double* p) const {
    if (p == xk) return 0;
    if (xn != nullptr && p == xn) return 6;
    if (p == m) return 12;
    return -1;
  }
};
bool AccumulateFactor(const Factor& f, const LocalOffset& offset, LocalH* H, LocalG* g);

// Robust-loss continuation. Far from the solution every whitened measurement
// residual is huge (SQUID-level σ), and a loss of a few σ would then treat all
// samples as outliers. Each pass uses scale_k = max(nominal, min(scale_{k−1}/10,
// 3 · median ‖e‖)) over the measurement factors at the current estimate; the
// passes stop after a pass at the nominal scale.
double NextLossScale(const std::vector<Factor*>& measurements, double nominal, double previous);

// A chain-structured least-squares problem: states x_0..x_{N-1} (6 each) and
// one global block m (3); groups[k] holds the factors whose earliest chain
// state is x_k, and they may touch only x_k, x_{k+1} and m. The batch, the
// window and the covariance all work on this one shape.
struct ChainProblem {
  std::vector<double*> states;
  double* moment = nullptr;
  std::vector<std::vector<const Factor*>> groups;
};
// Adds the parameter blocks and factors to a problem that does not own them.
void AddToProblem(const ChainProblem& chain, ceres::Problem* problem);

// One continuation schedule for a problem, solved by options.batch_solver.
// `build(warm_turn)` returns the
// problem (factors' measurement losses are set by the schedule) with, if
// warm_turn, Gaussian warm-up turn-rate factors instead of the robust ones.
struct PassResult {
  ceres::Solver::Summary last;
  int iterations = 0;
  double solve_time_s = 0.0;
  double first_initial_cost = 0.0;
  // The continuation reached its pass at the nominal loss scale (false: it
  // ran out of passes, and the last solve's CONVERGENCE is not the problem's).
  bool reached_final_pass = false;
  // Loss of the final pass; the measurement factors point to it.
  std::unique_ptr<ceres::LossFunction> final_loss;
};
// `intermediate`: every pass only gives a starting point (looser tolerance).
PassResult SolveWithContinuation(const TrackerOptions& options, int max_iterations_per_pass,
                                 bool intermediate, const std::vector<Factor*>& measurements,
                                 bool warm_up_turn_rate, const std::function<ChainProblem(bool warm_turn)>& build);

// Levenberg-Marquardt on a chain problem, with the step rules of Ceres'
// trust-region minimiser (LEVENBERG_MARQUARDT strategy: damping λ·diag(H)
// with diag clamped to [1e-6, 1e32], λ = 1/radius, initial radius 1e4, steps
// accepted when actual/predicted decrease > 1e-3, radius ×1/max(1/3, 1−(2ρ−1)³)
// on success and ÷2, ÷4, ... on failure). Each iteration linearises every
// factor once (robust losses by √ρ' reweighting) and solves the damped normal
// equations by block-tridiagonal elimination of the chain (FactorizeChain),
// O(N) instead of a general sparse Cholesky. The summary is filled like
// Ceres' (termination type, message, costs, one IterationSummary per
// iteration) so callers treat both solvers alike.
struct ChainSolverOptions {
  int max_num_iterations = 100;
  double function_tolerance = 1e-8;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-10;
  double initial_trust_region_radius = 1e4;
  double max_trust_region_radius = 1e16;
  double min_trust_region_radius = 1e-32;
  double min_relative_decrease = 1e-3;
  int num_threads = 1;  // threads evaluating the factors
};
void SolveChainLevenbergMarquardt(const ChainSolverOptions& options, const ChainProblem& chain,
                                  ceres::Solver::Summary* summary);

// The moment update of SolveChainLevenbergMarquardt: m ⊕ Δm turns the
// tangential horizontal part of Δm into a rotation about the vertical (by
// Δm_t / ρ, ρ = horizontal magnitude) and adds the radial and vertical parts,
// so that ⊕ agrees with + to first order. Why: a body moment rotated about
// the vertical by α and every heading changed by −α give the same world
// moment, a curved valley of the cost in Cartesian m that a straight step
// leaves radially; with ⊕ it is a straight line (observed: the SQUID ship
// pass crawled for 440 iterations along it with +, and the moment's y part
// stopped 4 σ off after the default 100).
Eigen::Vector3d RetractMoment(const Eigen::Vector3d& m, const Eigen::Vector3d& dm);

// Marginal covariances of a chain of states x_0..x_{N-1} (6 each) and one
// global block m (3) at the current parameter values. groups[k] holds the
// factors whose earliest chain state is x_k; they may touch only x_k, x_{k+1}
// and m. Forward pass: eliminate x_0, x_1, ... (Schur complements onto
// (x_{k+1}, m)); backward pass: x_k | (x_{k+1}, m) ~ N(−D_k⁻¹ C_k y, D_k⁻¹)
// gives P_kk = D_k⁻¹ + G Σ Gᵀ, G = −D_k⁻¹ C_k, Σ = Cov(x_{k+1}, m).
// Covariances are in parameter units (m in moment-block units).
using Mat69 = Eigen::Matrix<double, 6, 9>;

// Forward elimination of the chain (Gauss-Newton normal equations H δ = −g):
// per state D_k⁻¹, the coupling C_k to (x_{k+1}, m) and the reduced gradient
// g_k; S, g_m the moment system after all states are eliminated.
struct ChainFactorization {
  std::vector<StateCovariance> D_inv;
  std::vector<Mat69> C;
  std::vector<StateVector> g;
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  Eigen::Vector3d g_m = Eigen::Vector3d::Zero();
};
// Gauss-Newton information of every group at the current parameter values:
// H[k], g[k] over the local vector [x_k; x_{k+1}; m] (the x_{k+1} part is
// zero for the last state). Kept so that a rejected Levenberg-Marquardt step
// can be re-solved with more damping without evaluating the factors again.
struct ChainLinearization {
  std::vector<LocalH> H;
  std::vector<LocalG> g;
};
// num_threads > 1: the groups are evaluated by that many threads.
bool LinearizeChain(const ChainProblem& chain, ChainLinearization* out, int num_threads = 1);
// Forward elimination of (H + λ·diag(H)) δ = −g, diag clamped to [1e-6, 1e32]
// (λ = 0: plain Gauss-Newton). False if a pivot is not positive definite.
bool EliminateChain(const ChainLinearization& lin, double lambda, ChainFactorization* out);
// LinearizeChain + EliminateChain(λ = 0).
bool FactorizeChain(const ChainProblem& chain, ChainFactorization* out, int num_threads = 1);
bool ChainCovariance(const ChainFactorization& f, std::vector<StateCovariance>* P_x, Eigen::Matrix3d* P_m);
// The solution Z of H Z = R for a right-hand side of any number of columns,
// by the factorisation (f: of H, λ = 0): forward elimination of R, then
// back substitution. R's rows (and Z's) are [x_0 (6); …; x_{N−1} (6); m (3)],
// N = f.D_inv.size(), in parameter units. False if R has the wrong number of
// rows or Z is not finite.
bool ChainSolve(const ChainFactorization& f, const Eigen::MatrixXd& R, Eigen::MatrixXd* Z);
// Gauss-Newton step by back substitution: Δm = −S⁻¹ g_m,
// Δx_k = −D_k⁻¹ (g_k + C_k [Δx_{k+1}; Δm]).
void ChainStep(const ChainFactorization& f, std::vector<StateVector>* dx, Eigen::Vector3d* dm);
// ½ Σ ρ(‖e‖²) over the factors.
double TotalCost(const std::vector<std::vector<const Factor*>>& groups, int num_threads = 1);

bool ChainCovariance(const ChainProblem& chain, std::vector<StateCovariance>* P_x, Eigen::Matrix3d* P_m);

}  // namespace magnav::tracker::internal
