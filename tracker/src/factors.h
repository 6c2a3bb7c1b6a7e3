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

// New loss of a type with scale a (in σ of the residual norm); null for trivial.
std::unique_ptr<ceres::LossFunction> MakeLoss(LossType type, double scale_sigma);

// Adds a factor to a problem that does not own costs or losses.
void AddToProblem(const Factor& f, ceres::Problem* problem);

// Problem options that leave cost and loss functions to their owner.
ceres::Problem::Options NonOwningProblemOptions();

// Measurement factors of one epoch.
void AddMeasurementFactors(const Epoch& epoch, const Eigen::Vector3d& B0_W, const TrackerOptions& options,
                           double moment_scale, double* state, double* moment, std::vector<Factor>* out);
// Process factors (kinematic + turn rate) between two epochs.
void AddProcessFactors(double dt_s, const ProcessNoise& q, const ceres::LossFunction* turn_loss, double* s0,
                       double* s1, std::vector<Factor>* out);

// Gauss-Newton contribution of one factor at the current parameter values,
// robust loss applied by iteratively-reweighted scaling (√ρ'(‖e‖²)).
// `offset(block)` gives the block's index in the local 15-dim system
// (−1 = skip). Every tracker factor has two parameter blocks.
// Returns false if the factor could not be evaluated.
using LocalH = Eigen::Matrix<double, 15, 15>;
using LocalG = Eigen::Matrix<double, 15, 1>;
bool AccumulateFactor(const Factor& f, const std::function<int(const double*)>& offset, LocalH* H, LocalG* g);

// Robust-loss continuation. Far from the solution every whitened measurement
// residual is huge (SQUID-level σ), and a loss of a few σ would then treat all
// samples as outliers. Each pass uses scale_k = max(nominal, min(scale_{k−1}/10,
// 3 · median ‖e‖)) over the measurement factors at the current estimate; the
// passes stop after a pass at the nominal scale.
double NextLossScale(const std::vector<Factor*>& measurements, double nominal, double previous);

// One continuation schedule for a problem. `build(meas_loss, warm_turn)`
// makes the problem with that measurement loss (null = squared) and, if
// warm_turn, Gaussian warm-up turn-rate factors instead of the robust ones.
struct PassResult {
  ceres::Solver::Summary last;
  int iterations = 0;
  double solve_time_s = 0.0;
  double first_initial_cost = 0.0;
  // Loss of the final pass; the measurement factors point to it.
  std::unique_ptr<ceres::LossFunction> final_loss;
};
// `intermediate`: every pass only gives a starting point (looser tolerance).
PassResult SolveWithContinuation(const TrackerOptions& options, int max_iterations_per_pass,
                                 bool intermediate, const std::vector<Factor*>& measurements,
                                 bool warm_up_turn_rate,
                                 const std::function<void(ceres::Problem*, bool warm_turn)>& build);

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
bool FactorizeChain(const std::vector<double*>& x, const double* m,
                    const std::vector<std::vector<const Factor*>>& groups, ChainFactorization* out);
bool ChainCovariance(const ChainFactorization& f, std::vector<StateCovariance>* P_x, Eigen::Matrix3d* P_m);
// Gauss-Newton step by back substitution: Δm = −S⁻¹ g_m,
// Δx_k = −D_k⁻¹ (g_k + C_k [Δx_{k+1}; Δm]).
void ChainStep(const ChainFactorization& f, std::vector<StateVector>* dx, Eigen::Vector3d* dm);
// ½ Σ ρ(‖e‖²) over the factors.
double TotalCost(const std::vector<std::vector<const Factor*>>& groups);

bool ChainCovariance(const std::vector<double*>& x, const double* m,
                     const std::vector<std::vector<const Factor*>>& groups, std::vector<StateCovariance>* P_x,
                     Eigen::Matrix3d* P_m);

}  // namespace magnav::tracker::internal
