#include "magnav/localizer/ekf.h"

#include <Eigen/Cholesky>
#include <chrono>
#include <cmath>
#include <limits>

#include "magnav/core/error.h"
#include "magnav/core/nees.h"
#include "magnav/localizer/checkpoint.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/models.h"
#include "magnav/localizer/stream.h"

namespace magnav::localizer {

double GnssSigma(const GnssFix& fix, const LocalizerOptions& options) {
  return options.gnss_sigma_m > 0.0 ? options.gnss_sigma_m : fix.sigma_m;
}

bool InitialVesselFromGnss(const std::vector<GnssFix>& fixes, double t0_s, const LocalizerOptions& options,
                           VesselVector* x0, VesselCovariance* P0, double window_s) {
  // Straight line p(t) = a + b (t − t0) by least squares over the window;
  // then the fix farthest off the line is dropped and the line refitted while
  // it is beyond the outlier gate (options.gate_probability, 2 dof), so that
  // one wild fix cannot place the start (and with it every gate) kilometres off.
  std::vector<const GnssFix*> used;
  for (const GnssFix& f : fixes) {
    if (f.t_s < t0_s - window_s || f.t_s > t0_s + window_s) continue;
    if (!(GnssSigma(f, options) > 0.0)) continue;
    used.push_back(&f);
  }
  const double gate = ChiSquareQuantile(options.gate_probability, 2);
  Eigen::Matrix2d coef, cov;
  double var = 0.0;
  for (;;) {
    Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
    Eigen::Matrix<double, 2, 2> rhs = Eigen::Matrix2d::Zero();  // columns x, y
    double t_min = INFINITY, t_max = -INFINITY;
    var = 0.0;
    for (const GnssFix* f : used) {
      const double sigma = GnssSigma(*f, options);
      const double w = 1.0 / (sigma * sigma);
      const Eigen::Vector2d phi(1.0, f->t_s - t0_s);
      A += w * phi * phi.transpose();
      rhs += w * phi * f->p_xy_m.transpose();
      t_min = std::min(t_min, f->t_s);
      t_max = std::max(t_max, f->t_s);
      var = std::max(var, sigma * sigma);
    }
    if (used.size() < 2 || t_max - t_min < 2.0) return false;
    const Eigen::LDLT<Eigen::Matrix2d> ldlt(A);
    coef = ldlt.solve(rhs);  // row 0: position at t0, row 1: velocity
    cov = ldlt.solve(Eigen::Matrix2d::Identity());
    if (used.size() < 3) break;
    std::size_t worst = 0;
    double worst_r2 = -1.0;
    for (std::size_t i = 0; i < used.size(); ++i) {
      const Eigen::Vector2d fit = coef.row(0).transpose() + (used[i]->t_s - t0_s) * coef.row(1).transpose();
      const double sigma = GnssSigma(*used[i], options);
      const double r2 = (used[i]->p_xy_m - fit).squaredNorm() / (sigma * sigma);
      if (r2 > worst_r2) {
        worst_r2 = r2;
        worst = i;
      }
    }
    if (!(worst_r2 > gate)) break;
    used.erase(used.begin() + static_cast<std::ptrdiff_t>(worst));
  }
  const Eigen::Vector2d vel = coef.row(1).transpose();
  *x0 << coef(0, 0), coef(0, 1), vel.norm(), std::atan2(vel.y(), vel.x()), 0.0;
  P0->setZero();
  // Position: the fit's σ, but at least a third of a fix's (the straight
  // line is only a model of the start).
  const double var_p = std::max(cov(0, 0), var / 9.0);
  (*P0)(kX, kX) = var_p;
  (*P0)(kY, kY) = var_p;
  (*P0)(kV, kV) = std::pow(options.initial.speed_mps, 2);
  (*P0)(kHeading, kHeading) = std::pow(options.initial.heading_rad, 2);
  (*P0)(kTurnRate, kTurnRate) = std::pow(options.initial.turn_rate_radps, 2);
  return true;
}

LocalizerEkf::LocalizerEkf(const Vessel& vessel, const std::vector<SensorPrior>& sensors, double t0_s,
                           const VesselVector& x0, const VesselCovariance& P0, const LocalizerOptions& options)
    : vessel_(vessel),
      sensors_(sensors),
      options_(options),
      t_s_(t0_s),
      gate_magnetometer_nis_(ChiSquareQuantile(options.gate_probability, 3)),
      gate_gnss_nis_(ChiSquareQuantile(options.gate_probability, 2)),
      magnetometer_gate_(sensors.size()) {
  std::string why;
  if (!options.IsValid(&why)) throw InputError("localizer options: " + why);
  const int n = 5 + 2 * static_cast<int>(sensors.size());
  x_ = Eigen::VectorXd::Zero(n);
  P_ = Eigen::MatrixXd::Zero(n, n);
  x_.head<5>() = x0;
  P_.topLeftCorner<5, 5>() = P0;
  for (std::size_t j = 0; j < sensors.size(); ++j) {
    const int c = 5 + 2 * static_cast<int>(j);
    x_.segment<2>(c) = sensors[j].p_SinW_m.head<2>();
    P_(c, c) = P_(c + 1, c + 1) = sensors[j].sigma_xy_m * sensors[j].sigma_xy_m;
  }
}

int LocalizerEkf::Column(std::uint32_t sensor_id) const {
  for (std::size_t j = 0; j < sensors_.size(); ++j) {
    if (sensors_[j].sensor_id == sensor_id) return 5 + 2 * static_cast<int>(j);
  }
  return -1;
}

bool LocalizerEkf::Predict(double t_s) {
  if (!std::isfinite(t_s) || t_s < t_s_) return false;
  const double dt = t_s - t_s_;
  if (dt == 0.0) return true;
  VesselCovariance F;
  const VesselVector x_new = PropagateVessel(x_.head<5>(), dt, &F);
  const int n = static_cast<int>(x_.size());
  // Only the vessel rows and columns change: P_vv = F P_vv Fᵀ + Q, P_sv = P_sv Fᵀ
  // (lower storage: the sensor-vessel block is below the vessel block).
  const VesselCovariance Pvv = P_.topLeftCorner<5, 5>();  // kept full
  const VesselCovariance Pvv_new = F * Pvv * F.transpose() + ProcessCovariance(options_.process, dt);
  // A step no float can hold (t 1e300 s ahead): refused, nothing changed.
  if (!x_new.allFinite() || !F.allFinite() || !Pvv_new.allFinite()) return false;
  x_.head<5>() = x_new;
  P_.topLeftCorner<5, 5>() = 0.5 * (Pvv_new + Pvv_new.transpose());
  if (n > 5) P_.bottomLeftCorner(n - 5, 5) = P_.bottomLeftCorner(n - 5, 5) * F.transpose();
  t_s_ = t_s;
  return true;
}

void LocalizerEkf::JosephUpdate(const Eigen::MatrixXd& U, const Eigen::MatrixXd& K, const Eigen::MatrixXd& L_S) {
  // (I − KH) P (I − KH)ᵀ + K R Kᵀ = P − K Uᵀ − U Kᵀ + K S Kᵀ, U = P Hᵀ,
  // K S Kᵀ = W Wᵀ with W = K L_S (S = L_S L_Sᵀ). One pass over the lower
  // triangle (the only part stored; see Columns), column by column so each
  // column's tail stays in cache: O(n²) flops and one sweep of memory.
  const Eigen::MatrixXd W = K * L_S;
  const Eigen::Index n = P_.rows();
  for (Eigen::Index j = 0; j < n; ++j) {
    const Eigen::Index m = n - j;
    auto col = P_.col(j).tail(m);
    col.noalias() -= K.bottomRows(m) * U.row(j).transpose();
    col.noalias() -= U.bottomRows(m) * K.row(j).transpose();
    col.noalias() += W.bottomRows(m) * W.row(j).transpose();
  }
  // The vessel block is kept full (Predict and Columns read it whole).
  P_.topLeftCorner<5, 5>().triangularView<Eigen::StrictlyUpper>() = P_.topLeftCorner<5, 5>().transpose();
}

Eigen::MatrixXd LocalizerEkf::Columns(int c, int w) const {
  // Lower storage: rows < c of columns c.. are the transposed rows c.. left of c.
  const int n = static_cast<int>(P_.rows());
  Eigen::MatrixXd out(n, w);
  out.topRows(c) = P_.block(c, 0, w, c).transpose();
  out.bottomRows(n - c) = P_.block(c, c, n - c, w);
  for (int a = 0; a < w; ++a) {
    for (int b = a + 1; b < w; ++b) out(c + a, b) = out(c + b, a);
  }
  return out;
}

Eigen::MatrixXd LocalizerEkf::covariance() const { return P_.selfadjointView<Eigen::Lower>(); }

bool LocalizerEkf::Gate(double nis, double threshold, GateState* stream, double* inflate) {
  last_nis_ = nis;
  *inflate = 1.0;
  if (!std::isfinite(nis)) {
    last_outcome_ = Outcome::kFailed;
    return false;
  }
  if (nis <= threshold) {
    *stream = GateState{};  // closes an open gate
  } else if (stream->open) {
    ++gate_releases_;
  } else if (options_.gate_release_after > 0 && stream->refused_in_a_row >= options_.gate_release_after) {
    // A run of refusals: the filter, not the data, is off (the linearised S
    // of the first passes over a sensor metres off understates its
    // innovations). Open this stream's gate until an update fits again.
    stream->open = true;
    ++gate_releases_;
  } else {
    ++stream->refused_in_a_row;
    ++(stream == &gnss_gate_ ? rejected_gnss_ : rejected_magnetometer_);
    last_outcome_ = Outcome::kRejected;
    return false;
  }
  // Released beyond the gate: the linearised S understates this innovation
  // by at least nis / threshold; the update is applied with S scaled so.
  if (nis > threshold) *inflate = nis / threshold;
  last_outcome_ = Outcome::kApplied;
  return true;
}

bool LocalizerEkf::Update(const MagSample& sample) {
  last_outcome_ = Outcome::kFailed;
  const int c = Column(sample.sensor_id);
  if (c < 0 || !sample.B_T.allFinite() || !Predict(sample.t_s)) return false;
  const int j = (c - 5) / 2;
  const Eigen::Vector3d p_S(x_[c], x_[c + 1], sensors_[static_cast<std::size_t>(j)].p_SinW_m.z());
  Jacobian3x5 Hv;
  Jacobian3x2 Hs;
  const Eigen::Vector3d predicted = VesselFieldAtSensor(x_.head<5>(), vessel_, p_S, &Hv, &Hs);
  // U = P Hᵀ touches only the vessel and this sensor's columns of P.
  Eigen::MatrixXd U = Columns(0, 5) * Hv.transpose() + Columns(c, 2) * Hs.transpose();
  Eigen::Matrix3d S = Hv * U.topRows<5>() + Hs * U.middleRows<2>(c);
  S = 0.5 * (S + S.transpose()).eval();
  S.diagonal().array() += options_.sigma_B_T * options_.sigma_B_T;
  Eigen::LLT<Eigen::Matrix3d> llt(S);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::Vector3d innovation = sample.B_T - predicted;
  double inflate = 1.0;
  if (!Gate(innovation.dot(llt.solve(innovation)), gate_magnetometer_nis_,
            &magnetometer_gate_[static_cast<std::size_t>(j)], &inflate)) {
    return false;
  }
  if (inflate > 1.0) llt.compute(inflate * S);
  Eigen::MatrixXd K = llt.solve(U.transpose()).transpose();
  if (!K.allFinite()) {
    last_outcome_ = Outcome::kFailed;
    return false;
  }
  Eigen::VectorXd x_post = x_ + K * innovation;
  // Iterated update: relinearise at x_post (the field and its Jacobians at
  // the updated vessel and sensor state), x_post = x + K_i (z − h(x_i) −
  // H_i (x − x_i)), with K_i, S_i from H_i and the prior P.
  for (int it = 1; it < options_.magnetometer_iterations; ++it) {
    const Eigen::Vector3d p_Si(x_post[c], x_post[c + 1], p_S.z());
    const Eigen::Vector3d h_i = VesselFieldAtSensor(x_post.head<5>(), vessel_, p_Si, &Hv, &Hs);
    const Eigen::MatrixXd U_i = Columns(0, 5) * Hv.transpose() + Columns(c, 2) * Hs.transpose();
    Eigen::Matrix3d S_i = Hv * U_i.topRows<5>() + Hs * U_i.middleRows<2>(c);
    S_i = 0.5 * (S_i + S_i.transpose()).eval();
    S_i.diagonal().array() += options_.sigma_B_T * options_.sigma_B_T;
    const Eigen::LLT<Eigen::Matrix3d> llt_i(inflate * S_i);
    if (llt_i.info() != Eigen::Success) break;
    const Eigen::Vector3d r_i = sample.B_T - h_i - Hv * (x_.head<5>() - x_post.head<5>()) -
                                Hs * (x_.segment<2>(c) - x_post.segment<2>(c));
    const Eigen::MatrixXd K_i = llt_i.solve(U_i.transpose()).transpose();
    if (!K_i.allFinite() || !r_i.allFinite()) break;
    const Eigen::VectorXd x_next = x_ + K_i * r_i;
    const double step = (x_next - x_post).head<2>().norm() + (x_next - x_post).segment<2>(c).norm();
    x_post = x_next;
    K = K_i;
    U = U_i;
    llt = llt_i;
    if (step < 1e-3) break;
  }
  x_ = x_post;
  JosephUpdate(U, K, llt.matrixL().toDenseMatrix());
  return true;
}

bool LocalizerEkf::Update(const GnssFix& fix) {
  last_outcome_ = Outcome::kFailed;
  const double sigma = GnssSigma(fix, options_);
  if (!(sigma > 0.0) || !fix.p_xy_m.allFinite() || !Predict(fix.t_s)) return false;
  const Eigen::MatrixXd U = Columns(0, 2);  // H = [I2 0]
  Eigen::Matrix2d S = U.topRows<2>();
  S = 0.5 * (S + S.transpose()).eval();
  S.diagonal().array() += sigma * sigma;
  Eigen::LLT<Eigen::Matrix2d> llt(S);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::Vector2d innovation = fix.p_xy_m - x_.head<2>();
  double inflate = 1.0;
  if (!Gate(innovation.dot(llt.solve(innovation)), gate_gnss_nis_, &gnss_gate_, &inflate)) return false;
  if (inflate > 1.0) llt.compute(inflate * S);
  const Eigen::MatrixXd K = llt.solve(U.transpose()).transpose();
  if (!K.allFinite()) {
    last_outcome_ = Outcome::kFailed;
    return false;
  }
  x_.noalias() += K * innovation;
  JosephUpdate(U, K, llt.matrixL().toDenseMatrix());
  return true;
}

std::vector<SensorEstimate> LocalizerEkf::SensorEstimates() const {
  std::vector<SensorEstimate> out;
  for (std::size_t j = 0; j < sensors_.size(); ++j) {
    const int c = 5 + 2 * static_cast<int>(j);
    SensorEstimate e;
    e.sensor_id = sensors_[j].sensor_id;
    e.p_SinW_m = {x_[c], x_[c + 1], sensors_[j].p_SinW_m.z()};
    e.cov_xy_m2 << P_(c, c), P_(c + 1, c), P_(c + 1, c), P_(c + 1, c + 1);
    out.push_back(e);
  }
  return out;
}

namespace {
Localization RunStream(const Pass& pass, const LocalizerOptions& options, const StreamOptions& whole_file);
}  // namespace

Localization RunEkf(const Pass& pass, const LocalizerOptions& options) {
  StreamOptions whole_file;
  whole_file.reorder_delay_s = std::numeric_limits<double>::infinity();  // everything at Flush
  return RunStream(pass, options, whole_file);
}

Localization RunEkfBounded(const Pass& pass, const LocalizerOptions& options, const IncrementalCrlbOptions& bound) {
  StreamOptions whole_file;
  whole_file.reorder_delay_s = std::numeric_limits<double>::infinity();  // everything at Flush
  whole_file.bounded = true;
  whole_file.bound = bound;
  return RunStream(pass, options, whole_file);
}

namespace {
Localization RunStream(const Pass& pass, const LocalizerOptions& options, const StreamOptions& whole_file) {
  const auto t0 = std::chrono::steady_clock::now();
  StreamingLocalizer s(pass.vessel, pass.sensors, options, whole_file);
  std::size_t g = 0;
  for (const MagSample& m : pass.samples) {
    while (g < pass.gnss.size() && pass.gnss[g].t_s <= m.t_s) s.Add(pass.gnss[g++]);
    s.Add(m);
  }
  while (g < pass.gnss.size()) s.Add(pass.gnss[g++]);
  s.Flush();
  if (!s.initialized()) {
    throw InputError("localizer: the vessel's start is unknown: the EKF needs at least two GNSS fixes spanning "
                     "2 s within 10 s of the first sample, or a given start (--vessel-start X,Y,SPEED,HEADING)");
  }
  Localization out = s.Result();
  out.summary.solve_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() - out.summary.crlb_time_s;
  return out;
}
}  // namespace

void LocalizerEkf::SaveState(StateWriter& w) const {
  w.F64(t_s_);
  w.Matrix(x_);
  w.Matrix(P_);  // as stored: the lower triangle is the covariance
  w.F64(last_nis_);
  w.U64(magnetometer_gate_.size());
  for (const GateState& g : magnetometer_gate_) {
    w.I64(g.refused_in_a_row);
    w.U8(g.open ? 1 : 0);
  }
  w.I64(gnss_gate_.refused_in_a_row);
  w.U8(gnss_gate_.open ? 1 : 0);
  w.U8(static_cast<std::uint8_t>(last_outcome_));
  w.U64(rejected_magnetometer_);
  w.U64(rejected_gnss_);
  w.U64(gate_releases_);
}

void LocalizerEkf::RestoreState(StateReader& r) {
  const std::size_t n = 5 + 2 * sensors_.size();
  const double t = r.F64();
  Eigen::MatrixXd x = r.Matrix(n, 1), P = r.Matrix(n, n);
  if (static_cast<std::size_t>(x.rows()) != n || x.cols() != 1 || static_cast<std::size_t>(P.rows()) != n ||
      static_cast<std::size_t>(P.cols()) != n) {
    throw CheckpointError("corrupt: EKF state of another size");
  }
  const double nis = r.F64();
  if (r.Count(sensors_.size()) != sensors_.size()) throw CheckpointError("corrupt: EKF gates of another size");
  auto gate = [&r] {
    GateState g;
    g.refused_in_a_row = static_cast<int>(r.I64());
    g.open = r.U8() != 0;
    return g;
  };
  std::vector<GateState> mag(sensors_.size());
  for (GateState& g : mag) g = gate();
  const GateState gnss = gate();
  const std::uint8_t outcome = r.U8();
  if (outcome > static_cast<std::uint8_t>(Outcome::kFailed)) throw CheckpointError("corrupt: EKF outcome");
  const std::uint64_t rej_mag = r.U64(), rej_gnss = r.U64(), releases = r.U64();
  t_s_ = t;
  x_ = x.col(0);
  P_ = std::move(P);
  last_nis_ = nis;
  magnetometer_gate_ = std::move(mag);
  gnss_gate_ = gnss;
  last_outcome_ = static_cast<Outcome>(outcome);
  rejected_magnetometer_ = rej_mag;
  rejected_gnss_ = rej_gnss;
  gate_releases_ = releases;
}

}  // namespace magnav::localizer
