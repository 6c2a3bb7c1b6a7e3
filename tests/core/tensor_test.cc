#include "magnav/core/tensor.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "magnav/core/dipole.h"

namespace magnav {
namespace {

TEST(Tensor5, PackUnpackRoundTripsTraceFreeSymmetric) {
  const Mat3 T = DipoleT(Vec3(3, -2, 6), Vec3(10, 40, -30));
  const Tensor5 t = PackTensor5(T);
  EXPECT_DOUBLE_EQ(t[0], T(0, 0));
  EXPECT_DOUBLE_EQ(t[1], T(0, 1));
  EXPECT_DOUBLE_EQ(t[2], T(0, 2));
  EXPECT_DOUBLE_EQ(t[3], T(1, 1));
  EXPECT_DOUBLE_EQ(t[4], T(1, 2));
  EXPECT_LT((UnpackTensor5(t) - T).norm(), 1e-15 * T.norm());
}

TEST(Tensor, AsymmetryAndTraceMeasures) {
  Mat3 T = Mat3::Zero();
  EXPECT_EQ(RelativeAsymmetry(T), 0.0);
  EXPECT_EQ(RelativeTrace(T), 0.0);
  T << 1, 2, 0, 0, -1, 0, 0, 0, 0;  // asymmetric, trace-free
  EXPECT_NEAR(RelativeAsymmetry(T), std::sqrt(8.0) / std::sqrt(6.0), 1e-15);
  EXPECT_EQ(RelativeTrace(T), 0.0);
  EXPECT_NEAR(RelativeTrace(Mat3::Identity()), std::sqrt(3.0), 1e-15);
}

TEST(SortedEigen, DipoleTensorMiddleEigenvalueIsNormalToMomentAndOffset) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n01;
  for (int k = 0; k < 500; ++k) {
    const Vec3 r(n01(rng) * 20, n01(rng) * 20, n01(rng) * 20);
    const Vec3 m(n01(rng) * 1e3, n01(rng) * 1e3, n01(rng) * 1e3);
    const Mat3 T = DipoleT(r, m);
    const SortedEigen e = SortedEigenDecomposition(T);
    EXPECT_LE(e.values[0], e.values[1]);
    EXPECT_LE(e.values[1], e.values[2]);
    EXPECT_EQ(e.SmallestMagnitudeIndex(), 1);
    // The eigenvalue of smallest magnitude is M·n = 3k (m·r)/r⁵ and its
    // eigenvector is ±(m × r)/|m × r|.
    const double expected = 3e-7 * m.dot(r) / std::pow(r.norm(), 5);
    EXPECT_NEAR(e.values[1], expected, 1e-9 * e.values.cwiseAbs().maxCoeff());
    const Vec3 n = m.cross(r).normalized();
    EXPECT_NEAR(std::abs(e.vectors.col(1).dot(n)), 1.0, 1e-8);
    // Reconstruction and orthonormality.
    EXPECT_LT((e.vectors * e.values.asDiagonal() * e.vectors.transpose() - T).norm(), 1e-12 * T.norm());
    EXPECT_NEAR(e.vectors.determinant(), 1.0, 1e-12);
  }
}

TEST(SortedEigen, ConditionNumberAndDegenerateInput) {
  Mat3 T = Mat3::Zero();
  T.diagonal() << -2, 1, 1;
  EXPECT_NEAR(SortedEigenDecomposition(T).ConditionNumber(), 2.0, 1e-12);
  T.diagonal() << -1, 0, 1;
  EXPECT_TRUE(std::isinf(SortedEigenDecomposition(T).ConditionNumber()));
  EXPECT_TRUE(std::isinf(SortedEigenDecomposition(Mat3::Zero()).ConditionNumber()));
  Mat3 bad = Mat3::Identity();
  bad(0, 1) = std::nan("");
  EXPECT_TRUE(std::isnan(SortedEigenDecomposition(bad).values[0]));
}

TEST(Tensor, RowMajorRoundTrip) {
  std::array<double, 9> a{1, 2, 3, 4, 5, 6, 7, 8, 9};
  const Mat3 T = TensorFromRowMajor(a);
  EXPECT_EQ(T(0, 1), 2);
  EXPECT_EQ(T(1, 0), 4);
  EXPECT_EQ(TensorToRowMajor(T), a);
}

}  // namespace
}  // namespace magnav
