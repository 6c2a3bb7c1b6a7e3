// Internal: the window's per-sensor offset lines (SensorOffsetOptions::
// window_lines) marginalised out of the window's covariance.
//
// The window solves its track and every sensor's B offset line
// o_j(t) = level_j + rate_j·(t − t_ref) by alternation (sensor_offset.h), so
// the chain's covariance (ChainCovariance) is the track's *given* the
// offsets: it leaves out what the lines took from the samples. With the
// joint information
//   H = [A  B; Bᵀ D],   A: the chain's (states x_0..x_{N−1}, moment),
//                       D: the offsets' (their samples and priors),
//                       B: their coupling through the B residuals,
// the states' and the moment's marginal covariance is the top-left block of
// H⁻¹ = A⁻¹ + Z S⁻¹ Zᵀ with Z = A⁻¹ B and S = D − Bᵀ Z (the Schur complement
// of A): each published covariance gets Z_k S⁻¹ Z_kᵀ added, Z_k the rows of
// x_k. Z is solved on the chain's factorisation (ChainSolve, O(N) per
// column; 6 columns per sensor with a line).
//
// Each measurement factor's residual is e = L (h − z) with z's B part
// B − B0 − o(t) (cost_functions.h) and L block-diagonal between B and T
// (MeasurementSqrtInfo), so ∂e/∂level = [I/σ_B; 0] and ∂e/∂rate = dt·[I/σ_B; 0];
// the robust loss's weight ρ′(‖e‖²) scales each factor's terms, as in the
// chain's own linearisation (AccumulateFactor). Offsets are in nT and nT/s
// here (1e-9 T, 1e-9 T/s; world NED) so that D is of order one per sample.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "factors.h"

namespace magnav::tracker::internal {

class OffsetLineMarginal {
 public:
  // `num_states`: the chain's N; `sensors`: the sensor ids that have a line
  // (the columns, 6 each: level x y z, rate x y z).
  OffsetLineMarginal(std::size_t num_states, const std::vector<std::uint32_t>& sensors);

  // One measurement factor (a MeasurementCost at the current parameter
  // values, blocks {x_k, moment}) of chain state k at sensor `sensor_id`,
  // σ_B sigma_B_T (T), dt_s its time minus the lines' reference time (s).
  // False (nothing added) if the sensor has no line or the factor cannot be
  // evaluated (the chain leaves it out too).
  bool Add(const Factor& f, std::size_t k, std::uint32_t sensor_id, double sigma_B_T, double dt_s);
  // Every line's zero-mean prior: σ level_sigma_T (T) on the level, σ
  // rate_sigma_T_per_s (T/s) on the rate, per axis (as LineOffsetAccumulator).
  void AddPriors(double level_sigma_T, double rate_sigma_T_per_s);

  // P_x[k] += Z_k S⁻¹ Z_kᵀ and P_m += Z_m S⁻¹ Z_mᵀ (the moment block in the
  // chain's parameter units), `f` the chain's factorisation at the same
  // parameter values. False (nothing changed) if S is not positive definite
  // or the sizes disagree.
  bool Marginalize(const ChainFactorization& f, std::vector<StateCovariance>* P_x, Eigen::Matrix3d* P_m) const;

  std::size_t num_lines() const { return column_.size(); }

 private:
  std::size_t num_states_;
  std::map<std::uint32_t, Eigen::Index> column_;  // sensor id → first column
  Eigen::MatrixXd B_;  // (6N + 3) × 6L: Σ J_xᵀ J_o
  Eigen::MatrixXd D_;  // 6L × 6L: Σ J_oᵀ J_o + priors
};

}  // namespace magnav::tracker::internal
