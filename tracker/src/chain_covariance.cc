// Marginal covariances of every state and of the moment by selected
// inversion of the chain's factorisation (exact, O(N)).
#include <Eigen/Cholesky>

#include "factors.h"

namespace magnav::tracker::internal {

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

bool ChainSolve(const ChainFactorization& f, const Eigen::MatrixXd& R, Eigen::MatrixXd* Z) {
  const std::size_t n = f.D_inv.size();
  const Eigen::Index rows = static_cast<Eigen::Index>(6 * n + 3), q = R.cols();
  if (R.rows() != rows || f.C.size() != n) return false;
  // Forward: r_k = R_k + c_k (c_k what the eliminated x_{k−1} carried onto
  // x_k); x_k carries −C_kᵀ D_k⁻¹ r_k onto (x_{k+1}, m).
  Eigen::MatrixXd reduced = R;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Index i = static_cast<Eigen::Index>(6 * k);
    const Eigen::MatrixXd carried = f.C[k].transpose() * (f.D_inv[k] * reduced.middleRows(i, 6));  // 9 × q
    if (k + 1 < n) reduced.middleRows(i + 6, 6) -= carried.topRows(6);
    reduced.bottomRows(3) -= carried.bottomRows(3);
  }
  // The moment, then back substitution z_k = D_k⁻¹ (r_k − C_k [z_{k+1}; z_m]).
  Z->resize(rows, q);
  Z->bottomRows(3) = Eigen::LLT<Eigen::Matrix3d>(f.S).solve(reduced.bottomRows(3));
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(9, q);  // [z_{k+1}; z_m]
  y.bottomRows(3) = Z->bottomRows(3);
  for (std::size_t k = n; k-- > 0;) {
    const Eigen::Index i = static_cast<Eigen::Index>(6 * k);
    Z->middleRows(i, 6) = f.D_inv[k] * (reduced.middleRows(i, 6) - f.C[k] * y);
    y.topRows(6) = Z->middleRows(i, 6);
  }
  return Z->allFinite();
}

bool ChainCovariance(const ChainProblem& chain, std::vector<StateCovariance>* P_x, Eigen::Matrix3d* P_m) {
  ChainFactorization f;
  return FactorizeChain(chain, &f) && ChainCovariance(f, P_x, P_m);
}

}  // namespace magnav::tracker::internal
