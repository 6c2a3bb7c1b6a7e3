#include "graph.h"

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>

#include "magnav/core/error.h"
#include "magnav/localizer/cost_functions.h"
#include "magnav/localizer/ekf.h"

namespace magnav::localizer::internal {

Graph BuildGraph(const Pass& pass, const LocalizerOptions& options) {
  Graph g;
  g.timeline = BuildTimeline(pass, options.epoch_tolerance_s);
  g.num_epochs = static_cast<int>(g.timeline.t.size());
  g.num_sensors = static_cast<int>(pass.sensors.size());
  const auto add = [&g](Factor::Kind kind, ceres::CostFunction* cost, std::vector<int> blocks) {
    Factor f;
    f.kind = kind;
    f.cost.reset(cost);
    f.blocks = std::move(blocks);
    g.factors.push_back(std::move(f));
  };
  for (int k = 0; k < g.num_epochs; ++k) {
    if (k + 1 < g.num_epochs) {
      add(Factor::Kind::kMotion, new MotionCost(g.timeline.t[k + 1] - g.timeline.t[k], options.process), {k, k + 1});
    }
    for (int i : g.timeline.gnss_at[k]) {
      const GnssFix& f = pass.gnss[static_cast<std::size_t>(i)];
      const double sigma = GnssSigma(f, options);
      if (!(sigma > 0.0)) {
        throw InputError("localizer: the GNSS fix at t = " + std::to_string(f.t_s) +
                         " s has no sigma (give one per fix or LocalizerOptions::gnss_sigma_m)");
      }
      add(Factor::Kind::kGnss, new GnssCost(f.p_xy_m, sigma), {k});
    }
    for (int i : g.timeline.samples_at[k]) {
      const MagSample& s = pass.samples[static_cast<std::size_t>(i)];
      const int j = pass.SensorIndex(s.sensor_id);
      if (j < 0) continue;  // the readers refuse unknown sensors; never here
      add(Factor::Kind::kMagnetometer,
          new MagnetometerCost(pass.vessel, pass.sensors[static_cast<std::size_t>(j)].p_SinW_m.z(), s.B_T,
                               options.sigma_B_T),
          {k, g.num_epochs + j});
    }
  }
  for (int j = 0; j < g.num_sensors; ++j) {
    const SensorPrior& p = pass.sensors[static_cast<std::size_t>(j)];
    add(Factor::Kind::kPrior, new SensorPriorCost(p.p_SinW_m.head<2>(), p.sigma_xy_m), {g.num_epochs + j});
  }
  return g;
}

std::vector<double> Pack(const Graph& g, const std::vector<VesselVector>& trajectory,
                         const std::vector<Eigen::Vector2d>& sensors_xy) {
  std::vector<double> p(static_cast<std::size_t>(g.num_params()));
  for (int k = 0; k < g.num_epochs; ++k) {
    Eigen::Map<VesselVector>{&p[static_cast<std::size_t>(5 * k)]} = trajectory[static_cast<std::size_t>(k)];
  }
  for (int j = 0; j < g.num_sensors; ++j) {
    Eigen::Map<Eigen::Vector2d>{&p[static_cast<std::size_t>(g.offset(g.num_epochs + j))]} =
        sensors_xy[static_cast<std::size_t>(j)];
  }
  return p;
}

bool Information(const Graph& g, const std::vector<double>& params, const ceres::LossFunction* magnetometer_loss,
                 const ceres::LossFunction* gnss_loss, Eigen::SparseMatrix<double>* H) {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(g.factors.size() * 60);
  Eigen::VectorXd e;
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J;
  for (const Factor& f : g.factors) {
    const int m = f.cost->num_residuals();
    const std::size_t nb = f.blocks.size();
    e.resize(m);
    J.resize(nb);
    std::vector<const double*> p(nb);
    std::vector<double*> jac(nb);
    for (std::size_t b = 0; b < nb; ++b) {
      p[b] = &params[static_cast<std::size_t>(g.offset(f.blocks[b]))];
      J[b].resize(m, g.size(f.blocks[b]));
      jac[b] = J[b].data();
    }
    if (!f.cost->Evaluate(p.data(), e.data(), jac.data())) return false;
    double w = 1.0;
    const ceres::LossFunction* loss = f.kind == Factor::Kind::kMagnetometer ? magnetometer_loss
                                      : f.kind == Factor::Kind::kGnss       ? gnss_loss
                                                                            : nullptr;
    if (loss != nullptr) {
      double rho[3];
      loss->Evaluate(e.squaredNorm(), rho);
      w = std::max(rho[1], 0.0);
    }
    for (std::size_t a = 0; a < nb; ++a) {
      for (std::size_t b = 0; b < nb; ++b) {
        const Eigen::MatrixXd block = w * J[a].transpose() * J[b];
        const int oa = g.offset(f.blocks[a]), ob = g.offset(f.blocks[b]);
        for (int r = 0; r < block.rows(); ++r) {
          for (int c = 0; c < block.cols(); ++c) {
            if (block(r, c) != 0.0) triplets.emplace_back(oa + r, ob + c, block(r, c));
          }
        }
      }
    }
  }
  H->resize(g.num_params(), g.num_params());
  H->setFromTriplets(triplets.begin(), triplets.end());
  return true;
}

int CountBeyond(const Graph& g, const std::vector<double>& params, Factor::Kind kind, double threshold) {
  int count = 0;
  Eigen::VectorXd e;
  std::vector<const double*> p;
  for (const Factor& f : g.factors) {
    if (f.kind != kind) continue;
    e.resize(f.cost->num_residuals());
    p.clear();
    for (int b : f.blocks) p.push_back(&params[static_cast<std::size_t>(g.offset(b))]);
    if (!f.cost->Evaluate(p.data(), e.data(), nullptr) || !(e.squaredNorm() <= threshold)) ++count;
  }
  return count;
}

bool SensorMarginalCovariance(const Graph& g, const Eigen::SparseMatrix<double>& H, Eigen::MatrixXd* cov) {
  const int nx = g.num_state_params(), ns = 2 * g.num_sensors;
  const Eigen::SparseMatrix<double> Hxx = H.topLeftCorner(nx, nx);
  const Eigen::MatrixXd Hxs = Eigen::MatrixXd(H.topRightCorner(nx, ns));
  const Eigen::MatrixXd Hss = Eigen::MatrixXd(H.bottomRightCorner(ns, ns));
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Hxx);
  if (ldlt.info() != Eigen::Success) return false;
  const Eigen::MatrixXd X = ldlt.solve(Hxs);
  if (ldlt.info() != Eigen::Success) return false;
  Eigen::MatrixXd J = Hss - Hxs.transpose() * X;  // Schur complement: information on the sensors
  J = 0.5 * (J + J.transpose()).eval();
  const Eigen::LLT<Eigen::MatrixXd> llt(J);
  if (llt.info() != Eigen::Success) return false;
  *cov = llt.solve(Eigen::MatrixXd::Identity(ns, ns));
  *cov = 0.5 * (*cov + cov->transpose()).eval();
  return cov->allFinite();
}

bool KnownTrajectoryCovariances(const Graph& g, const Eigen::SparseMatrix<double>& H,
                                std::vector<Eigen::Matrix2d>* cov) {
  const int nx = g.num_state_params();
  cov->assign(static_cast<std::size_t>(g.num_sensors), Eigen::Matrix2d::Zero());
  for (int j = 0; j < g.num_sensors; ++j) {
    const Eigen::Matrix2d Hjj = Eigen::MatrixXd(H.block(nx + 2 * j, nx + 2 * j, 2, 2));
    const Eigen::LLT<Eigen::Matrix2d> llt(Hjj);
    if (llt.info() != Eigen::Success) return false;
    (*cov)[static_cast<std::size_t>(j)] = llt.solve(Eigen::Matrix2d::Identity());
  }
  return true;
}

}  // namespace magnav::localizer::internal
