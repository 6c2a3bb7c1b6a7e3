// Gradient tensor utilities. A magnetic gradient tensor T (T/m) in a source-free
// region is symmetric (curl-free) and trace-free (divergence-free): five
// numbers define it. magnav packs them as t5 = [Txx, Txy, Txz, Tyy, Tyz]
// (the paper's measurement vector), Tzz = −Txx − Tyy.
#pragma once

#include <array>

#include <Eigen/Dense>

namespace magnav {

using Tensor5 = Eigen::Matrix<double, 5, 1>;

Tensor5 PackTensor5(const Eigen::Matrix3d& T);
Eigen::Matrix3d UnpackTensor5(const Tensor5& t5);

// ‖T − Tᵀ‖_F / ‖T‖_F (0 for T = 0).
double RelativeAsymmetry(const Eigen::Matrix3d& T);
// |tr T| / ‖T‖_F (0 for T = 0).
double RelativeTrace(const Eigen::Matrix3d& T);

// Eigen-decomposition of the symmetric part of T, eigenvalues ascending
// (λ0 ≤ λ1 ≤ λ2), unit eigenvectors in the matching columns of `vectors`
// (right-handed: v2 = v0 × v1).
struct SortedEigen {
  Eigen::Vector3d values;
  Eigen::Matrix3d vectors;
  // Index of the eigenvalue of smallest magnitude (for a dipole tensor it is
  // the middle one, M·n, whose eigenvector is normal to the plane of m and r).
  int SmallestMagnitudeIndex() const;
  // |λ|max / |λ|min (infinity when the smallest magnitude is 0).
  double ConditionNumber() const;
};
SortedEigen SortedEigenDecomposition(const Eigen::Matrix3d& T);

// Row-major 9-array <-> matrix (the order of files and DDS messages).
Eigen::Matrix3d TensorFromRowMajor(const std::array<double, 9>& t);
std::array<double, 9> TensorToRowMajor(const Eigen::Matrix3d& T);

}  // namespace magnav
