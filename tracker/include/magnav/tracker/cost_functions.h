// Cost functions of the tracker. Every residual is whitened (units of σ).
//
// Parameter blocks:
//   state  (6): [x, y, z (m, world NED), v (m/s), h (rad), ω (rad/s)] of one epoch
//   moment (3): m_B / moment_scale, the body moment in units of moment_scale
//               (A·m²), so that its entries are O(1) like the other parameters.
#pragma once

#include <ceres/autodiff_cost_function.h>
#include <ceres/sized_cost_function.h>

#include <Eigen/Core>
#include <cmath>

#include "magnav/core/dipole.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/motion.h"

namespace magnav::tracker {

using SqrtInfo8 = Eigen::Matrix<double, 8, 8>;

// Square-root information (8×8, upper triangular) of one gradiometer
// measurement [B (3); Txx, Txy, Txz, Tyy, Tyz]. B: σ_B I. Tensor: σ_T per
// element; with trace_free the diagonal pair (Txx, Tyy) has correlation −1/2
// (noise of the three diagonal elements sums to zero).
SqrtInfo8 MeasurementSqrtInfo(double sigma_B_T, double sigma_T_Tpm, bool trace_free);

// Measurement residual of one gradiometer sample.
//
//   m_W = Rz(h) · s · m̃          (s = moment_scale, m̃ the moment block)
//   r   = p_S − p_V              (dipole → sensor)
//   e   = L [h_BT(r, m_W) − z],  z = [B − B0; T5]
//
// with h_BT the dipole model (DipoleMeasurement) and L the square-root
// information. Analytic Jacobians by the chain rule:
//   ∂e/∂p_V = −L J_z_r,   ∂e/∂h = L J_z_m ∂m_W/∂h,   ∂e/∂m̃ = s L J_z_m Rz(h);
// the columns of v and ω are zero.
class MeasurementCost final : public ceres::SizedCostFunction<8, 6, 3> {
 public:
  MeasurementCost(const GradiometerSample& sample, const Eigen::Vector3d& B0_W, const SqrtInfo8& sqrt_info,
                  double moment_scale_Am2);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;
  // The sensor's background offset (world NED, T) added to B0 in this
  // factor's B (cluster_background.h); zero at construction.
  void SetBackgroundOffset(const Eigen::Vector3d& offset_W) { z_.head<3>() = B_minus_B0_ - offset_W; }
  // The B part of the residual at the parameters, unwhitened: the sample's B
  // minus B0 and the offset, minus the dipole's predicted B (world NED, T).
  Eigen::Vector3d BResidual(double const* const* parameters) const;
  const SqrtInfo8& sqrt_info() const { return sqrt_info_; }
  // Whether the B rows are in the residual (true at construction). Off, the
  // B rows' residuals and Jacobians are zero: the factor carries the tensor's
  // information alone (B and tensor noise are independent, so the rows split).
  void SetFieldUsed(bool used) { field_used_ = used; }

 private:
  Eigen::Vector3d p_SinW_;
  Eigen::Vector3d B_minus_B0_;
  Measurement8 z_;
  SqrtInfo8 sqrt_info_;
  double moment_scale_;
  bool field_used_ = true;
};

// Kinematic process residual between consecutive epochs. KinematicCost is
// the analytic one the tracker uses (CoordinatedTurnJacobian of core/motion.h);
// KinematicResidual is the same residual as a templated functor, kept for
// automatic differentiation (the tests compare the two).
//
//   x̂_{k+1} = PropagateCoordinatedTurn(x_k, dt)
//   e = [(p_{k+1} − p̂)/σ_p, (v_{k+1} − v_k)/σ_v, (h_{k+1} − ĥ)/σ_h] / √dt
//
// (5 residuals; σ in units per √s; KinematicCost may give z its own σ,
// ProcessNoise::depth_m_per_sqrt_s.) The turn rate has its own residual so it
// can carry its own robust loss.
struct KinematicResidual {
  KinematicResidual(double dt_s, double sigma_p, double sigma_v, double sigma_h)
      : dt(dt_s),
        w_p(1.0 / (sigma_p * std::sqrt(dt_s))),
        w_v(1.0 / (sigma_v * std::sqrt(dt_s))),
        w_h(1.0 / (sigma_h * std::sqrt(dt_s))) {}

  template <typename T>
  bool operator()(const T* s0, const T* s1, T* e) const {
    const CtState<T> a{s0[0], s0[1], s0[2], s0[3], s0[4], s0[5]};
    const CtState<T> p = PropagateCoordinatedTurn(a, dt);
    e[0] = (s1[0] - p.x) * w_p;
    e[1] = (s1[1] - p.y) * w_p;
    e[2] = (s1[2] - p.z) * w_p;
    e[3] = (s1[3] - s0[3]) * w_v;
    e[4] = (s1[4] - p.heading) * w_h;
    return true;
  }

  static ceres::CostFunction* Create(double dt_s, double sigma_p, double sigma_v, double sigma_h) {
    return new ceres::AutoDiffCostFunction<KinematicResidual, 5, 6, 6>(
        new KinematicResidual(dt_s, sigma_p, sigma_v, sigma_h));
  }

  double dt, w_p, w_v, w_h;
};

class KinematicCost final : public ceres::SizedCostFunction<5, 6, 6> {
 public:
  // σ_p for x and y, sigma_depth for z.
  KinematicCost(double dt_s, double sigma_p, double sigma_v, double sigma_h, double sigma_depth);
  // The same σ_p for z.
  KinematicCost(double dt_s, double sigma_p, double sigma_v, double sigma_h)
      : KinematicCost(dt_s, sigma_p, sigma_v, sigma_h, sigma_p) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  double dt_;
  Eigen::Matrix<double, 5, 1> w_;  // 1/(σ √dt) per residual
};

// Turn-rate random walk: e = (ω_{k+1} − ω_k) / (σ_ω √dt). Linear, analytic.
class TurnRateCost final : public ceres::SizedCostFunction<1, 6, 6> {
 public:
  TurnRateCost(double dt_s, double sigma_w) : w_(1.0 / (sigma_w * std::sqrt(dt_s))) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  double w_;
};

// Gaussian prior on [state (6); moment block (3)] from marginalised epochs:
//   e = L (x − x̄) + c
// with LᵀL the marginal information and c = L⁻ᵀ g its gradient term (so that
// ½‖e‖² equals the linearised marginalised cost up to a constant).
class PriorCost final : public ceres::SizedCostFunction<9, 6, 3> {
 public:
  PriorCost(const Eigen::Matrix<double, 9, 9>& L, const Eigen::Matrix<double, 9, 1>& x_bar,
            const Eigen::Matrix<double, 9, 1>& c)
      : L_(L), x_bar_(x_bar), c_(c) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;
  const Eigen::Matrix<double, 9, 9>& L() const { return L_; }
  const Eigen::Matrix<double, 9, 1>& x_bar() const { return x_bar_; }
  const Eigen::Matrix<double, 9, 1>& c() const { return c_; }

 private:
  Eigen::Matrix<double, 9, 9> L_;
  Eigen::Matrix<double, 9, 1> x_bar_, c_;
};

}  // namespace magnav::tracker
