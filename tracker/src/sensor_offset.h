// Internal: the per-sensor B offset nuisance of a track's window and batch
// solve (SensorOffsetOptions, options.h).
#pragma once

#include <Eigen/Core>
#include <ceres/sized_cost_function.h>
#include <vector>

#include "factors.h"
#include "magnav/tracker/cost_functions.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/nees.h"

namespace magnav::tracker::internal {

// The samples that share one offset (one sensor over the window, or over a
// batch segment): the offset's conditional mean given the track at the
// current parameter values, under its zero-mean Gaussian prior.
class SensorOffsetAccumulator {
 public:
  // One measurement factor (a MeasurementCost, blocks {state, moment}) whose
  // sample has σ_B sigma_B_T and whose B currently has own_W (world NED, T)
  // of this offset removed. False (nothing added) if it cannot be evaluated.
  bool Add(const Factor& f, double sigma_B_T, const Eigen::Vector3d& own_W);
  // Σ w_i r_i/σ_i² / (Σ w_i/σ_i² + 1/σ_o²): r_i the sample's B minus B0 (and
  // any offset from outside) minus the track's predicted B; w_i the robust
  // loss's weight ρ′(‖e_i‖²) (1 without a loss). World NED, T.
  Eigen::Vector3d Mean(double prior_sigma_T) const;
  // The same under a prior of mean prior_mean_W (world NED, T) and σ
  // prior_sigma_T per axis: (Σ w_i r_i/σ_i² + m/σ²) / (Σ w_i/σ_i² + 1/σ²).
  Eigen::Vector3d Mean(const Eigen::Vector3d& prior_mean_W, double prior_sigma_T) const;
  // The robust score test of a zero offset: ‖Σ w_i r_i/σ_i²‖² / Σ w_i/σ_i²,
  // χ² with 3 dof under no offset (n ‖ē‖² of the whitened residuals where
  // every w is 1); false (nothing to test) without information.
  bool Score(double* chi2) const {
    if (!(information_ > 0.0)) return false;
    *chi2 = weighted_sum_.squaredNorm() / information_;
    return true;
  }
  // Σ w_i r_i/σ_i² (T⁻¹) and Σ w_i/σ_i² (T⁻²), for a joint solve of several.
  const Eigen::Vector3d& weighted_sum() const { return weighted_sum_; }
  double information() const { return information_; }

 private:
  Eigen::Vector3d weighted_sum_ = Eigen::Vector3d::Zero();  // T⁻¹
  double information_ = 0.0;                                // T⁻²
};

// Whether the score test (SumScores' χ² on dof) fires at the `quantile` point
// of χ² with dof degrees of freedom; never without a dof.
inline bool ScoreTestFires(double chi2, int dof, double quantile) {
  return dof > 0 && chi2 > ChiSquareQuantile(quantile, dof);
}

// The score test over several offsets (the batch's per (sensor, segment),
// the window's per sensor): the sum of their Score()s into *chi2 and 3 dof
// each into *dof; offsets without information are left out.
template <class AccumulatorMap>
void SumScores(const AccumulatorMap& accumulators, double* chi2, int* dof) {
  for (const auto& [key, a] : accumulators) {
    double c = 0.0;
    if (!a.Score(&c)) continue;
    *chi2 += c;
    *dof += 3;
  }
}

// The samples of one sensor over the window for an offset that is a line in
// time (SensorOffsetOptions::window_lines): o(t) = level + rate · (t − t_ref).
class LineOffsetAccumulator {
 public:
  // As SensorOffsetAccumulator::Add; dt_s = the sample's t − t_ref (s) and
  // own_W the line's value at that time now removed from its B.
  bool Add(const Factor& f, double sigma_B_T, const Eigen::Vector3d& own_W, double dt_s);
  // The level (T) and rate (T/s), world NED, minimising
  //   Σ w_i‖r_i − level − rate·dt_i‖²/σ_i² + ‖level‖²/σ_l² + ‖rate‖²/σ_r²
  // (σ_l level_sigma_T, σ_r rate_sigma_T_per_s). False if singular.
  bool Solve(double level_sigma_T, double rate_sigma_T_per_s, Eigen::Vector3d* level_W,
             Eigen::Vector3d* rate_W) const;

 private:
  Eigen::Matrix2d information_ = Eigen::Matrix2d::Zero();                  // [T⁻², T⁻² s; ·, T⁻² s²]
  Eigen::Matrix<double, 2, 3> weighted_sum_ = Eigen::Matrix<double, 2, 3>::Zero();  // [T⁻¹; T⁻¹ s]
};

// The track's predicted tensor SNR ‖T̂‖_F/σ_T at sample s (σ_T sigma_T_Tpm,
// T/m): the dipole at state x_state (x, y, z world NED m, …, heading rad at
// index 4) with body moment m_B_Am2 (A·m²). 0 if it cannot be evaluated.
double PredictedTensorSnr(const GradiometerSample& s, const double* x_state, const Eigen::Vector3d& m_B_Am2,
                          double sigma_T_Tpm);

// One sensor's offset carried between windows (SensorOffsetOptions::carry):
// what the samples that have left the window say of it, a Gaussian with the
// same variance on each axis, as of time t_s; between t_s and t it moves by
// a random walk of σ = rate·|t − t_s| (the drift bound).
struct CarriedOffset {
  Eigen::Vector3d mean_W = Eigen::Vector3d::Zero();  // world NED, T
  double variance_T2 = 0.0;                          // per axis, T²
  double t_s = 0.0;

  // The variance at time t (T²): variance_T2 + (rate_T_per_s·|t − t_s|)².
  double VarianceAt(double t, double rate_T_per_s) const;
  // The walk to t, then the Bayesian update with the samples of `a` (taken at t).
  void Update(const SensorOffsetAccumulator& a, double t, double rate_T_per_s);
};

// One sensor's offsets over consecutive segments o_0..o_{n−1} (world NED, T)
// joined by a random walk — per segment, each with its own zero-mean prior
// (the cluster background's SmoothOffsets, cluster_background.h, is a
// per-sample smoother from one prior) — the minimiser of
//   Σ_k [Σ_i∈k w_i‖r_i − o_k‖²/σ_i² + ‖o_k‖²/σ_k²] + Σ_k ‖o_{k+1} − o_k‖²/q²
// (segments[k]: segment k's accumulator, absent = no sample; prior_sigma_T[k]
// its prior σ_k; step_sigma_T = q, the most a drift moves between segments).
std::vector<Eigen::Vector3d> SegmentOffsets(const std::vector<const SensorOffsetAccumulator*>& segments,
                                           const std::vector<double>& prior_sigma_T, double step_sigma_T);

// A measurement factor with its sensor's offset as a parameter block (for the
// batch's covariance with the offsets marginalised: SolveBatch with
// SensorOffsetOptions::batch). The offset block is in nT (world NED; a
// Jacobian of order 1, as the states'), at o_at_nT when the base factor was
// set up with that offset (MeasurementCost::SetBackgroundOffset):
//   e = e_base(x, m) + L_B · (o − o_at) · 1e-9,
// L_B the first three columns of the base's square-root information.
class OffsetMeasurementCost final : public ceres::SizedCostFunction<8, 6, 3, 3> {
 public:
  OffsetMeasurementCost(const MeasurementCost* base, const Eigen::Vector3d& o_at_nT) : base_(base), o_at_nT_(o_at_nT) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  const MeasurementCost* base_;  // not owned
  Eigen::Vector3d o_at_nT_;
};

// The offsets' Gaussian priors in nT: one offset's zero-mean prior of σ
// sigma_nT per axis (blocks {o}), or the random walk between two consecutive
// segments of one sensor, (o₂ − o₁)/σ (blocks {o₁, o₂}).
class OffsetPriorCost final : public ceres::SizedCostFunction<3, 3> {
 public:
  explicit OffsetPriorCost(double sigma_nT) : w_(1.0 / sigma_nT) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  double w_;
};
class OffsetStepCost final : public ceres::SizedCostFunction<3, 3, 3> {
 public:
  explicit OffsetStepCost(double sigma_nT) : w_(1.0 / sigma_nT) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  double w_;
};

}  // namespace magnav::tracker::internal
