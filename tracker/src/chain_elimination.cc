// Block-tridiagonal elimination of the chain of states plus the shared
// moment: linearisation of the factors, the damped normal equations, the
// step, and the cost.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>

#include "factors.h"
#include "parallel.h"

namespace magnav::tracker::internal {

namespace {

// JᵀJ and Jᵀe of a two-block factor with fixed sizes (no heap, fixed-size
// products): M residuals, blocks of N0 and N1 parameters.
template <int M, int N0, int N1>
bool AccumulateFixed(const Factor& f, const LocalOffset& offset, LocalH* H, LocalG* g) {
  Eigen::Matrix<double, M, 1> e;
  Eigen::Matrix<double, M, N0, Eigen::RowMajor> J0;
  Eigen::Matrix<double, M, N1, (N1 == 1 ? Eigen::ColMajor : Eigen::RowMajor)> J1;
  double* jac[2] = {J0.data(), J1.data()};
  const double* params[2] = {f.blocks[0], f.blocks[1]};
  if (!f.cost->Evaluate(params, e.data(), jac)) return false;
  // A non-finite residual or Jacobian contributes nothing (never NaN into H).
  if (!e.allFinite() || !J0.allFinite() || !J1.allFinite()) return false;
  if (f.loss != nullptr) {
    double rho[3];
    f.loss->Evaluate(e.squaredNorm(), rho);
    const double w = std::sqrt(std::max(rho[1], 0.0));
    e *= w;
    J0 *= w;
    J1 *= w;
  }
  const int o0 = offset(f.blocks[0]), o1 = offset(f.blocks[1]);
  if (o0 >= 0) {
    H->block<N0, N0>(o0, o0) += J0.transpose().lazyProduct(J0);
    g->segment<N0>(o0).noalias() += J0.transpose().lazyProduct(e);
  }
  if (o1 >= 0) {
    H->block<N1, N1>(o1, o1) += J1.transpose().lazyProduct(J1);
    g->segment<N1>(o1).noalias() += J1.transpose().lazyProduct(e);
  }
  if (o0 >= 0 && o1 >= 0) {
    const Eigen::Matrix<double, N0, N1> X = J0.transpose().lazyProduct(J1);
    H->block<N0, N1>(o0, o1) += X;
    H->block<N1, N0>(o1, o0) += X.transpose();
  }
  return true;
}

}  // namespace

bool AccumulateFactor(const Factor& f, const LocalOffset& offset, LocalH* H,
                      LocalG* g) {
  const auto& sizes = f.cost->parameter_block_sizes();
  if (sizes.size() != 2 || f.blocks.size() != 2) return false;
  const int m = f.cost->num_residuals();
  if (sizes[0] == 6 && sizes[1] == 3 && m == 8) return AccumulateFixed<8, 6, 3>(f, offset, H, g);
  if (sizes[0] == 6 && sizes[1] == 3 && m == 9) return AccumulateFixed<9, 6, 3>(f, offset, H, g);
  if (sizes[0] == 6 && sizes[1] == 6 && m == 5) return AccumulateFixed<5, 6, 6>(f, offset, H, g);
  if (sizes[0] == 6 && sizes[1] == 6 && m == 1) return AccumulateFixed<1, 6, 6>(f, offset, H, g);
  return false;  // not a tracker factor shape
}

namespace {

// Inverse of a symmetric positive-definite 6×6 matrix A = LLᵀ (and L⁻¹) by
// Cholesky with fixed-size loops (Eigen's LLT::solve takes its dynamic-size triangular
// path for a matrix right-hand side, a third of the chain elimination's
// time). False if A is not positive definite.
bool InvertSpd6(const StateCovariance& A, StateCovariance* A_inv, StateCovariance* L_inv_out) {
  StateCovariance L = StateCovariance::Zero();
  for (int j = 0; j < 6; ++j) {
    double d = A(j, j);
    for (int p = 0; p < j; ++p) d -= L(j, p) * L(j, p);
    if (!(d > 0.0)) return false;
    L(j, j) = std::sqrt(d);
    for (int i = j + 1; i < 6; ++i) {
      double v = A(i, j);
      for (int p = 0; p < j; ++p) v -= L(i, p) * L(j, p);
      L(i, j) = v / L(j, j);
    }
  }
  StateCovariance& L_inv = *L_inv_out;  // lower triangular
  L_inv.setZero();
  for (int j = 0; j < 6; ++j) {
    L_inv(j, j) = 1.0 / L(j, j);
    for (int i = j + 1; i < 6; ++i) {
      double v = 0.0;
      for (int p = j; p < i; ++p) v -= L(i, p) * L_inv(p, j);
      L_inv(i, j) = v / L(i, i);
    }
  }
  *A_inv = L_inv.transpose().lazyProduct(L_inv);
  return A_inv->allFinite();
}

}  // namespace
namespace {

// ½ ρ(‖e‖²) of one factor; +∞ if it cannot be evaluated.
double FactorCost(const Factor& f) {
  // Tracker factors have two blocks and at most 9 residuals.
  const int m = f.cost->num_residuals();
  if (m > 9 || f.blocks.size() != 2) return std::numeric_limits<double>::infinity();
  Eigen::Matrix<double, 9, 1> e = Eigen::Matrix<double, 9, 1>::Zero();
  const double* params[2] = {f.blocks[0], f.blocks[1]};
  if (!f.cost->Evaluate(params, e.data(), nullptr)) return std::numeric_limits<double>::infinity();
  double rho[3] = {e.squaredNorm(), 1.0, 0.0};
  if (f.loss != nullptr) f.loss->Evaluate(e.squaredNorm(), rho);
  return 0.5 * rho[0];
}

}  // namespace

bool LinearizeChain(const ChainProblem& chain, ChainLinearization* out, int num_threads) {
  const std::size_t n = chain.states.size();
  if (n == 0 || chain.groups.size() != n) return false;
  out->H.resize(n);
  out->g.resize(n);
  return ParallelFor(n, num_threads, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      const LocalOffset offset{chain.states[k], k + 1 < n ? chain.states[k + 1] : nullptr, chain.moment};
      LocalH& H = out->H[k];
      LocalG& g = out->g[k];
      H.setZero();
      g.setZero();
      for (const Factor* f : chain.groups[k]) {
        if (!AccumulateFactor(*f, offset, &H, &g)) return false;
      }
    }
    return true;
  });
}

bool EliminateChain(const ChainLinearization& lin, double lambda, ChainFactorization* out) {
  const std::size_t n = lin.H.size();
  if (n == 0 || lin.g.size() != n) return false;
  const auto damping = [lambda](const auto& diagonal) {
    return (lambda * diagonal.array().max(1e-6).min(1e32)).matrix().eval();
  };
  using Mat99 = Eigen::Matrix<double, 9, 9>;
  out->D_inv.resize(n);
  out->C.resize(n);
  out->g.resize(n);
  Mat99 carried = Mat99::Zero();  // information on (x_k, m) from eliminated states
  Eigen::Matrix<double, 9, 1> carried_g = Eigen::Matrix<double, 9, 1>::Zero();
  StateVector diag_next = StateVector::Zero();  // undamped diag(H) of x_k from group k−1
  Eigen::Vector3d diag_m = Eigen::Vector3d::Zero();
  StateCovariance L_inv;
  for (std::size_t k = 0; k < n; ++k) {
    // Blocks of group k over [x_k; x_{k+1}; m], plus what the eliminated
    // states carried onto (x_k, m): D (x_k), C (x_k with (x_{k+1}, m)), B.
    const LocalH& H = lin.H[k];
    const LocalG& g = lin.g[k];
    StateCovariance D = H.topLeftCorner<6, 6>() + carried.topLeftCorner<6, 6>();
    diag_m += H.diagonal().tail<3>();
    if (lambda > 0.0) {
      D.diagonal() += damping((H.diagonal().head<6>() + diag_next).eval());
      diag_next = H.diagonal().segment<6>(6);
    }
    Mat69& C = out->C[k];
    C.leftCols<6>() = H.block<6, 6>(0, 6);
    C.rightCols<3>() = H.block<6, 3>(0, 12) + carried.topRightCorner<6, 3>();
    out->g[k] = g.head<6>() + carried_g.head<6>();
    if (!InvertSpd6(D, &out->D_inv[k], &L_inv)) return false;
    // Schur complement B − Cᵀ D⁻¹ C = B − WᵀW with W = L⁻¹ C (symmetric by
    // construction); lazyProduct: coefficient-based kernels for small sizes.
    const Mat69 W = L_inv.lazyProduct(C);
    const Eigen::Matrix<double, 6, 1> w = L_inv.lazyProduct(out->g[k]);
    const Eigen::Matrix3d carried_mm = carried.bottomRightCorner<3, 3>();
    const Eigen::Vector3d carried_gm = carried_g.tail<3>();
    carried = H.bottomRightCorner<9, 9>();
    carried.bottomRightCorner<3, 3>() += carried_mm;
    carried.noalias() -= W.transpose().lazyProduct(W);
    carried_g = g.tail<9>();
    carried_g.tail<3>() += carried_gm;
    carried_g.noalias() -= W.transpose().lazyProduct(w);
  }
  // After the last state only the moment part of `carried` is meaningful.
  out->S = carried.bottomRightCorner<3, 3>();
  if (lambda > 0.0) out->S.diagonal() += damping(diag_m);
  out->g_m = carried_g.tail<3>();
  return out->S.allFinite() && Eigen::LLT<Eigen::Matrix3d>(out->S).info() == Eigen::Success;
}

bool FactorizeChain(const ChainProblem& chain, ChainFactorization* out, int num_threads) {
  ChainLinearization lin;
  return LinearizeChain(chain, &lin, num_threads) && EliminateChain(lin, 0.0, out);
}

void ChainStep(const ChainFactorization& f, std::vector<StateVector>* dx, Eigen::Vector3d* dm) {
  const std::size_t n = f.D_inv.size();
  *dm = -Eigen::LLT<Eigen::Matrix3d>(f.S).solve(f.g_m);
  dx->assign(n, StateVector::Zero());
  Eigen::Matrix<double, 9, 1> y;  // (Δx_{k+1}, Δm)
  y << StateVector::Zero(), *dm;
  for (std::size_t k = n; k-- > 0;) {
    (*dx)[k] = -f.D_inv[k].lazyProduct((f.g[k] + f.C[k].lazyProduct(y)).eval());
    y.head<6>() = (*dx)[k];
  }
}

double TotalCost(const std::vector<std::vector<const Factor*>>& groups, int num_threads) {
  std::vector<double> partial(NumChunks(groups.size(), num_threads), 0.0);
  ParallelFor(groups.size(), num_threads, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      for (const Factor* f : groups[k]) partial[chunk] += FactorCost(*f);
    }
    return true;
  });
  double cost = 0.0;
  for (double c : partial) cost += c;  // fixed order: the same sum on every run
  return cost;
}

}  // namespace magnav::tracker::internal
