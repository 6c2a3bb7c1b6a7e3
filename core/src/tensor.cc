#include "magnav/core/tensor.h"

#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

namespace magnav {

Tensor5 PackTensor5(const Eigen::Matrix3d& T) {
  Tensor5 t;
  t << T(0, 0), T(0, 1), T(0, 2), T(1, 1), T(1, 2);
  return t;
}

Eigen::Matrix3d UnpackTensor5(const Tensor5& t) {
  Eigen::Matrix3d T;
  T << t[0], t[1], t[2],  //
      t[1], t[3], t[4],   //
      t[2], t[4], -t[0] - t[3];
  return T;
}

double RelativeAsymmetry(const Eigen::Matrix3d& T) {
  const double n = T.norm();
  return n > 0.0 ? (T - T.transpose()).norm() / n : 0.0;
}

double RelativeTrace(const Eigen::Matrix3d& T) {
  const double n = T.norm();
  return n > 0.0 ? std::abs(T.trace()) / n : 0.0;
}

int SortedEigen::SmallestMagnitudeIndex() const {
  int k = 0;
  for (int i = 1; i < 3; ++i) {
    if (std::abs(values[i]) < std::abs(values[k])) k = i;
  }
  return k;
}

double SortedEigen::ConditionNumber() const {
  const double lo = std::abs(values[SmallestMagnitudeIndex()]);
  const double hi = values.cwiseAbs().maxCoeff();
  if (lo == 0.0) return std::numeric_limits<double>::infinity();
  return hi / lo;
}

SortedEigen SortedEigenDecomposition(const Eigen::Matrix3d& T) {
  const Eigen::Matrix3d S = 0.5 * (T + T.transpose());
  // Scale to unit norm first: the closed-form 3×3 solver works in any units.
  const double s = S.norm();
  SortedEigen out;
  if (!(s > 0.0) || !std::isfinite(s)) {
    out.values.setZero();
    out.vectors.setIdentity();
    if (!std::isfinite(s)) out.values.setConstant(std::numeric_limits<double>::quiet_NaN());
    return out;
  }
  // The iterative solver is more accurate than computeDirect for nearly
  // degenerate eigenvalues (dipole axis cases), and still fast for 3×3.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(S / s);
  out.values = es.eigenvalues() * s;  // ascending
  out.vectors = es.eigenvectors();
  if (out.vectors.col(0).cross(out.vectors.col(1)).dot(out.vectors.col(2)) < 0.0) {
    out.vectors.col(2) = -out.vectors.col(2);
  }
  return out;
}

Eigen::Matrix3d TensorFromRowMajor(const std::array<double, 9>& t) {
  Eigen::Matrix3d T;
  T << t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8];
  return T;
}

std::array<double, 9> TensorToRowMajor(const Eigen::Matrix3d& T) {
  return {T(0, 0), T(0, 1), T(0, 2), T(1, 0), T(1, 1), T(1, 2), T(2, 0), T(2, 1), T(2, 2)};
}

}  // namespace magnav
