// Tracker building blocks: analytic Jacobians of the measurement cost against
// numeric differentiation, the tensor-noise whitening, the single-sample
// initialiser on noise-free reference data, option validation.
#include "magnav/tracker/cost_functions.h"

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "magnav/core/csv.h"
#include "magnav/core/frames.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/tensor.h"
#include "magnav/core/units.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/options.h"
#include "test_data.h"

namespace magnav::tracker {
namespace {

TEST(MeasurementCost, AnalyticJacobiansAgreeWithNumericDifferentiation) {
  std::mt19937 rng(11);
  std::normal_distribution<double> n01;
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = 1e-6;
  const SqrtInfo8 L = MeasurementSqrtInfo(1e-9, 1.4e-9, true);
  for (int trial = 0; trial < 100; ++trial) {
    GradiometerSample s;
    s.p_SinW = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)) * 5.0;
    const double scale = 3000.0;
    // Random vessel state 3–40 m from the sensor, and a measurement made by a
    // different moment so the residual is not zero.
    Eigen::Matrix<double, 6, 1> x;
    Eigen::Vector3d dir(n01(rng), n01(rng), n01(rng));
    x.head<3>() = s.p_SinW + dir.normalized() * (3.0 + 37.0 * std::abs(n01(rng)) / 3.0);
    x(3) = 1.0;
    x(4) = 3.0 * n01(rng);
    x(5) = 0.01 * n01(rng);
    Eigen::Vector3d m_tilde(n01(rng), n01(rng), n01(rng));
    Eigen::Vector3d B;
    Eigen::Matrix3d T;
    DipoleBT(s.p_SinW - x.head<3>(), scale * 1.1 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng)), &B, &T);
    s.B = B + Eigen::Vector3d(2e-5, 1e-6, 4.5e-5);
    s.T = T;
    const MeasurementCost cost(s, Eigen::Vector3d(2e-5, 1e-6, 4.5e-5), L, scale);
    ceres::GradientChecker checker(&cost, static_cast<const std::vector<const ceres::Manifold*>*>(nullptr),
                                   nd);
    std::vector<const double*> params = {x.data(), m_tilde.data()};
    ceres::GradientChecker::ProbeResults results;
    EXPECT_TRUE(checker.Probe(params.data(), 1e-6, &results)) << results.error_log;
  }
}

TEST(MeasurementCost, ResidualIsZeroAtTheTruthAndWhitened) {
  GradiometerSample s;
  s.p_SinW = {1.0, -2.0, 0.0};
  const Eigen::Vector3d p_V(5.0, 3.0, -5.0), m_B(2000.0, 300.0, 800.0);
  const double h = 0.7;
  Eigen::Vector3d B;
  Eigen::Matrix3d T;
  DipoleBT(s.p_SinW - p_V, WorldMoment(m_B, h), &B, &T);
  s.B = B;
  s.T = T;
  const MeasurementCost cost(s, Eigen::Vector3d::Zero(), MeasurementSqrtInfo(1e-9, 1e-9, false), 1000.0);
  Eigen::Matrix<double, 6, 1> x;
  x << p_V, 1.0, h, 0.0;
  const Eigen::Vector3d m_tilde = m_B / 1000.0;
  const double* params[] = {x.data(), m_tilde.data()};
  Eigen::Matrix<double, 8, 1> e;
  ASSERT_TRUE(cost.Evaluate(params, e.data(), nullptr));
  EXPECT_LT(e.norm(), 1e-3);  // in σ = 1 nT: only rounding
}

// SetFieldUsed(false) (the window's prior of a sensor whose B offset the
// window solves, window.cc): the B rows' residuals and Jacobians are zero and
// the tensor rows are those of the full factor, bit for bit.
TEST(MeasurementCost, WithoutItsFieldCarriesTheTensorRowsAlone) {
  GradiometerSample s;
  s.p_SinW = {1.0, -2.0, 0.0};
  const Eigen::Vector3d p_V(5.0, 3.0, -5.0), m_B(2000.0, 300.0, 800.0);
  Eigen::Vector3d B;
  Eigen::Matrix3d T;
  DipoleBT(s.p_SinW - p_V, WorldMoment(m_B, 0.7), &B, &T);
  s.B = B + Eigen::Vector3d(30e-9, -20e-9, 10e-9);  // a B misfit: nonzero B rows
  s.T = T + 2e-9 * Eigen::Matrix3d::Identity();
  const SqrtInfo8 L = MeasurementSqrtInfo(1e-9, 1.4e-9, true);
  const MeasurementCost full(s, Eigen::Vector3d::Zero(), L, 1000.0);
  MeasurementCost tensor_only(s, Eigen::Vector3d::Zero(), L, 1000.0);
  tensor_only.SetFieldUsed(false);
  Eigen::Matrix<double, 6, 1> x;
  x << p_V + Eigen::Vector3d(0.3, -0.2, 0.1), 1.0, 0.65, 0.0;
  const Eigen::Vector3d m_tilde = m_B / 1000.0 * 1.05;
  const double* params[] = {x.data(), m_tilde.data()};
  Eigen::Matrix<double, 8, 1> e_full, e_t;
  Eigen::Matrix<double, 8, 6, Eigen::RowMajor> Jx_full, Jx_t;
  Eigen::Matrix<double, 8, 3, Eigen::RowMajor> Jm_full, Jm_t;
  double* J_full[] = {Jx_full.data(), Jm_full.data()};
  double* J_t[] = {Jx_t.data(), Jm_t.data()};
  ASSERT_TRUE(full.Evaluate(params, e_full.data(), J_full));
  ASSERT_TRUE(tensor_only.Evaluate(params, e_t.data(), J_t));
  EXPECT_GT(e_full.head<3>().norm(), 10.0);  // the B misfit, in σ
  EXPECT_EQ(e_t.head<3>(), Eigen::Vector3d::Zero());
  EXPECT_EQ(e_t.tail<5>(), e_full.tail<5>());
  EXPECT_TRUE(Jx_t.topRows<3>().isZero(0.0));
  EXPECT_TRUE(Jm_t.topRows<3>().isZero(0.0));
  EXPECT_EQ(Jx_t.bottomRows<5>(), Jx_full.bottomRows<5>());
  EXPECT_EQ(Jm_t.bottomRows<5>(), Jm_full.bottomRows<5>());
  tensor_only.SetFieldUsed(true);
  ASSERT_TRUE(tensor_only.Evaluate(params, e_t.data(), nullptr));
  EXPECT_EQ(e_t, e_full);
}

TEST(MeasurementSqrtInfo, WhitensTheTraceFreeTensorNoise) {
  const double sT = 1.4e-9;
  const SqrtInfo8 L = MeasurementSqrtInfo(1e-9, sT, true);
  Eigen::Matrix<double, 8, 8> cov = Eigen::Matrix<double, 8, 8>::Zero();
  cov.diagonal().head<3>().setConstant(1e-18);
  cov.diagonal().tail<5>().setConstant(sT * sT);
  cov(3, 6) = cov(6, 3) = -0.5 * sT * sT;  // Txx, Tyy
  const Eigen::Matrix<double, 8, 8> I = L * cov * L.transpose();
  EXPECT_LT((I - Eigen::Matrix<double, 8, 8>::Identity()).norm(), 1e-9);
}

// The kinematic factor against values independent of its code: (1) zero on
// the reference truth tracks, whose kinematics are exact closed-form
// coordinated turns (magpylib generator), between every pair of consecutive
// samples (the rate of row i holds over (t_i, t_i+1)); (2) its analytic
// Jacobians against numeric differentiation (ceres::GradientChecker), turning
// and straight.
TEST(KinematicCost, ZeroOnTheExactReferenceTracks) {
  for (const std::string vessel : {"auv", "ship"}) {
    const CsvTable t = CsvTable::Read(testing::ReferencePath("track_truth_" + vessel + ".csv"));
    const auto c = [&](const char* n) { return t.column(n); };
    auto state = [&](std::size_t i) {
      Eigen::Matrix<double, 6, 1> s;
      s << t.number(i, c("x")), t.number(i, c("y")), t.number(i, c("z")),
          std::hypot(t.number(i, c("vx")), t.number(i, c("vy"))), t.number(i, c("heading")),
          t.number(i, c("turn_rate"));
      return s;
    };
    double worst = 0.0;
    for (std::size_t i = 0; i + 1 < t.num_rows(); ++i) {
      const double dt = t.number(i + 1, c("t")) - t.number(i, c("t"));
      const KinematicCost cost(dt, 0.01, 0.005, 0.002);
      Eigen::Matrix<double, 6, 1> s0 = state(i), s1 = state(i + 1);
      // The file wraps headings to (−π, π]; the track's state is continuous.
      s1(4) = s0(4) + WrapAngle(s1(4) - s0(4));
      const double* params[] = {s0.data(), s1.data()};
      Eigen::Matrix<double, 5, 1> e;
      ASSERT_TRUE(cost.Evaluate(params, e.data(), nullptr));
      worst = std::max(worst, e.cwiseAbs().maxCoeff());
    }
    // Positions are exact to ~1e-9 m in the file: ~3e-7 in σ units here.
    EXPECT_LT(worst, 1e-5) << vessel;
  }
}

TEST(KinematicCost, AnalyticJacobiansAgreeWithNumericDifferentiation) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = 1e-7;
  for (int trial = 0; trial < 50; ++trial) {
    const double dt = 0.05 + 0.5 * (u(rng) + 1.0);
    const KinematicCost cost(dt, 0.01, 0.005, 0.002);
    Eigen::Matrix<double, 6, 1> s0, s1;
    s0 << 50 * u(rng), 50 * u(rng), 20 + u(rng), 3 + u(rng), 3 * u(rng), trial % 5 == 0 ? 0.0 : 0.05 * u(rng);
    s1 = s0 + 0.1 * Eigen::Matrix<double, 6, 1>::NullaryExpr([&] { return u(rng); });
    ceres::GradientChecker checker(&cost, static_cast<const std::vector<const ceres::Manifold*>*>(nullptr), nd);
    std::vector<const double*> params = {s0.data(), s1.data()};
    ceres::GradientChecker::ProbeResults results;
    EXPECT_TRUE(checker.Probe(params.data(), 1e-6, &results)) << trial << " " << results.error_log;
  }
}

// The depth's own random walk (ProcessNoise::depth_m_per_sqrt_s): z is
// whitened by σ_depth √dt, x and y by σ_p √dt; the 4-argument form uses σ_p
// for all three.
TEST(KinematicCost, DepthHasItsOwnSigma) {
  const double dt = 0.25;
  Eigen::Matrix<double, 6, 1> s0, s1;
  s0 << 0.0, 0.0, -5.0, 0.0, 0.3, 0.0;  // at rest: the prediction is s0
  s1 = s0;
  s1.head<3>() += Eigen::Vector3d(0.01, 0.02, 0.003);
  const double* params[] = {s0.data(), s1.data()};
  Eigen::Matrix<double, 5, 1> e, e4;
  ASSERT_TRUE(KinematicCost(dt, 0.01, 0.005, 0.002, 0.0003).Evaluate(params, e.data(), nullptr));
  ASSERT_TRUE(KinematicCost(dt, 0.01, 0.005, 0.002).Evaluate(params, e4.data(), nullptr));
  EXPECT_NEAR(e(0), 0.01 / (0.01 * 0.5), 1e-12);
  EXPECT_NEAR(e(1), 0.02 / (0.01 * 0.5), 1e-12);
  EXPECT_NEAR(e(2), 0.003 / (0.0003 * 0.5), 1e-9);
  EXPECT_NEAR(e4(2), 0.003 / (0.01 * 0.5), 1e-12);
  EXPECT_TRUE(e.tail<2>() == e4.tail<2>());
}

TEST(PriorCost, ResidualAndJacobian) {
  Eigen::Matrix<double, 9, 9> L = Eigen::Matrix<double, 9, 9>::Identity() * 2.0;
  L(0, 7) = 0.5;
  Eigen::Matrix<double, 9, 1> x_bar = Eigen::Matrix<double, 9, 1>::LinSpaced(9, 0.0, 8.0), c;
  c.setConstant(0.1);
  const PriorCost cost(L, x_bar, c);
  Eigen::Matrix<double, 6, 1> s = x_bar.head<6>();
  Eigen::Vector3d m = x_bar.tail<3>();
  s(0) += 1.0;
  const double* params[] = {s.data(), m.data()};
  Eigen::Matrix<double, 9, 1> e;
  Eigen::Matrix<double, 9, 6, Eigen::RowMajor> J0;
  Eigen::Matrix<double, 9, 3, Eigen::RowMajor> J1;
  double* jac[] = {J0.data(), J1.data()};
  ASSERT_TRUE(cost.Evaluate(params, e.data(), jac));
  EXPECT_NEAR(e(0), 2.1, 1e-12);
  EXPECT_NEAR(e(1), 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(J1(0, 1), 0.5);
  EXPECT_DOUBLE_EQ(J0(3, 3), 2.0);
}

// TED+EGT offsets on the noise-free AUV pass, including t = 77.6 s where T
// is singular (sensor in the dipole's equatorial plane).
TEST(SingleSampleOffset, RecoversTheNoiseFreeReferenceOffsets) {
  const GradiometerFile f =
      ReadGradiometerFile(testing::ReferencePath("track_pass_auv_1sensor_noisefree.csv"));
  const CsvTable truth = CsvTable::Read(testing::ReferencePath("track_truth_auv.csv"));
  ASSERT_EQ(truth.num_rows(), f.samples.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < f.samples.size(); ++i) {
    const auto& s = f.samples[i];
    const Eigen::Vector3d p_V(truth.number(i, truth.column("x")), truth.number(i, truth.column("y")),
                              truth.number(i, truth.column("z")));
    const auto r = SingleSampleOffset(s.B - *f.B0, s.T);
    ASSERT_TRUE(r.has_value());
    const Eigen::Vector3d r_true = s.p_SinW - p_V;
    worst = std::max(worst, (*r - r_true).norm() / r_true.norm());
  }
  // README: TED + eigenvector row ≤ 4.4e-10 relative on all samples; B − B0
  // loses ~1e-16·|B0| absolutely, which far from the vessel is ~1e-8 relative.
  EXPECT_LT(worst, 1e-6);
}

TEST(Options, DefaultsAreValidAndBadValuesAreNamed) {
  TrackerOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.process.turn_rate_radps_per_sqrt_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("turn_rate"), std::string::npos);
  o = TrackerOptions{};
  o.process.depth_m_per_sqrt_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("depth_m_per_sqrt_s"), std::string::npos);
  o = TrackerOptions{};
  o.process.depth_weak_m_per_sqrt_s = 3e-4;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.process.depth_weak_m_per_sqrt_s = -1e-4;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("depth_weak_m_per_sqrt_s"), std::string::npos);
  o = TrackerOptions{};
  o.process.depth_weak_tensor_snr = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("depth_weak_tensor_snr"), std::string::npos);
  o = TrackerOptions{};
  o.window_s = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("window_s"), std::string::npos);
  for (int n : {-1, TrackerOptions::kMaxBatchTurnChangePoints + 1}) {
    o = TrackerOptions{};
    o.batch_turn_change_points = n;
    EXPECT_FALSE(o.IsValid(&why)) << n;
    EXPECT_NE(why.find("batch_turn_change_points"), std::string::npos);
  }
  o.batch_turn_change_points = 0;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  LossType t;
  EXPECT_TRUE(ParseLossType("cauchy", &t));
  EXPECT_EQ(t, LossType::kCauchy);
  EXPECT_FALSE(ParseLossType("l1", &t));
}

}  // namespace
}  // namespace magnav::tracker
