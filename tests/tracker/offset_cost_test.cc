// The batch's sensor-offset factors for its marginal covariance
// (tracker/src/sensor_offset.h): OffsetMeasurementCost is its base
// MeasurementCost with the offset as a parameter block (nT): at o = o_at the
// same residuals and Jacobians, the offset's Jacobian the exact derivative
// (the model is linear in it); OffsetPriorCost and OffsetStepCost their
// Gaussian residuals.
#include <gtest/gtest.h>

#include <Eigen/Core>

#include "magnav/core/gradiometer.h"
#include "magnav/tracker/cost_functions.h"
#include "sensor_offset.h"

namespace magnav::tracker::internal {
namespace {

TEST(OffsetCosts, TheOffsetBlockMovesTheBResidualsAsTheBaseOffsetWould) {
  GradiometerSample s;
  s.t_s = 1.0;
  s.sensor_id = 3;
  s.p_SinW = Eigen::Vector3d(2.0, -1.0, 0.5);
  s.B = Eigen::Vector3d(2.1e-5, -3e-6, 4.2e-5);
  s.T << 1e-8, 2e-9, 3e-9, 2e-9, -4e-9, 1e-9, 3e-9, 1e-9, -6e-9;
  s.sigma_B = 1e-9;
  s.sigma_T = 1e-10;
  const Eigen::Vector3d B0(2e-5, -3.5e-6, 4.1e-5);
  const SqrtInfo8 L = MeasurementSqrtInfo(1e-9, 1e-10, true);
  const Eigen::Vector3d o_at_T(3e-9, -1e-9, 2e-9);
  MeasurementCost base(s, B0, L, 1000.0);
  base.SetBackgroundOffset(o_at_T);
  const OffsetMeasurementCost cost(&base, o_at_T * 1e9);
  double state[6] = {-6.0, 3.0, -5.0, 1.0, 0.3, 0.0};
  double moment[3] = {1.5, 0.3, 0.8};
  Eigen::Vector3d o_nT = o_at_T * 1e9;
  const double* params[3] = {state, moment, o_nT.data()};
  Eigen::Matrix<double, 8, 1> e_base, e;
  ASSERT_TRUE(base.Evaluate(params, e_base.data(), nullptr));
  Eigen::Matrix<double, 8, 6, Eigen::RowMajor> J0;
  Eigen::Matrix<double, 8, 3, Eigen::RowMajor> J1, J2;
  double* jac[3] = {J0.data(), J1.data(), J2.data()};
  ASSERT_TRUE(cost.Evaluate(params, e.data(), jac));
  EXPECT_LT((e - e_base).norm(), 1e-12 * (1.0 + e_base.norm()));  // at o_at: the base's
  // Moving the block by δ moves the residual as the base with offset o_at + δ.
  const Eigen::Vector3d delta_nT(0.7, -1.2, 0.4);
  o_nT += delta_nT;
  ASSERT_TRUE(cost.Evaluate(params, e.data(), nullptr));
  MeasurementCost moved(s, B0, L, 1000.0);
  moved.SetBackgroundOffset(o_at_T + delta_nT * 1e-9);
  Eigen::Matrix<double, 8, 1> e_moved;
  ASSERT_TRUE(moved.Evaluate(params, e_moved.data(), nullptr));
  EXPECT_LT((e - e_moved).norm(), 1e-9 * (1.0 + e_moved.norm()));
  EXPECT_LT((e - (e_base + J2 * delta_nT)).norm(), 1e-9 * (1.0 + e.norm()));  // linear in the offset
  EXPECT_GT(J2.norm(), 0.1);  // of order 1 in nT per σ_B = 1 nT

  const OffsetPriorCost prior(2.0);
  const OffsetStepCost step(0.5);
  Eigen::Vector3d a(1.0, -2.0, 4.0), b(2.0, 0.0, 3.0);
  const double* pa[1] = {a.data()};
  const double* pab[2] = {a.data(), b.data()};
  Eigen::Vector3d r;
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> Ja, Jb;
  double* ja[1] = {Ja.data()};
  double* jab[2] = {Ja.data(), Jb.data()};
  ASSERT_TRUE(prior.Evaluate(pa, r.data(), ja));
  EXPECT_LT((r - a / 2.0).norm(), 1e-15);
  EXPECT_LT((Ja - Eigen::Matrix3d::Identity() / 2.0).norm(), 1e-15);
  ASSERT_TRUE(step.Evaluate(pab, r.data(), jab));
  EXPECT_LT((r - (b - a) / 0.5).norm(), 1e-14);
  EXPECT_LT((Ja + Eigen::Matrix3d::Identity() / 0.5).norm(), 1e-14);
  EXPECT_LT((Jb - Eigen::Matrix3d::Identity() / 0.5).norm(), 1e-14);
}

}  // namespace
}  // namespace magnav::tracker::internal
