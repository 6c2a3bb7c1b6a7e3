#include "magnav/localizer/crlb.h"

#include <Eigen/Cholesky>
#include <cmath>

#include "graph.h"
#include "magnav/core/error.h"
#include "magnav/localizer/checkpoint.h"
#include "magnav/localizer/cost_functions.h"
#include "magnav/localizer/ekf.h"

namespace magnav::localizer {

std::vector<double> EpochTimes(const Pass& pass, const LocalizerOptions& options) {
  return internal::BuildTimeline(pass, options.epoch_tolerance_s).t;
}

CrlbResult ComputeCrlb(const Pass& pass, const LocalizerOptions& options, const std::vector<VesselVector>& trajectory,
                       const std::vector<Eigen::Vector2d>& sensors_xy) {
  const internal::Graph g = internal::BuildGraph(pass, options);
  if (trajectory.size() != static_cast<std::size_t>(g.num_epochs) ||
      sensors_xy.size() != static_cast<std::size_t>(g.num_sensors)) {
    throw InputError("ComputeCrlb: expected " + std::to_string(g.num_epochs) + " states and " +
                     std::to_string(g.num_sensors) + " sensors, got " + std::to_string(trajectory.size()) +
                     " and " + std::to_string(sensors_xy.size()));
  }
  CrlbResult out;
  const std::size_t m = sensors_xy.size();
  out.joint.assign(m, Eigen::Matrix2d::Zero());
  out.known_trajectory.assign(m, Eigen::Matrix2d::Zero());
  Eigen::SparseMatrix<double> H;
  if (!internal::Information(g, internal::Pack(g, trajectory, sensors_xy), nullptr, nullptr, &H)) return out;
  if (!internal::SensorMarginalCovariance(g, H, &out.joint_full)) return out;
  if (!internal::KnownTrajectoryCovariances(g, H, &out.known_trajectory)) return out;
  for (std::size_t j = 0; j < m; ++j) {
    out.joint[j] = out.joint_full.block<2, 2>(2 * static_cast<int>(j), 2 * static_cast<int>(j));
  }
  out.ok = true;
  return out;
}

CrlbResult AttachCrlb(const Pass& pass, const LocalizerOptions& options, const std::vector<VesselVector>& trajectory,
                      std::vector<SensorEstimate>* sensors) {
  std::vector<Eigen::Vector2d> s_xy;
  for (const auto& e : *sensors) s_xy.push_back(e.p_SinW_m.head<2>());
  CrlbResult b = ComputeCrlb(pass, options, trajectory, s_xy);
  for (std::size_t j = 0; j < sensors->size(); ++j) {
    (*sensors)[j].crlb_joint_m2 = b.joint[j];
    (*sensors)[j].crlb_known_trajectory_m2 = b.known_trajectory[j];
  }
  return b;
}

bool IncrementalCrlbOptions::IsValid(std::string* error) const {
  if (!(lag_s >= 0.0) || !std::isfinite(lag_s)) {
    if (error) *error = "bound lag_s must be finite and >= 0";
    return false;
  }
  if (max_window_items < 1) {
    if (error) *error = "bound max_window_items must be >= 1";
    return false;
  }
  return true;
}

IncrementalCrlb::IncrementalCrlb(const Vessel& vessel, const std::vector<SensorPrior>& sensors,
                                 const LocalizerOptions& options, const IncrementalCrlbOptions& bound)
    : vessel_(vessel), sensors_(sensors), options_(options), bound_(bound) {
  std::string why;
  if (!bound.IsValid(&why)) throw InputError("localizer options: " + why);
  const int m = static_cast<int>(sensors.size());
  folded_.info = Eigen::MatrixXd::Zero(5 + 2 * m, 5 + 2 * m);
  folded_.known.assign(sensors.size(), Eigen::Matrix2d::Zero());
  for (int j = 0; j < m; ++j) {
    const double s = sensors[static_cast<std::size_t>(j)].sigma_xy_m;  // SensorPriorCost: J = I / σ
    folded_.info.block<2, 2>(5 + 2 * j, 5 + 2 * j) = Eigen::Matrix2d::Identity() / (s * s);
    folded_.known[static_cast<std::size_t>(j)] = Eigen::Matrix2d::Identity() / (s * s);
    index_[sensors[static_cast<std::size_t>(j)].sensor_id] = j;
  }
}

IncrementalCrlb::Epoch& IncrementalCrlb::EpochAt(double t_s, const Eigen::VectorXd& state) {
  if (window_.empty() || t_s - window_.back().t_s > options_.epoch_tolerance_s) {
    window_.emplace_back();
    window_.back().t_s = t_s;
  }
  window_.back().x = state.head<5>();
  ++window_items_;
  return window_.back();
}

void IncrementalCrlb::Add(const MagSample& sample, const Eigen::VectorXd& state) {
  if (!index_.count(sample.sensor_id)) return;
  EpochAt(sample.t_s, state).samples.push_back(sample);
  FoldOld(state);
}

void IncrementalCrlb::Add(const GnssFix& fix, const Eigen::VectorXd& state) {
  EpochAt(fix.t_s, state).fixes.push_back(fix);
  FoldOld(state);
}

void IncrementalCrlb::FoldOld(const Eigen::VectorXd& state) {
  // The newest epoch may still take items: never folded here.
  const double newest = window_.back().t_s;
  std::vector<Eigen::Vector2d> s_xy;
  while (window_.size() > 1 &&
         (newest - window_.front().t_s > bound_.lag_s || window_items_ > bound_.max_window_items)) {
    if (s_xy.empty()) {
      for (std::size_t j = 0; j < sensors_.size(); ++j) s_xy.push_back(state.segment<2>(5 + 2 * static_cast<int>(j)));
    }
    Fold(window_.front(), s_xy, &folded_);
    window_items_ -= window_.front().samples.size() + window_.front().fixes.size();
    window_.pop_front();
    ++folded_epochs_;
  }
}

void IncrementalCrlb::Fold(const Epoch& e, const std::vector<Eigen::Vector2d>& sensors_xy, Folded* f) const {
  const int n = static_cast<int>(f->info.rows()), ns = n - 5;
  if (f->has_state) {
    // Motion factor between the folded state x₀ and this epoch's x₁, then x₀
    // eliminated: info ← [[J₁ᵀJ₁, 0], [0, Λ_ss]] − Cᵀ A⁻¹ C with
    // A = Λ₀₀ + J₀ᵀJ₀ and C = [J₀ᵀJ₁, Λ₀s].
    const MotionCost motion(e.t_s - f->t_s, options_.process);
    Eigen::Matrix<double, 5, 5, Eigen::RowMajor> J0, J1;
    Eigen::Matrix<double, 5, 1> r;
    const double* p[2] = {f->x.data(), e.x.data()};
    double* jac[2] = {J0.data(), J1.data()};
    if (motion.Evaluate(p, r.data(), jac)) {
      const Eigen::Matrix<double, 5, 5> A = f->info.topLeftCorner<5, 5>() + J0.transpose() * J0;
      Eigen::MatrixXd C(5, n);
      C.leftCols<5>() = J0.transpose() * J1;
      C.rightCols(ns) = f->info.topRightCorner(5, ns);
      const Eigen::LDLT<Eigen::Matrix<double, 5, 5>> ldlt(A);
      const Eigen::MatrixXd X = ldlt.solve(C);
      f->info.topLeftCorner<5, 5>() = J1.transpose() * J1;
      f->info.topRightCorner(5, ns).setZero();
      f->info.bottomLeftCorner(ns, 5).setZero();
      f->info.noalias() -= C.transpose() * X;
    }
  }
  const double* p[2] = {e.x.data(), nullptr};
  for (const GnssFix& fix : e.fixes) {
    const double sigma = GnssSigma(fix, options_);
    if (!(sigma > 0.0)) continue;  // the door refuses these
    const GnssCost cost(fix.p_xy_m, sigma);
    Eigen::Matrix<double, 2, 5, Eigen::RowMajor> J;
    Eigen::Vector2d r;
    double* jac[1] = {J.data()};
    if (cost.Evaluate(p, r.data(), jac)) f->info.topLeftCorner<5, 5>() += J.transpose() * J;
  }
  for (const MagSample& s : e.samples) {
    const int j = index_.at(s.sensor_id);
    const SensorPrior& prior = sensors_[static_cast<std::size_t>(j)];
    const MagnetometerCost cost(vessel_, prior.p_SinW_m.z(), s.B_T, options_.sigma_B_T);
    Eigen::Matrix<double, 3, 5, Eigen::RowMajor> Jx;
    Eigen::Matrix<double, 3, 2, Eigen::RowMajor> Js;
    Eigen::Vector3d r;
    const Eigen::Vector2d& xy = sensors_xy[static_cast<std::size_t>(j)];
    p[1] = xy.data();
    double* jac[2] = {Jx.data(), Js.data()};
    if (!cost.Evaluate(p, r.data(), jac)) continue;
    const int c = 5 + 2 * j;
    f->info.topLeftCorner<5, 5>() += Jx.transpose() * Jx;
    const Eigen::Matrix<double, 5, 2> xs = Jx.transpose() * Js;
    f->info.block<5, 2>(0, c) += xs;
    f->info.block<2, 5>(c, 0) += xs.transpose();
    const Eigen::Matrix2d ss = Js.transpose() * Js;
    f->info.block<2, 2>(c, c) += ss;
    f->known[static_cast<std::size_t>(j)] += ss;
  }
  f->has_state = true;
  f->t_s = e.t_s;
  f->x = e.x;
}

CrlbResult IncrementalCrlb::Bounds(const std::vector<Eigen::Vector2d>& sensors_xy) const {
  const std::size_t m = sensors_.size();
  if (sensors_xy.size() != m) {
    throw InputError("IncrementalCrlb::Bounds: expected " + std::to_string(m) + " sensors, got " +
                     std::to_string(sensors_xy.size()));
  }
  CrlbResult out;
  out.joint.assign(m, Eigen::Matrix2d::Zero());
  out.known_trajectory.assign(m, Eigen::Matrix2d::Zero());
  Folded f = folded_;
  for (const Epoch& e : window_) Fold(e, sensors_xy, &f);
  if (!f.has_state) return out;
  const int ns = 2 * static_cast<int>(m);
  const Eigen::Matrix<double, 5, 5> Hxx = f.info.topLeftCorner<5, 5>();
  const Eigen::LDLT<Eigen::Matrix<double, 5, 5>> ldlt(Hxx);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return out;
  const Eigen::MatrixXd Hxs = f.info.topRightCorner(5, ns);
  Eigen::MatrixXd J = f.info.bottomRightCorner(ns, ns) - Hxs.transpose() * ldlt.solve(Hxs);
  J = 0.5 * (J + J.transpose()).eval();
  const Eigen::LLT<Eigen::MatrixXd> llt(J);
  if (llt.info() != Eigen::Success) return out;
  out.joint_full = llt.solve(Eigen::MatrixXd::Identity(ns, ns));
  out.joint_full = 0.5 * (out.joint_full + out.joint_full.transpose()).eval();
  if (!out.joint_full.allFinite()) return out;
  for (std::size_t j = 0; j < m; ++j) {
    const Eigen::LLT<Eigen::Matrix2d> k(f.known[j]);
    if (k.info() != Eigen::Success) return out;
    out.known_trajectory[j] = k.solve(Eigen::Matrix2d::Identity());
    out.joint[j] = out.joint_full.block<2, 2>(2 * static_cast<int>(j), 2 * static_cast<int>(j));
  }
  out.ok = true;
  return out;
}

std::vector<double> IncrementalCrlb::WindowTimes() const {
  std::vector<double> t;
  for (const Epoch& e : window_) t.push_back(e.t_s);
  return t;
}

std::vector<VesselVector> IncrementalCrlb::WindowTrajectory() const {
  std::vector<VesselVector> x;
  for (const Epoch& e : window_) x.push_back(e.x);
  return x;
}

void IncrementalCrlb::SaveState(StateWriter& w) const {
  w.Matrix(folded_.info);
  w.U64(folded_.known.size());
  for (const Eigen::Matrix2d& k : folded_.known) w.Matrix(k);
  w.U8(folded_.has_state ? 1 : 0);
  w.F64(folded_.t_s);
  w.Matrix(folded_.x);
  w.U64(window_.size());
  for (const Epoch& e : window_) {
    w.F64(e.t_s);
    w.Matrix(e.x);
    w.U64(e.samples.size());
    for (const MagSample& s : e.samples) {
      w.F64(s.t_s);
      w.U32(s.sensor_id);
      for (int i = 0; i < 3; ++i) w.F64(s.B_T[i]);
    }
    w.U64(e.fixes.size());
    for (const GnssFix& f : e.fixes) {
      w.F64(f.t_s);
      w.F64(f.p_xy_m.x());
      w.F64(f.p_xy_m.y());
      w.F64(f.sigma_m);
    }
  }
  w.U64(window_items_);
  w.U64(folded_epochs_);
}

void IncrementalCrlb::RestoreState(StateReader& r) {
  const std::size_t m = sensors_.size(), n = 5 + 2 * m;
  const std::size_t max_items = bound_.max_window_items + 1;
  auto fixed = [&r](std::size_t rows, std::size_t cols, const char* what) {
    Eigen::MatrixXd a = r.Matrix(rows, cols);
    if (static_cast<std::size_t>(a.rows()) != rows || static_cast<std::size_t>(a.cols()) != cols) {
      throw CheckpointError(std::string("corrupt: bound ") + what + " of another size");
    }
    return a;
  };
  Folded f;
  f.info = fixed(n, n, "information");
  if (r.Count(m) != m) throw CheckpointError("corrupt: bound of another number of sensors");
  f.known.resize(m);
  for (Eigen::Matrix2d& k : f.known) k = fixed(2, 2, "sensor information");
  f.has_state = r.U8() != 0;
  f.t_s = r.F64();
  f.x = fixed(5, 1, "vessel state");
  std::deque<Epoch> window(r.Count(max_items));
  for (Epoch& e : window) {
    e.t_s = r.F64();
    e.x = fixed(5, 1, "epoch state");
    e.samples.resize(r.Count(max_items));
    for (MagSample& s : e.samples) {
      s.t_s = r.F64();
      s.sensor_id = r.U32();
      for (int i = 0; i < 3; ++i) s.B_T[i] = r.F64();
    }
    e.fixes.resize(r.Count(max_items));
    for (GnssFix& fx : e.fixes) {
      fx.t_s = r.F64();
      fx.p_xy_m.x() = r.F64();
      fx.p_xy_m.y() = r.F64();
      fx.sigma_m = r.F64();
    }
  }
  const std::uint64_t items = r.U64(), folded = r.U64();
  folded_ = std::move(f);
  window_ = std::move(window);
  window_items_ = static_cast<std::size_t>(items);
  folded_epochs_ = folded;
}

}  // namespace magnav::localizer
