// The localizer's models and building blocks against independent truth:
// Jacobians against central finite differences, the field against the dipole
// formula written out here, one EKF update against the textbook dense
// Joseph-form update, the bounds against a dense Fisher information built by
// finite differences, and bad input refused without touching the state.
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <fstream>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "magnav/core/error.h"
#include "magnav/localizer/cost_functions.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/ekf.h"
#include "magnav/localizer/input.h"
#include "magnav/localizer/models.h"
#include "test_data.h"

namespace magnav::localizer {
namespace {

const Vessel kVessel{{30000.0, 2000.0, 10000.0}, 0.0};

// B = μ0/4π [3 (m·r) r / r⁵ − m / r³], m = Rz(h) m_B, written out independently.
Eigen::Vector3d FieldByHand(const VesselVector& x, const Eigen::Vector3d& p_S) {
  const double c = std::cos(x[kHeading]), s = std::sin(x[kHeading]);
  const Eigen::Vector3d& mb = kVessel.m_B_Am2;
  const Eigen::Vector3d m(c * mb.x() - s * mb.y(), s * mb.x() + c * mb.y(), mb.z());
  const Eigen::Vector3d r = p_S - Eigen::Vector3d(x[kX], x[kY], kVessel.z_m);
  const double n = r.norm();
  return 1e-7 * (3.0 * m.dot(r) * r / std::pow(n, 5) - m / std::pow(n, 3));
}

// Central differences of a cost function's residual with respect to block b.
Eigen::MatrixXd NumericJacobian(const ceres::CostFunction& f, std::vector<std::vector<double>> params, int b,
                                double h) {
  const int m = f.num_residuals();
  const int n = f.parameter_block_sizes()[static_cast<std::size_t>(b)];
  Eigen::MatrixXd J(m, n);
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd ep(m), em(m);
    auto p = params;
    p[static_cast<std::size_t>(b)][static_cast<std::size_t>(i)] += h;
    std::vector<const double*> ptr;
    for (auto& v : p) ptr.push_back(v.data());
    f.Evaluate(ptr.data(), ep.data(), nullptr);
    p[static_cast<std::size_t>(b)][static_cast<std::size_t>(i)] -= 2 * h;
    ptr.clear();
    for (auto& v : p) ptr.push_back(v.data());
    f.Evaluate(ptr.data(), em.data(), nullptr);
    J.col(i) = (ep - em) / (2 * h);
  }
  return J;
}

Eigen::MatrixXd AnalyticJacobian(const ceres::CostFunction& f, std::vector<std::vector<double>> params, int b) {
  const int m = f.num_residuals();
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J;
  std::vector<double*> jac;
  std::vector<const double*> ptr;
  for (std::size_t k = 0; k < params.size(); ++k) {
    J.emplace_back(m, f.parameter_block_sizes()[k]);
    ptr.push_back(params[k].data());
  }
  for (auto& j : J) jac.push_back(j.data());
  Eigen::VectorXd e(m);
  EXPECT_TRUE(f.Evaluate(ptr.data(), e.data(), jac.data()));
  return J[static_cast<std::size_t>(b)];
}

TEST(LocalizerModel, FieldIsTheDipoleOfTheTurnedMoment) {
  VesselVector x;
  x << 12.0, -7.0, 2.0, 0.7, 0.05;
  const Eigen::Vector3d p_S(30.0, 15.0, 30.0);
  const Eigen::Vector3d B = VesselFieldAtSensor(x, kVessel, p_S);
  EXPECT_LT((B - FieldByHand(x, p_S)).norm(), 1e-12 * B.norm());
}

TEST(LocalizerModel, MagnetometerJacobiansMatchFiniteDifferences) {
  for (double heading : {0.0, 0.7, -2.5}) {
    const MagnetometerCost f(kVessel, 30.0, Eigen::Vector3d(1e-8, -2e-8, 3e-8), 1e-9);
    const std::vector<std::vector<double>> p = {{12.0, -7.0, 2.0, heading, 0.05}, {30.0, 15.0}};
    for (int b : {0, 1}) {
      const Eigen::MatrixXd A = AnalyticJacobian(f, p, b), N = NumericJacobian(f, p, b, 1e-5);
      EXPECT_LT((A - N).norm(), 1e-6 * A.norm()) << "block " << b << " heading " << heading << "\n" << A << "\n" << N;
    }
  }
}

TEST(LocalizerModel, MotionJacobiansMatchFiniteDifferencesIncludingStraightLine) {
  const LocalizerProcessNoise q;
  for (double w : {0.1, 1e-5, 0.0}) {
    const MotionCost f(0.2, q);
    const std::vector<std::vector<double>> p = {{1.0, 2.0, 2.0, 0.3, w}, {1.4, 2.1, 2.0, 0.3, w}};
    for (int b : {0, 1}) {
      const Eigen::MatrixXd A = AnalyticJacobian(f, p, b), N = NumericJacobian(f, p, b, 1e-6);
      EXPECT_LT((A - N).norm(), 1e-6 * A.norm()) << "block " << b << " turn rate " << w;
    }
  }
  // ω → 0: the prediction is continuous (the straight line is the limit).
  VesselVector x;
  x << 0.0, 0.0, 2.0, 0.3, 1e-9;
  const VesselVector a = PropagateVessel(x, 10.0);
  x[kTurnRate] = 0.0;
  const VesselVector b = PropagateVessel(x, 10.0);
  EXPECT_LT((a - b).norm(), 1e-6);  // ω = 1e-9 moves the end by ≈ v t² ω / 2 = 1e-7 m
  EXPECT_NEAR(b[kX], 20.0 * std::cos(0.3), 1e-12);
  EXPECT_NEAR(b[kY], 20.0 * std::sin(0.3), 1e-12);
}

std::vector<SensorPrior> TwoSensors() {
  return {{3, {30.0, 15.0, 30.0}, 15.0}, {7, {-20.0, 40.0, 30.0}, 15.0}};
}

TEST(LocalizerEkf, OneUpdateEqualsTheDenseJosephForm) {
  const auto sensors = TwoSensors();
  VesselVector x0;
  x0 << 10.0, 5.0, 2.0, 0.4, 0.01;
  const VesselCovariance P0 = VesselVector(4.0, 4.0, 0.25, 0.1, 0.001).asDiagonal();
  LocalizerOptions opt;
  opt.magnetometer_iterations = 1;  // the plain EKF update
  LocalizerEkf ekf(kVessel, sensors, 0.0, x0, P0, opt);
  ASSERT_TRUE(ekf.Predict(0.2));
  const Eigen::VectorXd x = ekf.state();
  const Eigen::MatrixXd P = ekf.covariance();
  MagSample s{0.2, 7, Eigen::Vector3d(5e-9, -3e-9, 8e-9)};
  ASSERT_TRUE(ekf.Update(s));

  // Dense textbook update with H by central differences of the hand-written field.
  const int n = static_cast<int>(x.size());
  const auto h = [&](const Eigen::VectorXd& z) {
    return FieldByHand(z.head<5>(), Eigen::Vector3d(z[7], z[8], 30.0));
  };
  Eigen::MatrixXd H(3, n);
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd a = x, b = x;
    a[i] += 1e-5;
    b[i] -= 1e-5;
    H.col(i) = (h(a) - h(b)) / 2e-5;
  }
  const Eigen::Matrix3d R = Eigen::Matrix3d::Identity() * opt.sigma_B_T * opt.sigma_B_T;
  const Eigen::Matrix3d S = H * P * H.transpose() + R;
  const Eigen::MatrixXd K = P * H.transpose() * S.inverse();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd P_ref = (I - K * H) * P * (I - K * H).transpose() + K * R * K.transpose();
  const Eigen::VectorXd x_ref = x + K * (s.B_T - h(x));
  EXPECT_LT((ekf.state() - x_ref).norm(), 1e-6 * (x_ref - x).norm() + 1e-9);
  EXPECT_LT((ekf.covariance() - P_ref).norm(), 1e-6 * P.norm());
  EXPECT_EQ(ekf.covariance(), ekf.covariance().transpose());
  // The unobserved sensor 3 is untouched only through correlations (none yet).
  EXPECT_EQ(ekf.state().segment<2>(5), x.segment<2>(5));
}

// The iterated update (the default, magnetometer_iterations = 2): the second
// iteration relinearises at the first's result x1, x2 = x + K1 (z − h(x1) −
// H1 (x − x1)), and the covariance is the Joseph form with H1, K1 (K1 from the
// prior P and H1): the textbook IEKF, dense, H by central differences.
TEST(LocalizerEkf, IteratedUpdateEqualsTheDenseTextbookIekf) {
  const auto sensors = TwoSensors();
  VesselVector x0;
  x0 << 10.0, 5.0, 2.0, 0.4, 0.01;
  const VesselCovariance P0 = VesselVector(4.0, 4.0, 0.25, 0.1, 0.001).asDiagonal();
  const LocalizerOptions opt;
  ASSERT_EQ(opt.magnetometer_iterations, 2);
  LocalizerEkf ekf(kVessel, sensors, 0.0, x0, P0, opt);
  ASSERT_TRUE(ekf.Predict(0.2));
  const Eigen::VectorXd x = ekf.state();
  const Eigen::MatrixXd P = ekf.covariance();
  MagSample s{0.2, 7, Eigen::Vector3d(5e-9, -3e-9, 8e-9)};
  ASSERT_TRUE(ekf.Update(s));

  const int n = static_cast<int>(x.size());
  const auto h = [&](const Eigen::VectorXd& z) {
    return FieldByHand(z.head<5>(), Eigen::Vector3d(z[7], z[8], 30.0));
  };
  const auto jacobian = [&](const Eigen::VectorXd& at) {
    Eigen::MatrixXd H(3, n);
    for (int i = 0; i < n; ++i) {
      Eigen::VectorXd a = at, b = at;
      a[i] += 1e-5;
      b[i] -= 1e-5;
      H.col(i) = (h(a) - h(b)) / 2e-5;
    }
    return H;
  };
  const Eigen::Matrix3d R = Eigen::Matrix3d::Identity() * opt.sigma_B_T * opt.sigma_B_T;
  const auto gain = [&](const Eigen::MatrixXd& H) {
    const Eigen::Matrix3d S = H * P * H.transpose() + R;
    return Eigen::MatrixXd(P * H.transpose() * S.inverse());
  };
  const Eigen::MatrixXd H0 = jacobian(x);
  const Eigen::VectorXd x1 = x + gain(H0) * (s.B_T - h(x));
  const Eigen::MatrixXd H1 = jacobian(x1);
  const Eigen::MatrixXd K1 = gain(H1);
  const Eigen::VectorXd x2 = x + K1 * (s.B_T - h(x1) - H1 * (x - x1));
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd P_ref = (I - K1 * H1) * P * (I - K1 * H1).transpose() + K1 * R * K1.transpose();
  // The premise: the second iteration moves the state (else this equals the plain update).
  ASSERT_GT((x2 - x1).norm(), 1e-3 * (x1 - x).norm());
  EXPECT_LT((ekf.state() - x2).norm(), 1e-6 * (x2 - x).norm() + 1e-9);
  EXPECT_LT((ekf.covariance() - P_ref).norm(), 1e-6 * P.norm());
  EXPECT_EQ(ekf.covariance(), ekf.covariance().transpose());
}

TEST(LocalizerEkf, BadSamplesLeaveTheStateUntouched) {
  VesselVector x0;
  x0 << 10.0, 5.0, 2.0, 0.4, 0.01;
  LocalizerEkf ekf(kVessel, TwoSensors(), 1.0, x0, VesselCovariance::Identity(), LocalizerOptions{});
  const Eigen::VectorXd x = ekf.state();
  const Eigen::MatrixXd P = ekf.covariance();
  EXPECT_FALSE(ekf.Update(MagSample{1.0, 4, Eigen::Vector3d(1e-9, 0, 0)}));  // unknown sensor
  EXPECT_FALSE(ekf.Update(MagSample{0.5, 3, Eigen::Vector3d(1e-9, 0, 0)}));  // before time()
  EXPECT_FALSE(ekf.Update(MagSample{1.0, 3, Eigen::Vector3d(std::nan(""), 0, 0)}));
  EXPECT_FALSE(ekf.Update(GnssFix{1.0, Eigen::Vector2d(std::nan(""), 0), 3.0}));
  EXPECT_FALSE(ekf.Update(GnssFix{1.0, Eigen::Vector2d(1.0, 0), 0.0}));  // no sigma, no override: no guess
  EXPECT_FALSE(ekf.Predict(std::numeric_limits<double>::infinity()));
  EXPECT_EQ(ekf.state(), x);
  EXPECT_EQ(ekf.covariance(), P);
  EXPECT_EQ(ekf.time(), 1.0);
}

TEST(LocalizerInput, GateRefusesAndCounts) {
  InputGate gate(TwoSensors());
  EXPECT_EQ(gate.Check(MagSample{1.0, 3, Eigen::Vector3d::Zero()}), SampleCheck::kOk);
  EXPECT_EQ(gate.Check(MagSample{1.0, 5, Eigen::Vector3d::Zero()}), SampleCheck::kUnknownSensor);
  EXPECT_EQ(gate.Check(MagSample{0.8, 3, Eigen::Vector3d::Zero()}), SampleCheck::kTimeBackwards);
  EXPECT_EQ(gate.Check(MagSample{0.8, 7, Eigen::Vector3d::Zero()}), SampleCheck::kOk);  // per sensor
  EXPECT_EQ(gate.Check(MagSample{2.0, 7, Eigen::Vector3d(0, std::nan(""), 0)}), SampleCheck::kNonFinite);
  EXPECT_EQ(gate.Check(GnssFix{1.0, Eigen::Vector2d::Zero(), 0.0}), SampleCheck::kBadSigma);
  EXPECT_EQ(gate.Check(GnssFix{1.0, Eigen::Vector2d::Zero(), 3.0}), SampleCheck::kOk);
  EXPECT_EQ(gate.Check(GnssFix{0.5, Eigen::Vector2d::Zero(), 3.0}), SampleCheck::kTimeBackwards);
  // Out of range: B in nT sent as T (|B_i| > 1 T), a position beyond 1e7 m;
  // refused without moving the stream's time (a later good one is accepted).
  EXPECT_EQ(gate.Check(MagSample{3.0, 7, Eigen::Vector3d(0, 0, 48000.0)}), SampleCheck::kOutOfRange);
  EXPECT_EQ(gate.Check(MagSample{3.0, 7, Eigen::Vector3d(0, 0, -1.5)}), SampleCheck::kOutOfRange);
  EXPECT_EQ(gate.Check(MagSample{2.5, 7, Eigen::Vector3d(0, 0, 0.99)}), SampleCheck::kOk);
  EXPECT_EQ(gate.Check(GnssFix{2.0, Eigen::Vector2d(1e308, 0.0), 3.0}), SampleCheck::kOutOfRange);
  EXPECT_EQ(gate.Check(GnssFix{2.0, Eigen::Vector2d(0.0, 0.0), 1e8}), SampleCheck::kOutOfRange);
  EXPECT_EQ(gate.Check(GnssFix{1.5, Eigen::Vector2d(-9e6, 9e6), 3.0}), SampleCheck::kOk);
}

// A small pass: a straight-then-turning vessel over two sensors, noise-free.
Pass SmallPass(std::vector<VesselVector>* truth) {
  Pass p;
  p.vessel = kVessel;
  p.sensors = TwoSensors();
  VesselVector x;
  x << -40.0, 0.0, 2.0, 0.3, 0.0;
  for (int k = 0; k < 40; ++k) {
    const double t = 0.5 * k;
    if (k == 20) x[kTurnRate] = 0.05;
    truth->push_back(x);
    if (k % 2 == 0) p.gnss.push_back({t, x.head<2>(), 3.0});
    for (const auto& s : p.sensors) p.samples.push_back({t, s.sensor_id, FieldByHand(x, s.p_SinW_m)});
    x = PropagateVessel(x, 0.5);
  }
  return p;
}

TEST(LocalizerCrlb, EqualsTheDenseInverseOfAFiniteDifferenceFisherInformation) {
  std::vector<VesselVector> traj;
  const Pass pass = SmallPass(&traj);
  const LocalizerOptions opt;
  std::vector<Eigen::Vector2d> s = {{30.0, 15.0}, {-20.0, 40.0}};
  const CrlbResult b = ComputeCrlb(pass, opt, traj, s);
  ASSERT_TRUE(b.ok);

  // Whitened residuals of the whole pass as one function of all parameters,
  // written with the cost functions, differentiated numerically.
  const int N = static_cast<int>(traj.size()), n = 5 * N + 4;
  const auto residuals = [&](const Eigen::VectorXd& z) {
    std::vector<double> e;
    const auto push = [&e](const ceres::CostFunction& f, std::vector<const double*> p) {
      Eigen::VectorXd r(f.num_residuals());
      f.Evaluate(p.data(), r.data(), nullptr);
      for (int i = 0; i < r.size(); ++i) e.push_back(r[i]);
    };
    for (int k = 0; k < N; ++k) {
      const double* xk = z.data() + 5 * k;
      if (k + 1 < N) push(MotionCost(0.5, opt.process), {xk, xk + 5});
      if (k % 2 == 0) push(GnssCost(pass.gnss[static_cast<std::size_t>(k / 2)].p_xy_m, 3.0), {xk});
      for (int j = 0; j < 2; ++j) {
        push(MagnetometerCost(kVessel, 30.0, pass.samples[static_cast<std::size_t>(2 * k + j)].B_T, opt.sigma_B_T),
             {xk, z.data() + 5 * N + 2 * j});
      }
    }
    for (int j = 0; j < 2; ++j) {
      push(SensorPriorCost(pass.sensors[static_cast<std::size_t>(j)].p_SinW_m.head<2>(), 15.0),
           {z.data() + 5 * N + 2 * j});
    }
    return Eigen::Map<Eigen::VectorXd>(e.data(), static_cast<int>(e.size())).eval();
  };
  Eigen::VectorXd z(n);
  for (int k = 0; k < N; ++k) z.segment<5>(5 * k) = traj[static_cast<std::size_t>(k)];
  z.segment<2>(5 * N) = s[0];
  z.segment<2>(5 * N + 2) = s[1];
  const Eigen::VectorXd e0 = residuals(z);
  Eigen::MatrixXd J(e0.size(), n);
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd a = z, c = z;
    a[i] += 1e-6;
    c[i] -= 1e-6;
    J.col(i) = (residuals(a) - residuals(c)) / 2e-6;
  }
  const Eigen::MatrixXd F = J.transpose() * J;
  const Eigen::MatrixXd C = F.inverse();
  const Eigen::Matrix4d ref = C.bottomRightCorner<4, 4>();
  EXPECT_LT((b.joint_full - ref).norm(), 1e-4 * ref.norm()) << b.joint_full << "\n" << ref;
  for (int j = 0; j < 2; ++j) {
    const Eigen::Matrix2d known = F.block<2, 2>(5 * N + 2 * j, 5 * N + 2 * j).inverse();
    EXPECT_LT((b.known_trajectory[static_cast<std::size_t>(j)] - known).norm(), 1e-4 * known.norm());
  }
}

// Bad files: each refused with file, line and column (the CLI exits 2 on it).
struct BadFile {
  std::string name, measurements, deployment, gnss, expect;
};

std::string Write(const std::string& dir, const std::string& name, const std::string& text) {
  const std::string path = dir + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(LocalizerInput, BadFilesNameFileLineAndField) {
  const std::string dir = testing::TempDir();
  const std::string head = "# moment_body_Am2: 30000, 2000, 10000\n# vessel_z_m: 0\nt,sensor_id,B_x,B_y,B_z\n";
  const std::string deploy = "sensor_id,x,y,z,sigma_xy\n0,1,2,30,15\n1,5,6,30,15\n";
  const std::string gnss = "t,x,y,sigma\n0,0,0,3\n1,2,0,3\n";
  const std::vector<BadFile> cases = {
      {"unknown sensor", head + "0,0,1e-9,0,0\n0,1,1e-9,0,0\n0,9,1e-9,0,0\n", deploy, gnss,
       "m.csv:6: column 'sensor_id': sensor 9 is not in the deployment file"},
      {"time backwards", head + "1,0,1e-9,0,0\n1,1,1e-9,0,0\n0.5,0,1e-9,0,0\n", deploy, gnss,
       "m.csv:6: column 't': time goes backwards"},
      {"missing moment", "# vessel_z_m: 0\nt,sensor_id,B_x,B_y,B_z\n0,0,1e-9,0,0\n0,1,1e-9,0,0\n", deploy, gnss,
       "no vessel moment: give --moment-body"},
      {"missing depth", "# moment_body_Am2: 1, 2, 3\nt,sensor_id,B_x,B_y,B_z\n0,0,1e-9,0,0\n0,1,1e-9,0,0\n",
       deploy, gnss, "no vessel depth"},
      {"nan", head + "0,0,1e-9,nan,0\n0,1,1e-9,0,0\n", deploy, gnss, "m.csv:4: column 'B_y'"},
      {"never seen", head + "0,0,1e-9,0,0\n", deploy, gnss, "d.csv:3: column 'sensor_id': sensor 1 has no sample"},
      {"gnss sigma", head + "0,0,1e-9,0,0\n0,1,1e-9,0,0\n", deploy, "t,x,y,sigma\n0,0,0,-3\n", "g.csv:2: column 'sigma'"},
      {"gnss backwards", head + "0,0,1e-9,0,0\n0,1,1e-9,0,0\n", deploy, "t,x,y,sigma\n1,0,0,3\n0,0,0,3\n",
       "g.csv:3: column 't': time goes backwards"},
      {"duplicate sensor", head + "0,0,1e-9,0,0\n", "sensor_id,x,y,z,sigma_xy\n0,1,2,30,15\n0,5,6,30,15\n", gnss,
       "d.csv:3: column 'sensor_id': sensor 0 listed twice"},
  };
  for (const BadFile& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string m = Write(dir, "m.csv", c.measurements), d = Write(dir, "d.csv", c.deployment),
                      g = Write(dir, "g.csv", c.gnss);
    try {
      ReadPassFiles(m, d, g, std::nullopt);
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(c.expect), std::string::npos) << e.what();
    }
  }
  // The moment from outside replaces a missing line.
  const std::string m = Write(dir, "m.csv", "# vessel_z_m: 0\nt,sensor_id,B_x,B_y,B_z\n0,0,1e-9,0,0\n0,1,1e-9,0,0\n");
  const PassFile f = ReadPassFiles(m, Write(dir, "d.csv", deploy), "", Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(f.pass.vessel.m_B_Am2, Eigen::Vector3d(1, 2, 3));
}

TEST(LocalizerOptions, DefaultsAreValidAndBadOnesNamed) {
  LocalizerOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.process.turn_rate_radps_per_sqrt_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("turn_rate"), std::string::npos);
  o = LocalizerOptions{};
  o.gnss_sigma_m = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("gnss_sigma_m"), std::string::npos);
  o = LocalizerOptions{};
  o.sigma_B_T = std::nan("");
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("sigma_B_T"), std::string::npos);
  for (const int iterations : {0, LocalizerOptions::kMaxMagnetometerIterations + 1, 1000000000}) {
    o = LocalizerOptions{};
    o.magnetometer_iterations = iterations;
    EXPECT_FALSE(o.IsValid(&why)) << iterations;
    EXPECT_NE(why.find("magnetometer_iterations"), std::string::npos);
  }
  o.magnetometer_iterations = LocalizerOptions::kMaxMagnetometerIterations;
  EXPECT_TRUE(o.IsValid(&why)) << why;
}

}  // namespace
}  // namespace magnav::localizer
