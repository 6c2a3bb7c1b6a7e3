// Coordinated-turn propagation against the reference truth tracks (exact
// closed-form kinematics there) and against the ω → 0 limit.
#include "magnav/core/motion.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/units.h"
#include "test_data.h"

namespace magnav {
namespace {

class TruthTrack : public ::testing::TestWithParam<const char*> {};

TEST_P(TruthTrack, StepByStepPropagationReproducesTruth) {
  const CsvTable t = CsvTable::Read(testing::ReferencePath(std::string("track_truth_") + GetParam() + ".csv"));
  const auto c = [&](const char* n) { return t.column(n); };
  double worst_pos = 0.0, worst_h = 0.0;
  for (std::size_t i = 0; i + 1 < t.num_rows(); ++i) {
    const double vx = t.number(i, c("vx")), vy = t.number(i, c("vy"));
    CtState<double> s{t.number(i, c("x")), t.number(i, c("y")), t.number(i, c("z")), std::hypot(vx, vy),
                      t.number(i, c("heading")), t.number(i, c("turn_rate"))};
    const double dt = t.number(i + 1, c("t")) - t.number(i, c("t"));
    // A sample at a segment boundary carries the later segment's rate, so
    // row i's rate holds over (t_i, t_i+1).
    const CtState<double> p = PropagateCoordinatedTurn(s, dt);
    worst_pos = std::max(worst_pos, std::hypot(p.x - t.number(i + 1, c("x")), p.y - t.number(i + 1, c("y"))));
    worst_h = std::max(worst_h, std::abs(WrapAngle(p.heading - t.number(i + 1, c("heading")))));
  }
  // Kinematics are exact in the file: only rounding remains.
  EXPECT_LT(worst_pos, 1e-9);
  EXPECT_LT(worst_h, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Reference, TruthTrack, ::testing::Values("auv", "ship"));

TEST(CoordinatedTurn, StraightLineLimitIsContinuous) {
  const CtState<double> s{1.0, 2.0, -5.0, 3.0, 0.7, 0.0};
  const auto a = PropagateCoordinatedTurn(s, 10.0);
  EXPECT_NEAR(a.x, 1.0 + 30.0 * std::cos(0.7), 1e-12);
  EXPECT_NEAR(a.y, 2.0 + 30.0 * std::sin(0.7), 1e-12);
  CtState<double> s2 = s;
  s2.turn_rate = 1e-9;
  const auto b = PropagateCoordinatedTurn(s2, 10.0);
  EXPECT_NEAR(b.x, a.x, 1e-6);
  EXPECT_NEAR(b.y, a.y, 1e-6);
  // A full circle returns to the start.
  CtState<double> s3 = s;
  s3.turn_rate = 0.1;
  const auto c = PropagateCoordinatedTurn(s3, 2 * M_PI / 0.1);
  EXPECT_NEAR(c.x, s.x, 1e-12);
  EXPECT_NEAR(c.y, s.y, 1e-12);
  for (double u : {1e-4, 9.99e-4, 1.001e-3, 0.1}) EXPECT_NEAR(Sinc(u), std::sin(u) / u, 3e-16);
}

// The analytic Jacobian equals automatic differentiation of the templated
// propagation (Ceres Jets, exact to rounding), on turning and straight states.
TEST(CoordinatedTurn, AnalyticJacobianEqualsAutomaticDifferentiation) {
  using Jet = ceres::Jet<double, 6>;
  for (double w : {0.0, 1e-7, 5e-4, 0.02, -0.3}) {
    for (double dt : {0.1, -0.5, 7.0}) {
      const CtState<double> s{10.0, -4.0, 3.0, 2.5, 2.9, w};
      const double in[6] = {s.x, s.y, s.z, s.v, s.heading, s.turn_rate};
      CtState<Jet> sj;
      Jet* fields[6] = {&sj.x, &sj.y, &sj.z, &sj.v, &sj.heading, &sj.turn_rate};
      for (int i = 0; i < 6; ++i) *fields[i] = Jet(in[i], i);
      const CtState<Jet> o = PropagateCoordinatedTurn(sj, dt);
      const Jet out[6] = {o.x, o.y, o.z, o.v, o.heading, o.turn_rate};
      const Eigen::Matrix<double, 6, 6> F = CoordinatedTurnJacobian(s, dt);
      for (int r = 0; r < 6; ++r) {
        for (int c = 0; c < 6; ++c) {
          EXPECT_NEAR(F(r, c), out[r].v[c], 1e-12 * (1.0 + std::abs(out[r].v[c])))
              << "row " << r << " col " << c << " omega " << w << " dt " << dt;
        }
      }
    }
  }
  for (double u : {0.0, 1e-4, 9.99e-4, 1.001e-3, 0.1, -2.0}) {
    const double h = 1e-6;
    EXPECT_NEAR(SincDerivative(u), (Sinc(u + h) - Sinc(u - h)) / (2 * h), 1e-9) << u;
  }
}

}  // namespace
}  // namespace magnav
