// FitDipoleMoment weighs B and T rows by their noise; when only one σ is
// known the answer must not depend on its units (before, a known σ_B of
// 1e-9 T met a weight |r| on the T rows: 1e9 against ~10, B alone decided).
#include <gtest/gtest.h>

#include "magnav/core/dipole.h"

namespace magnav {
namespace {

TEST(FitDipoleMoment, OneKnownSigmaDoesNotSwampTheOtherRows) {
  const Vec3 r(6.0, -3.0, 5.0), m(2000.0, 300.0, 800.0);
  Vec3 B;
  Mat3 T;
  DipoleBT(r, m, &B, &T);
  // B carries a bias of 1 % of its size; T is exact.
  const Vec3 B_biased = B + 0.01 * B.norm() * Vec3(1.0, -1.0, 0.5).normalized();
  Vec3 m_si, m_scaled, m_both;
  ASSERT_TRUE(FitDipoleMoment(r, B_biased, T, 1e-9, 0.0, &m_si));
  ASSERT_TRUE(FitDipoleMoment(r, B_biased, T, 1.0, 0.0, &m_scaled));
  EXPECT_LT((m_si - m_scaled).norm(), 1e-9 * m.norm());  // units of the known σ do not matter
  ASSERT_TRUE(FitDipoleMoment(r, B_biased, T, 1e-9, 1e-9 / r.norm(), &m_both));
  EXPECT_LT((m_si - m_both).norm(), 1e-9 * m.norm());  // the unknown σ_T taken as σ_B/|r|
  // The exact T rows pull the fit well inside the 1 % bias of B alone.
  Vec3 m_B_only;
  ASSERT_TRUE(FitDipoleMoment(r, B_biased, T, 1e-9, 1e6, &m_B_only));
  EXPECT_LT((m_si - m).norm(), 0.5 * (m_B_only - m).norm());
}

}  // namespace
}  // namespace magnav
