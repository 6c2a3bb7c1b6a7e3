// The window's offset lines marginalised out of its covariance
// (tracker/src/offset_marginal.h; issue 24, docs/ACCURACY.md "The window
// offsets' uncertainty in the window's σ"): on a small window of real
// measurement, process and prior factors, the chain's covariance plus
// Z S⁻¹ Zᵀ equals the states' and the moment's blocks of the inverse of the
// joint information over (states, moment, lines) built densely here, the
// lines' columns by differencing the factors' residuals in the offset (not by
// the J_o = [I/σ_B; 0] the marginal assumes). And ChainSolve against a dense
// solve.
#include "offset_marginal.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "factors.h"
#include "magnav/core/dipole.h"
#include "magnav/core/frames.h"
#include "magnav/tracker/cost_functions.h"
#include "magnav/tracker/initialize.h"

namespace magnav::tracker::internal {
namespace {

constexpr double kNano = 1e-9;

struct SmallWindow {
  static constexpr std::size_t kStates = 6;
  static constexpr double kDt = 0.5;
  TrackerOptions options;
  std::vector<StateVector> x;
  Eigen::Vector3d moment;  // moment block (m_B / kScale)
  static constexpr double kScale = 1000.0;
  Eigen::Vector3d B0 = Eigen::Vector3d(2e-5, 1e-6, 4.5e-5);
  std::vector<Epoch> epochs;
  std::vector<std::vector<Factor>> measurements, process;
  Factor prior;
  ChainProblem chain;

  SmallWindow() {
    x.resize(kStates);
    moment = Eigen::Vector3d(1.8, -0.3, 0.8);
    const Eigen::Vector3d m_B = kScale * moment;
    const std::vector<Eigen::Vector3d> sensors = {{0, 0, 0}, {0, 12, 0}, {12, 0, 0}};
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0.0, 1.0);
    for (std::size_t k = 0; k < kStates; ++k) {
      x[k] << -6.0 + 1.2 * kDt * static_cast<double>(k), 4.0, -5.0, 1.2, 0.0, 0.0;
      Epoch e;
      e.t_s = kDt * static_cast<double>(k);
      for (std::size_t j = 0; j < sensors.size(); ++j) {
        GradiometerSample s;
        s.sensor_id = static_cast<std::uint32_t>(j + 1);
        s.t_s = e.t_s;
        s.p_SinW = sensors[j];
        Eigen::Vector3d B;
        Eigen::Matrix3d T;
        // A little off the state, so that the residuals are not zero.
        const Eigen::Vector3d p = x[k].head<3>() + Eigen::Vector3d(0.05 * noise(rng), 0.05 * noise(rng), 0.0);
        DipoleBT(s.p_SinW - p, HeadingRotation(x[k](4)) * m_B, &B, &T);
        s.B = B0 + B;
        s.T = T;
        s.sigma_B = 1e-9;
        s.sigma_T = 1.4e-9;
        e.samples.push_back(s);
      }
      epochs.push_back(e);
    }
    measurements.resize(kStates);
    process.resize(kStates);
    for (std::size_t k = 0; k < kStates; ++k) {
      AddMeasurementFactors(epochs[k], B0, options, kScale, x[k].data(), moment.data(), &measurements[k]);
      if (k + 1 < kStates) AddProcessFactors(kDt, options.process, nullptr, x[k].data(), x[k + 1].data(), &process[k]);
    }
    Eigen::Matrix<double, 9, 9> L = Eigen::Matrix<double, 9, 9>::Identity();
    L.diagonal() << 2.0, 2.0, 2.0, 5.0, 3.0, 10.0, 1.0, 1.0, 1.0;
    Eigen::Matrix<double, 9, 1> x_bar;
    x_bar << x[0], moment;
    prior.kind = Factor::Kind::kPrior;
    prior.cost = std::make_unique<PriorCost>(L, x_bar, Eigen::Matrix<double, 9, 1>::Zero());
    prior.blocks = {x[0].data(), moment.data()};
    chain.moment = moment.data();
    chain.groups.resize(kStates);
    for (std::size_t k = 0; k < kStates; ++k) {
      chain.states.push_back(x[k].data());
      if (k == 0) chain.groups[k].push_back(&prior);
      for (const auto& f : measurements[k]) chain.groups[k].push_back(&f);
      for (const auto& f : process[k]) chain.groups[k].push_back(&f);
    }
  }
};

// The rows of a two-block factor's Jacobian over the dense parameter vector
// [x_0 … x_{N−1} (6 each); m (3)] (the offset columns are added apart).
Eigen::MatrixXd DenseJacobian(const Factor& f, const SmallWindow& w, Eigen::Index cols) {
  const int m = f.cost->num_residuals();
  const auto& sizes = f.cost->parameter_block_sizes();
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(2);
  J[0].resize(m, sizes[0]);
  J[1].resize(m, sizes[1]);
  double* jac[2] = {J[0].data(), J[1].data()};
  Eigen::VectorXd e(m);
  const double* params[2] = {f.blocks[0], f.blocks[1]};
  EXPECT_TRUE(f.cost->Evaluate(params, e.data(), jac));
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(m, cols);
  for (int b = 0; b < 2; ++b) {
    Eigen::Index c = -1;
    for (std::size_t k = 0; k < SmallWindow::kStates; ++k) {
      if (f.blocks[b] == w.x[k].data()) c = static_cast<Eigen::Index>(6 * k);
    }
    if (f.blocks[b] == w.moment.data()) c = static_cast<Eigen::Index>(6 * SmallWindow::kStates);
    EXPECT_GE(c, 0);
    out.block(0, c, m, sizes[b]) = J[b];
  }
  return out;
}

TEST(OffsetLineMarginal, EqualsTheDenseJointInverse) {
  SmallWindow w;
  const std::size_t n = SmallWindow::kStates;
  const double t_ref = 0.5 * SmallWindow::kDt * static_cast<double>(n - 1);
  const double level_sigma = 5e-9, rate_sigma = 5e-9;
  const std::vector<std::uint32_t> lines = {1, 2};  // sensor 3 has none
  const Eigen::Index ns = static_cast<Eigen::Index>(6 * n + 3), nl = 6 * 2;

  // The marginal (offset_marginal.h).
  ChainFactorization f;
  ASSERT_TRUE(FactorizeChain(w.chain, &f));
  std::vector<StateCovariance> P;
  Eigen::Matrix3d Pm;
  ASSERT_TRUE(ChainCovariance(f, &P, &Pm));
  const std::vector<StateCovariance> P_given = P;
  OffsetLineMarginal marginal(n, lines);
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t i = 0; i < w.measurements[k].size(); ++i) {
      const auto& smp = w.epochs[k].samples[i];
      const bool has_line = smp.sensor_id != 3;
      EXPECT_EQ(marginal.Add(w.measurements[k][i], k, smp.sensor_id, 1e-9, w.epochs[k].t_s - t_ref), has_line);
    }
  }
  marginal.AddPriors(level_sigma, rate_sigma);
  ASSERT_TRUE(marginal.Marginalize(f, &P, &Pm));

  // The dense joint information: every factor's rows, and the offsets' columns
  // (nT, nT/s) by differencing the measurement residuals in the offset.
  std::vector<Eigen::MatrixXd> rows;
  for (const auto& group : w.chain.groups) {
    for (const Factor* g : group) {
      Eigen::MatrixXd J = Eigen::MatrixXd::Zero(g->cost->num_residuals(), ns + nl);
      J.leftCols(ns) = DenseJacobian(*g, w, ns);
      if (g->kind == Factor::Kind::kMeasurement) {
        auto* cost = static_cast<MeasurementCost*>(g->cost.get());
        std::uint32_t id = 0;
        double t = 0.0;
        for (std::size_t k = 0; k < n; ++k) {
          for (std::size_t i = 0; i < w.measurements[k].size(); ++i) {
            if (&w.measurements[k][i] == g) {
              id = w.epochs[k].samples[i].sensor_id;
              t = w.epochs[k].t_s;
            }
          }
        }
        if (id == 1 || id == 2) {
          const Eigen::Index c = ns + 6 * static_cast<Eigen::Index>(id - 1);
          const double* params[2] = {g->blocks[0], g->blocks[1]};
          Eigen::Matrix<double, 8, 1> e0, e1;
          ASSERT_TRUE(cost->Evaluate(params, e0.data(), nullptr));
          for (int a = 0; a < 3; ++a) {
            cost->SetBackgroundOffset(kNano * Eigen::Vector3d::Unit(a));  // 1 nT on axis a
            ASSERT_TRUE(cost->Evaluate(params, e1.data(), nullptr));
            cost->SetBackgroundOffset(Eigen::Vector3d::Zero());
            J.col(c + a) = e1 - e0;
            J.col(c + 3 + a) = (t - t_ref) * (e1 - e0);
          }
        }
      }
      rows.push_back(J);
    }
  }
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(ns + nl, ns + nl);
  for (const auto& J : rows) H += J.transpose() * J;
  for (Eigen::Index l = 0; l < 2; ++l) {
    for (int a = 0; a < 3; ++a) {
      H(ns + 6 * l + a, ns + 6 * l + a) += std::pow(kNano / level_sigma, 2);
      H(ns + 6 * l + 3 + a, ns + 6 * l + 3 + a) += std::pow(kNano / rate_sigma, 2);
    }
  }
  const Eigen::MatrixXd H_inv = H.ldlt().solve(Eigen::MatrixXd::Identity(ns + nl, ns + nl));
  const Eigen::MatrixXd A_inv = H.topLeftCorner(ns, ns).ldlt().solve(Eigen::MatrixXd::Identity(ns, ns));
  double grew = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Index i = static_cast<Eigen::Index>(6 * k);
    const StateCovariance dense = H_inv.block<6, 6>(i, i);
    const StateCovariance given = A_inv.block<6, 6>(i, i);
    EXPECT_LE((P_given[k] - given).norm(), 1e-6 * given.norm()) << "state " << k;  // the chain alone
    EXPECT_LE((P[k] - dense).norm(), 1e-6 * dense.norm()) << "state " << k;
    grew = std::max(grew, P[k].topLeftCorner<3, 3>().trace() / P_given[k].topLeftCorner<3, 3>().trace());
  }
  EXPECT_LE((Pm - H_inv.block<3, 3>(ns - 3, ns - 3)).norm(), 1e-6 * Pm.norm());
  // The lines take B's information: the position's variance grows (measured 4.98x here).
  std::printf("grew %.3f\n", grew);
  EXPECT_GE(grew, 1.5);

  // ChainSolve against a dense solve of the chain's own information.
  Eigen::MatrixXd R = Eigen::MatrixXd::Random(ns, 4);
  Eigen::MatrixXd Z;
  ASSERT_TRUE(ChainSolve(f, R, &Z));
  const Eigen::MatrixXd Z_dense = A_inv * R;
  EXPECT_LE((Z - Z_dense).norm(), 1e-6 * Z_dense.norm());
  EXPECT_FALSE(ChainSolve(f, Eigen::MatrixXd::Zero(ns + 1, 1), &Z));  // wrong size refused
}

}  // namespace
}  // namespace magnav::tracker::internal
