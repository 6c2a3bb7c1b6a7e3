// Internal: the factor graph of a pass — one list of residuals shared by the
// batch smoother (handed to Ceres), its covariance and the Cramér–Rao bounds
// (Gauss-Newton / Fisher information assembled from the same residuals), so
// all three use one model.
//
// Parameters, packed in one vector: the vessel state of every epoch (5 each,
// epoch order), then every sensor's (x, y) (2 each, Pass::sensors order).
#pragma once

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"
#include "timeline.h"

namespace magnav::localizer::internal {

struct Factor {
  enum class Kind { kMagnetometer, kMotion, kGnss, kPrior };
  Kind kind = Kind::kMagnetometer;
  std::unique_ptr<ceres::CostFunction> cost;
  std::vector<int> blocks;  // block ids: epoch k → k, sensor j → num_epochs + j
};

struct Graph {
  Timeline timeline;
  int num_epochs = 0;
  int num_sensors = 0;
  std::vector<Factor> factors;

  int num_state_params() const { return 5 * num_epochs; }
  int num_params() const { return 5 * num_epochs + 2 * num_sensors; }
  int offset(int block) const { return block < num_epochs ? 5 * block : 5 * num_epochs + 2 * (block - num_epochs); }
  int size(int block) const { return block < num_epochs ? 5 : 2; }
};

Graph BuildGraph(const Pass& pass, const LocalizerOptions& options);

// Parameter vector of a trajectory (one state per epoch) and sensor positions.
std::vector<double> Pack(const Graph& g, const std::vector<VesselVector>& trajectory,
                         const std::vector<Eigen::Vector2d>& sensors_xy);

// Gauss-Newton information Σ JᵀJ over the factors at `params` (the Fisher
// information when the residuals are whitened). `magnetometer_loss` and
// `gnss_loss`, if not null, reweight each magnetometer / GNSS factor by
// ρ'(‖e‖²) (as Ceres does). Returns false if a factor cannot be evaluated.
bool Information(const Graph& g, const std::vector<double>& params, const ceres::LossFunction* magnetometer_loss,
                 const ceres::LossFunction* gnss_loss, Eigen::SparseMatrix<double>* H);

// Factors of one kind whose whitened squared residual ‖e‖² at `params`
// exceeds `threshold` (a factor that cannot be evaluated counts too).
int CountBeyond(const Graph& g, const std::vector<double>& params, Factor::Kind kind, double threshold);

// Covariance of the sensor block (last 2M parameters) of the inverse of H,
// by eliminating the trajectory block (sparse LDLᵀ of the block-tridiagonal
// trajectory information). False if H is not positive definite.
bool SensorMarginalCovariance(const Graph& g, const Eigen::SparseMatrix<double>& H, Eigen::MatrixXd* cov);

// Per-sensor (H_ss,jj)⁻¹: the bound for a perfectly known trajectory.
bool KnownTrajectoryCovariances(const Graph& g, const Eigen::SparseMatrix<double>& H,
                                std::vector<Eigen::Matrix2d>* cov);

}  // namespace magnav::localizer::internal
