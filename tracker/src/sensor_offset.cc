#include "sensor_offset.h"

#include <cmath>

#include <Eigen/Dense>

#include "magnav/core/dipole.h"
#include "magnav/core/frames.h"
#include "magnav/tracker/cost_functions.h"

namespace magnav::tracker::internal {

bool SensorOffsetAccumulator::Add(const Factor& f, double sigma_B_T, const Eigen::Vector3d& own_W) {
  const auto* cost = dynamic_cast<const MeasurementCost*>(f.cost.get());
  if (cost == nullptr || f.blocks.size() != 2 || !(sigma_B_T > 0.0)) return false;
  const double* parameters[2] = {f.blocks[0], f.blocks[1]};
  Eigen::Matrix<double, 8, 1> e;
  if (!cost->Evaluate(parameters, e.data(), nullptr) || !e.allFinite()) return false;
  double w = 1.0;
  if (f.loss != nullptr) {
    double rho[3];
    f.loss->Evaluate(e.squaredNorm(), rho);
    w = rho[1];
  }
  const Eigen::Vector3d r = cost->BResidual(parameters) + own_W;
  if (!r.allFinite() || !(w >= 0.0)) return false;
  const double inv_var = 1.0 / (sigma_B_T * sigma_B_T);
  weighted_sum_ += w * inv_var * r;
  information_ += w * inv_var;
  return true;
}

Eigen::Vector3d SensorOffsetAccumulator::Mean(double prior_sigma_T) const {
  const double prior_information = 1.0 / (prior_sigma_T * prior_sigma_T);
  return weighted_sum_ / (information_ + prior_information);
}

Eigen::Vector3d SensorOffsetAccumulator::Mean(const Eigen::Vector3d& prior_mean_W, double prior_sigma_T) const {
  const double prior_information = 1.0 / (prior_sigma_T * prior_sigma_T);
  return (weighted_sum_ + prior_information * prior_mean_W) / (information_ + prior_information);
}

bool LineOffsetAccumulator::Add(const Factor& f, double sigma_B_T, const Eigen::Vector3d& own_W, double dt_s) {
  SensorOffsetAccumulator one;
  if (!one.Add(f, sigma_B_T, own_W) || !std::isfinite(dt_s)) return false;
  const double info = one.information();  // w/σ²
  const Eigen::Vector3d sum = one.weighted_sum();  // w r/σ²
  const Eigen::Vector2d h(1.0, dt_s);
  information_ += info * h * h.transpose();
  weighted_sum_ += h * sum.transpose();
  return true;
}

bool LineOffsetAccumulator::Solve(double level_sigma_T, double rate_sigma_T_per_s, Eigen::Vector3d* level_W,
                                  Eigen::Vector3d* rate_W) const {
  Eigen::Matrix2d A = information_;
  A(0, 0) += 1.0 / (level_sigma_T * level_sigma_T);
  A(1, 1) += 1.0 / (rate_sigma_T_per_s * rate_sigma_T_per_s);
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(A);
  if (ldlt.info() != Eigen::Success) return false;
  const Eigen::Matrix<double, 2, 3> x = ldlt.solve(weighted_sum_);
  if (!x.allFinite()) return false;
  *level_W = x.row(0).transpose();
  *rate_W = x.row(1).transpose();
  return true;
}

double PredictedTensorSnr(const GradiometerSample& s, const double* x_state, const Eigen::Vector3d& m_B_Am2,
                          double sigma_T_Tpm) {
  const Eigen::Vector3d r_DtoS = s.p_SinW - Eigen::Vector3d(x_state[0], x_state[1], x_state[2]);
  if (!(r_DtoS.norm() > 0.0) || !(sigma_T_Tpm > 0.0)) return 0.0;
  const Eigen::Vector3d m_W = HeadingRotation(x_state[4]) * m_B_Am2;
  const double snr = DipoleT(r_DtoS, m_W).norm() / sigma_T_Tpm;
  return std::isfinite(snr) ? snr : 0.0;
}

double CarriedOffset::VarianceAt(double t, double rate_T_per_s) const {
  const double walk = rate_T_per_s * std::abs(t - t_s);
  return variance_T2 + walk * walk;
}

void CarriedOffset::Update(const SensorOffsetAccumulator& a, double t, double rate_T_per_s) {
  const double prior_information = 1.0 / VarianceAt(t, rate_T_per_s);
  const double information = a.information() + prior_information;
  mean_W = (a.weighted_sum() + prior_information * mean_W) / information;
  variance_T2 = 1.0 / information;
  t_s = t;
}

std::vector<Eigen::Vector3d> SegmentOffsets(const std::vector<const SensorOffsetAccumulator*>& segments,
                                           const std::vector<double>& prior_sigma_T, double step_sigma_T) {
  const int n = static_cast<int>(segments.size());
  // Normal equations, the same for the three axes: A o = b (A tridiagonal,
  // solved densely: a pass has tens of segments per sensor).
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n, 3);
  const double step_information = 1.0 / (step_sigma_T * step_sigma_T);
  for (int k = 0; k < n; ++k) {
    A(k, k) += 1.0 / (prior_sigma_T[k] * prior_sigma_T[k]);
    if (segments[k] != nullptr) {
      A(k, k) += segments[k]->information();
      b.row(k) = segments[k]->weighted_sum().transpose();
    }
    if (k + 1 < n) {
      A(k, k) += step_information;
      A(k + 1, k + 1) += step_information;
      A(k, k + 1) -= step_information;
      A(k + 1, k) -= step_information;
    }
  }
  const Eigen::MatrixXd o = A.ldlt().solve(b);
  std::vector<Eigen::Vector3d> out(n);
  for (int k = 0; k < n; ++k) out[k] = o.row(k).transpose();
  return out;
}

bool OffsetMeasurementCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  double* base_jacobians[2] = {jacobians != nullptr ? jacobians[0] : nullptr,
                               jacobians != nullptr ? jacobians[1] : nullptr};
  if (!base_->Evaluate(parameters, residuals, jacobians != nullptr ? base_jacobians : nullptr)) return false;
  const Eigen::Matrix<double, 8, 3> L_B = base_->sqrt_info().leftCols<3>() * 1e-9;
  Eigen::Map<Eigen::Matrix<double, 8, 1>> e(residuals);
  e += L_B * (Eigen::Map<const Eigen::Vector3d>(parameters[2]) - o_at_nT_);
  if (jacobians != nullptr && jacobians[2] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 8, 3, Eigen::RowMajor>> J(jacobians[2]);
    J = L_B;
  }
  return true;
}

bool OffsetPriorCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  Eigen::Map<Eigen::Vector3d> r(residuals);
  r = w_ * Eigen::Map<const Eigen::Vector3d>(parameters[0]);
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> J(jacobians[0]);
    J = w_ * Eigen::Matrix3d::Identity();
  }
  return true;
}

bool OffsetStepCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  Eigen::Map<Eigen::Vector3d> r(residuals);
  r = w_ * (Eigen::Map<const Eigen::Vector3d>(parameters[1]) - Eigen::Map<const Eigen::Vector3d>(parameters[0]));
  if (jacobians != nullptr) {
    for (int b = 0; b < 2; ++b) {
      if (jacobians[b] == nullptr) continue;
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> J(jacobians[b]);
      J = (b == 0 ? -w_ : w_) * Eigen::Matrix3d::Identity();
    }
  }
  return true;
}

}  // namespace magnav::tracker::internal
