// Forward model against the independent reference (magpylib) and identities.
#include "magnav/core/dipole.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/frames.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/tensor.h"
#include "test_data.h"

namespace magnav {
namespace {

struct RefCase {
  Vec3 r, m, B;
  Mat3 T;
  int kind;
};

std::vector<RefCase> LoadDipoleCases() {
  const CsvTable t = CsvTable::Read(testing::ReferencePath("dipole_cases.csv"));
  std::vector<RefCase> out;
  auto col = [&](const std::string& n) { return t.column(n); };
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    RefCase c;
    const Vec3 s(t.number(i, col("sensor_x")), t.number(i, col("sensor_y")), t.number(i, col("sensor_z")));
    const Vec3 d(t.number(i, col("dipole_x")), t.number(i, col("dipole_y")), t.number(i, col("dipole_z")));
    c.r = s - d;
    c.m = {t.number(i, col("m_x")), t.number(i, col("m_y")), t.number(i, col("m_z"))};
    c.B = {t.number(i, col("B_x")), t.number(i, col("B_y")), t.number(i, col("B_z"))};
    for (int k = 0; k < 9; ++k) {
      c.T(k / 3, k % 3) = t.number(i, col(TensorColumnName("T", k / 3, k % 3)));
    }
    c.kind = static_cast<int>(t.integer(i, col("case_kind")));
    out.push_back(c);
  }
  return out;
}

// Each entry point on its own against the reference (magpylib) values; the
// bounds are the reference's stated accuracy (README: B to 2.4e-15, T to
// 3.7e-10 relative) plus our own rounding, not a loose 1e-8.
TEST(DipoleReference, FieldAndTensorMatchEveryCase) {
  const auto cases = LoadDipoleCases();
  ASSERT_EQ(cases.size(), 500u);
  double worst_B = 0.0, worst_T = 0.0, worst_BT = 0.0;
  for (const auto& c : cases) {
    worst_B = std::max(worst_B, (DipoleB(c.r, c.m) - c.B).norm() / c.B.norm());
    worst_T = std::max(worst_T, (DipoleT(c.r, c.m) - c.T).norm() / c.T.norm());
    Vec3 B;
    Mat3 T;
    DipoleBT(c.r, c.m, &B, &T);
    worst_BT = std::max({worst_BT, (B - c.B).norm() / c.B.norm(), (T - c.T).norm() / c.T.norm()});
  }
  std::printf("worst relative error vs reference: B %.3g, T %.3g, DipoleBT %.3g\n", worst_B, worst_T, worst_BT);
  EXPECT_LT(worst_B, 5e-15);
  EXPECT_LT(worst_T, 5.6e-10);
  EXPECT_LT(worst_BT, 5.6e-10);
}

// T is the gradient of B: central differences of DipoleB (step 1e-5 |r|,
// truncation ~1e-10, rounding ~1e-11 relative) on every reference case.
TEST(DipoleReference, TensorIsTheFiniteDifferenceGradientOfB) {
  double worst = 0.0;
  for (const auto& c : LoadDipoleCases()) {
    const double h = 1e-5 * c.r.norm();
    Mat3 fd;
    for (int j = 0; j < 3; ++j) {
      const Vec3 dr = h * Vec3::Unit(j);
      fd.col(j) = (DipoleB(c.r + dr, c.m) - DipoleB(c.r - dr, c.m)) / (2.0 * h);
    }
    worst = std::max(worst, (fd - DipoleT(c.r, c.m)).norm() / DipoleT(c.r, c.m).norm());
  }
  std::printf("worst relative difference T vs finite differences of B: %.3g\n", worst);
  EXPECT_LT(worst, 1e-8);
}

TEST(DipoleIdentities, SymmetricTraceFreeAndEuler) {
  for (const auto& c : LoadDipoleCases()) {
    Vec3 B;
    Mat3 T;
    DipoleBT(c.r, c.m, &B, &T);
    EXPECT_EQ(RelativeAsymmetry(T), 0.0);
    EXPECT_LT(RelativeTrace(T), 1e-14);
    // Euler's homogeneity of degree −3: T r = −3 B.
    EXPECT_LT((T * c.r + 3.0 * B).norm(), 1e-13 * (T.norm() * c.r.norm()));
  }
}

TEST(DipoleClosedForm, AxialAndEquatorialFields) {
  // On the axis B = 2k m / r³; on the equator B = −k m / r³ (k = μ0/4π).
  const Vec3 m(0.0, 0.0, 1000.0);
  const double r = 7.0;
  const Vec3 Baxis = DipoleB(Vec3(0, 0, r), m);
  const Vec3 Beq = DipoleB(Vec3(r, 0, 0), m);
  EXPECT_NEAR(Baxis.z(), 2e-7 * 1000.0 / (r * r * r), 1e-22);
  EXPECT_NEAR(Beq.z(), -1e-7 * 1000.0 / (r * r * r), 1e-22);
  EXPECT_NEAR(Baxis.head<2>().norm(), 0.0, 1e-25);
}

// Residual = measurement in nT so GradientChecker's relative test is well scaled.
class MeasurementCost : public ceres::SizedCostFunction<8, 3, 3> {
 public:
  bool Evaluate(double const* const* p, double* residuals, double** jac) const override {
    const Eigen::Map<const Vec3> r(p[0]), m(p[1]);
    Jacobian8x3 Jr, Jm;
    using RowMajor8x3 = Eigen::Matrix<double, 8, 3, Eigen::RowMajor>;
    Eigen::Map<Measurement8> z(residuals);
    z = 1e9 * DipoleMeasurement(r, m, &Jr, &Jm);
    if (jac && jac[0]) {
      Eigen::Map<RowMajor8x3> J0(jac[0]);
      J0 = 1e9 * Jr;
    }
    if (jac && jac[1]) {
      Eigen::Map<RowMajor8x3> J1(jac[1]);
      J1 = 1e9 * Jm;
    }
    return true;
  }
};

TEST(DipoleJacobians, AgreeWithGradientChecker) {
  MeasurementCost cost;
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = 1e-6;
  ceres::GradientChecker checker(&cost, static_cast<const std::vector<const ceres::Manifold*>*>(nullptr), nd);
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 200; ++trial) {
    Vec3 r(n01(rng), n01(rng), n01(rng));
    r *= (2.0 + 50.0 * std::abs(n01(rng))) / r.norm();
    Vec3 m = 1e4 * Vec3(n01(rng), n01(rng), n01(rng));
    std::vector<const double*> params = {r.data(), m.data()};
    ceres::GradientChecker::ProbeResults results;
    EXPECT_TRUE(checker.Probe(params.data(), 1e-6, &results)) << results.error_log;
  }
}

TEST(DipoleJacobians, FieldJacobiansOfDipoleB) {
  const Vec3 r(3.0, -4.0, 5.0), m(100.0, 200.0, -50.0);
  Mat3 Jr, Jm;
  const Vec3 B = DipoleB(r, m, &Jr, &Jm);
  // Central differences (B is linear in m, so those are exact to rounding).
  Mat3 fd_r, fd_m;
  for (int j = 0; j < 3; ++j) {
    const Vec3 dr = 1e-5 * Vec3::Unit(j), dm = 1.0 * Vec3::Unit(j);
    fd_r.col(j) = (DipoleB(r + dr, m) - DipoleB(r - dr, m)) / 2e-5;
    fd_m.col(j) = (DipoleB(r, m + dm) - DipoleB(r, m - dm)) / 2.0;
  }
  EXPECT_LT((Jr - fd_r).norm(), 1e-8 * Jr.norm());
  EXPECT_LT((Jm - fd_m).norm(), 1e-10 * Jm.norm());
  // And J_B_m m = B.
  EXPECT_TRUE((Jm * m).isApprox(B, 1e-14));
}

TEST(DipoleMoment, FitRecoversMomentFromReference) {
  for (const auto& c : LoadDipoleCases()) {
    Vec3 m;
    ASSERT_TRUE(FitDipoleMoment(c.r, c.B, c.T, 0.0, 0.0, &m));
    EXPECT_LT((m - c.m).norm() / c.m.norm(), 1e-8);
  }
  Vec3 m;
  EXPECT_FALSE(FitDipoleMoment(Vec3::Zero(), Vec3::Ones(), Mat3::Identity(), 1, 1, &m));
  EXPECT_FALSE(FitDipoleMoment(Vec3(1, 2, std::nan("")), Vec3::Ones(), Mat3::Identity(), 1, 1, &m));
}

TEST(HeadingRotation, MomentRotatesClockwiseFromNorth) {
  const Vec3 m_B(1.0, 0.0, 0.5);
  // Heading 90° (east): forward axis points east.
  const Vec3 m_W = WorldMoment(m_B, M_PI / 2);
  EXPECT_NEAR(m_W.x(), 0.0, 1e-15);
  EXPECT_NEAR(m_W.y(), 1.0, 1e-15);
  EXPECT_NEAR(m_W.z(), 0.5, 1e-15);
  Vec3 J;
  WorldMoment(Vec3(2000, 300, 800), 0.3, &J);
  const double h = 1e-6;
  const Vec3 fd = (WorldMoment(Vec3(2000, 300, 800), 0.3 + h) - WorldMoment(Vec3(2000, 300, 800), 0.3 - h)) / (2 * h);
  EXPECT_LT((J - fd).norm(), 1e-6);
}

}  // namespace
}  // namespace magnav
