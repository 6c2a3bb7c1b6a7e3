#include "offset_marginal.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "magnav/tracker/cost_functions.h"

namespace magnav::tracker::internal {

namespace {

constexpr double kNano = 1e-9;  // T per nT: the offsets' unit here

}  // namespace

OffsetLineMarginal::OffsetLineMarginal(std::size_t num_states, const std::vector<std::uint32_t>& sensors)
    : num_states_(num_states) {
  for (std::uint32_t id : sensors) {
    if (column_.count(id) == 0) column_.emplace(id, static_cast<Eigen::Index>(6 * column_.size()));
  }
  const Eigen::Index q = static_cast<Eigen::Index>(6 * column_.size());
  B_ = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(6 * num_states + 3), q);
  D_ = Eigen::MatrixXd::Zero(q, q);
}

bool OffsetLineMarginal::Add(const Factor& f, std::size_t k, std::uint32_t sensor_id, double sigma_B_T,
                             double dt_s) {
  const auto it = column_.find(sensor_id);
  const auto* cost = dynamic_cast<const MeasurementCost*>(f.cost.get());
  if (it == column_.end() || cost == nullptr || k >= num_states_ || f.blocks.size() != 2 || !(sigma_B_T > 0.0) ||
      !std::isfinite(dt_s))
    return false;
  Eigen::Matrix<double, 8, 1> e;
  Eigen::Matrix<double, 8, 6, Eigen::RowMajor> J_x;
  Eigen::Matrix<double, 8, 3, Eigen::RowMajor> J_m;
  double* jac[2] = {J_x.data(), J_m.data()};
  const double* params[2] = {f.blocks[0], f.blocks[1]};
  if (!cost->Evaluate(params, e.data(), jac) || !e.allFinite() || !J_x.allFinite() || !J_m.allFinite()) return false;
  double w = 1.0;  // ρ′, as AccumulateFactor's √ρ′ on both Jacobians
  if (f.loss != nullptr) {
    double rho[3];
    f.loss->Evaluate(e.squaredNorm(), rho);
    w = std::max(rho[1], 0.0);
  }
  // J_o = [I; 0]·s on the B rows, s = 1e-9/σ_B per nT of level, dt·s per nT/s of rate.
  const double s = kNano / sigma_B_T;
  const Eigen::Index c = it->second;
  const Eigen::Index i = static_cast<Eigen::Index>(6 * k), im = static_cast<Eigen::Index>(6 * num_states_);
  const Eigen::Matrix<double, 6, 3> Bx = w * s * J_x.topRows<3>().transpose();
  const Eigen::Matrix3d Bm = w * s * J_m.topRows<3>().transpose();
  B_.block<6, 3>(i, c) += Bx;
  B_.block<6, 3>(i, c + 3) += dt_s * Bx;
  B_.block<3, 3>(im, c) += Bm;
  B_.block<3, 3>(im, c + 3) += dt_s * Bm;
  const double d = w * s * s;
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  D_.block<3, 3>(c, c) += d * I;
  D_.block<3, 3>(c, c + 3) += d * dt_s * I;
  D_.block<3, 3>(c + 3, c) += d * dt_s * I;
  D_.block<3, 3>(c + 3, c + 3) += d * dt_s * dt_s * I;
  return true;
}

void OffsetLineMarginal::AddPriors(double level_sigma_T, double rate_sigma_T_per_s) {
  const double level = kNano / level_sigma_T, rate = kNano / rate_sigma_T_per_s;
  for (const auto& [id, c] : column_) {
    D_.diagonal().segment<3>(c).array() += level * level;
    D_.diagonal().segment<3>(c + 3).array() += rate * rate;
  }
}

bool OffsetLineMarginal::Marginalize(const ChainFactorization& f, std::vector<StateCovariance>* P_x,
                                     Eigen::Matrix3d* P_m) const {
  if (column_.empty()) return true;
  if (f.D_inv.size() != num_states_ || P_x->size() != num_states_) return false;
  Eigen::MatrixXd Z;
  if (!ChainSolve(f, B_, &Z)) return false;
  Eigen::MatrixXd S = D_ - B_.transpose() * Z;
  S = 0.5 * (S + S.transpose()).eval();
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) return false;
  // Z S⁻¹ Zᵀ = Wᵀ W with W = L⁻¹ Zᵀ (S = L Lᵀ): symmetric by construction.
  const Eigen::MatrixXd W = llt.matrixL().solve(Z.transpose());
  if (!W.allFinite()) return false;
  for (std::size_t k = 0; k < num_states_; ++k) {
    const auto Wk = W.middleCols(static_cast<Eigen::Index>(6 * k), 6);
    (*P_x)[k] += Wk.transpose() * Wk;
  }
  const auto Wm = W.rightCols(3);
  *P_m += Wm.transpose() * Wm;
  return true;
}

}  // namespace magnav::tracker::internal
