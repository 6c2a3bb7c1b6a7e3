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

bool ChainCovariance(const ChainProblem& chain, std::vector<StateCovariance>* P_x, Eigen::Matrix3d* P_m) {
  ChainFactorization f;
  return FactorizeChain(chain, &f) && ChainCovariance(f, P_x, P_m);
}

}  // namespace magnav::tracker::internal
