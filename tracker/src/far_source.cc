#include "magnav/tracker/far_source.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <memory>
#include <sstream>

#include "magnav/core/checkpoint.h"
#include "quiet_sample.h"
#include "state_io.h"

namespace magnav::tracker {
namespace {

constexpr double kMu0Over4Pi = 1e-7;
// The moment is solved in units of 1e5 A·m² (a ship's), so that the solver's
// parameters are of order one.
constexpr double kMomentUnit = 1e5;
// Fewer sensors than this: no fit. The model is an array's (its bound is
// from the array's extent; with one sensor it would be 10 m from it and
// take the near vessel itself), and 8 parameters need B at several sensors.
constexpr std::size_t kMinSensors = 4;

bool Fail(std::string* error, const std::string& why) {
  if (error != nullptr) *error = "far_source: " + why;
  return false;
}

// Horizontal position on the line (see far_source.h) at t.
template <typename T>
void LinePosition(const T* g, const Eigen::Vector2d& c, double dt, T* x, T* y) {
  const T& d = g[0];
  const T& th = g[1];
  const T along = g[2] + g[3] * dt;
  using std::cos;
  using std::sin;
  *x = c.x() + d * cos(th) - along * sin(th);
  *y = c.y() + d * sin(th) + along * cos(th);
}

// One sample's whitened residual: (r − B_far)/σ.
struct FarSampleCost {
  FarSampleCost(const FarSourceSample& s, const Eigen::Vector2d& c, double t_ref) : s_(s), c_(c), dt_(s.t_s - t_ref) {}
  template <typename T>
  bool operator()(const T* g, const T* m, T* res) const {
    T px, py;
    LinePosition(g, c_, dt_, &px, &py);
    const T rx = s_.p_SinW.x() - px, ry = s_.p_SinW.y() - py, rz = s_.p_SinW.z() - g[4];
    const T r2 = rx * rx + ry * ry + rz * rz;
    using std::sqrt;
    const T r = sqrt(r2);
    const T r3 = r2 * r, r5 = r3 * r2;
    const T mx = m[0] * kMomentUnit, my = m[1] * kMomentUnit, mz = m[2] * kMomentUnit;
    const T mr = mx * rx + my * ry + mz * rz;
    const T k = T(kMu0Over4Pi);
    const T Bx = k * (T(3) * mr * rx / r5 - mx / r3);
    const T By = k * (T(3) * mr * ry / r5 - my / r3);
    const T Bz = k * (T(3) * mr * rz / r5 - mz / r3);
    res[0] = (s_.r_W.x() - Bx) / s_.sigma_T;
    res[1] = (s_.r_W.y() - By) / s_.sigma_T;
    res[2] = (s_.r_W.z() - Bz) / s_.sigma_T;
    return true;
  }
  FarSourceSample s_;
  Eigen::Vector2d c_;
  double dt_;
};

// B = G(r) m: G = μ0/4π (3 r rᵀ/r⁵ − I/r³).
Eigen::Matrix3d DipoleGain(const Eigen::Vector3d& r) {
  const double r2 = r.squaredNorm(), r1 = std::sqrt(r2), r3 = r2 * r1, r5 = r3 * r2;
  return kMu0Over4Pi * (3.0 * r * r.transpose() / r5 - Eigen::Matrix3d::Identity() / r3);
}

Eigen::Vector3d Position(const double* g, const Eigen::Vector2d& c, double dt) {
  double x, y;
  LinePosition(g, c, dt, &x, &y);
  return {x, y, g[4]};
}

// The moment that best fits the samples from the line g (least squares),
// and its whitened cost. False if singular.
bool LinearMoment(const std::vector<FarSourceSample>& samples, const double* g, const Eigen::Vector2d& c, double t_ref,
                  Eigen::Vector3d* m, double* cost) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double rr = 0.0;
  for (const FarSourceSample& s : samples) {
    const Eigen::Vector3d r = s.p_SinW - Position(g, c, s.t_s - t_ref);
    if (!(r.squaredNorm() > 1e-6)) return false;
    const Eigen::Matrix3d G = DipoleGain(r) / s.sigma_T;
    const Eigen::Vector3d z = s.r_W / s.sigma_T;
    A += G.transpose() * G;
    b += G.transpose() * z;
    rr += z.squaredNorm();
  }
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(A);
  if (ldlt.info() != Eigen::Success || !(A.trace() > 0.0)) return false;
  *m = ldlt.solve(b);
  if (!m->allFinite()) return false;
  *cost = rr - 2.0 * m->dot(b) + m->dot(A * *m);
  return std::isfinite(*cost);
}

}  // namespace

const char* FarSourceRefusalName(FarSourceRefusal r) {
  switch (r) {
    case FarSourceRefusal::kNoFit:
      return "no fit";
    case FarSourceRefusal::kSmallMoment:
      return "moment below a ship's";
    case FarSourceRefusal::kAtBound:
      return "at the bound";
    case FarSourceRefusal::kWeakField:
      return "field too weak";
    case FarSourceRefusal::kLargeMoment:
      return "moment above a ship's";
    case FarSourceRefusal::kNone:
      break;
  }
  return "accepted";
}

std::string FarSourceStats::BriefReport() const {
  std::ostringstream o;
  o << "far source: " << num_fits << " fits (" << num_accepted << " accepted, "
    << num_fits - num_accepted << " refused: " << num_refused_moment << " moment below a ship's, " << num_refused_bound
    << " at the bound, " << num_refused_weak << " field too weak, " << num_refused_no_fit << " no fit; "
    << num_grid_searches << " grid searches), its B removed for " << std::fixed << std::setprecision(1) << active_s
    << " s of data";
  if (num_refused_large > 0) o << "; " << num_refused_large << " refused: moment above a ship's";
  if (num_pre_track_corrected + num_pre_track_occupied + num_pre_track_already_tracked > 0) {
    o << "; kept samples from before a track's start (counted per fit): " << num_pre_track_corrected
      << " given its back-predicted B, " << num_pre_track_occupied << " left out as occupied, "
      << num_pre_track_already_tracked << " not given it (its vessel tracked then)";
  }
  if (has_accepted) {
    o << "; last accepted at t " << last_t_s << " s: (" << last_p_W.x() << ", " << last_p_W.y() << ", "
      << last_p_W.z() << ") m NED, " << last_range_m << " m from the sensors' centroid, " << std::setprecision(2)
      << std::scientific << last_moment_Am2 << " A m^2";
  }
  return o.str();
}

bool FarSourceOptions::IsValid(std::string* error) const {
  if (!(window_s > 0.0) || !std::isfinite(window_s)) return Fail(error, "window_s must be > 0");
  if (!(solve_interval_s > 0.0) || !std::isfinite(solve_interval_s)) return Fail(error, "solve_interval_s must be > 0");
  if (max_samples < 10) return Fail(error, "max_samples must be >= 10");
  if (!(sample_interval_s >= 0.0) || !std::isfinite(sample_interval_s)) return Fail(error, "sample_interval_s must be >= 0");
  if (!(min_span_s >= 0.0) || !(min_span_s <= window_s)) return Fail(error, "min_span_s must be in [0, window_s]");
  if (!(extent_factor >= 0.0) || !std::isfinite(extent_factor)) return Fail(error, "extent_factor must be >= 0");
  if (!(margin_m >= 0.0) || !std::isfinite(margin_m)) return Fail(error, "margin_m must be >= 0");
  if (!(max_range_m > 0.0) || !std::isfinite(max_range_m)) return Fail(error, "max_range_m must be > 0");
  if (!(max_height_m > 0.0) || !std::isfinite(max_height_m)) return Fail(error, "max_height_m must be > 0");
  if (!(loss_sigmas > 0.0) || !std::isfinite(loss_sigmas)) return Fail(error, "loss_sigmas must be > 0");
  if (!(tensor_gate > 0.0)) return Fail(error, "tensor_gate must be > 0");
  if (!(occupied_tensor_snr >= 0.0)) return Fail(error, "occupied_tensor_snr must be >= 0 (0 = off)");
  if (!(model_share >= 0.0) || !std::isfinite(model_share)) return Fail(error, "model_share must be >= 0");
  if (!(unexplained_sigma_T >= 0.0) || !std::isfinite(unexplained_sigma_T)) {
    return Fail(error, "unexplained_sigma_T must be >= 0 (0 = off)");
  }
  if (!(min_field_T >= 0.0) || !std::isfinite(min_field_T)) return Fail(error, "min_field_T must be >= 0");
  if (!(min_moment_Am2 >= 0.0) || !std::isfinite(min_moment_Am2)) return Fail(error, "min_moment_Am2 must be >= 0");
  if (!(bound_slack_m >= 0.0) || !std::isfinite(bound_slack_m)) return Fail(error, "bound_slack_m must be >= 0");
  if (!(max_moment_Am2 >= 0.0) || !std::isfinite(max_moment_Am2)) return Fail(error, "max_moment_Am2 must be >= 0 (0 = off)");
  if (max_moment_Am2 > 0.0 && max_moment_Am2 < min_moment_Am2) {
    return Fail(error, "max_moment_Am2 must be >= min_moment_Am2 (or 0 = off)");
  }
  if (!(bound_accept_moment_Am2 >= 0.0) || !std::isfinite(bound_accept_moment_Am2)) {
    return Fail(error, "bound_accept_moment_Am2 must be >= 0 (0 = off)");
  }
  if (!(max_interval_s >= solve_interval_s) || !std::isfinite(max_interval_s)) {
    return Fail(error, "max_interval_s must be >= solve_interval_s (equal: no back-off)");
  }
  if (!(along_extent_m >= 0.0) || !std::isfinite(along_extent_m)) return Fail(error, "along_extent_m must be >= 0");
  if (!(along_step_m > 0.0) || !std::isfinite(along_step_m)) return Fail(error, "along_step_m must be > 0");
  if (along_extent_m / along_step_m > 100.0) return Fail(error, "along_extent_m / along_step_m must be <= 100");
  return drift.IsValid(error);
}

bool TrackedWhenKept(const Eigen::Vector3d& p_then_W, const std::vector<Eigen::Vector3d>& p_tracked_W,
                     double same_vessel_m) {
  for (const Eigen::Vector3d& p : p_tracked_W) {
    if ((p.head<2>() - p_then_W.head<2>()).norm() < same_vessel_m) return true;
  }
  return false;
}

Eigen::Vector3d FarSourceModel::PositionAt(double t_s) const {
  const double g[5] = {d_m, theta_rad, a0_m, u_mps, z_m};
  return Position(g, centroid, t_s - t_ref_s);
}

Eigen::Vector3d FarSourceModel::BAt(const Eigen::Vector3d& p_SinW, double t_s) const {
  if (!valid) return Eigen::Vector3d::Zero();
  return DipoleGain(p_SinW - PositionAt(t_s)) * m_W;
}

double FarSourceModel::RangeAt(double t_s) const { return (PositionAt(t_s).head<2>() - centroid).norm(); }

double FarSourceMinRange(const std::vector<Eigen::Vector3d>& sensors, const FarSourceOptions& options,
                         Eigen::Vector2d* centroid) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : sensors) c += p.head<2>();
  if (!sensors.empty()) c /= static_cast<double>(sensors.size());
  double R = 0.0;
  for (const auto& p : sensors) R = std::max(R, (p.head<2>() - c).norm());
  if (centroid != nullptr) *centroid = c;
  return options.extent_factor * R + options.margin_m;
}

FarSourceModel FitFarSource(const std::vector<FarSourceSample>& samples, const std::vector<Eigen::Vector3d>& sensors,
                            const FarSourceOptions& options, const FarSourceModel* warm, bool search_grid,
                            bool* searched) {
  FarSourceModel out;
  if (searched != nullptr) *searched = false;
  if (samples.size() < 10 || sensors.size() < kMinSensors) return out;
  Eigen::Vector2d c;
  const double r_min = FarSourceMinRange(sensors, options, &c);
  const double r_max = std::max(options.max_range_m, r_min + 1.0);
  double cz = 0.0;
  for (const auto& p : sensors) cz += p.z();
  cz /= static_cast<double>(sensors.size());
  double t0 = samples.front().t_s, t1 = t0;
  for (const auto& s : samples) {
    t0 = std::min(t0, s.t_s);
    t1 = std::max(t1, s.t_s);
  }
  const double t_ref = t1;  // the newest sample: what is removed next is near it
  // Starts: a grid of lines (moment solved at each) on a coarse subset (every
  // 4th sample, at most ~200: the grid only ranks starts), and the previous
  // fit moved to this t_ref.
  std::vector<FarSourceSample> coarse;
  const std::size_t stride = std::max<std::size_t>(4, (samples.size() + 199) / 200);
  for (std::size_t i = 0; i < samples.size(); i += stride) coarse.push_back(samples[i]);
  struct Start {
    double g[5];
    double cost;
  };
  std::vector<Start> starts;  // the warm start (if any) first, then the grid's best
  const auto cost_of = [&](const double* g, double* cost) {
    Eigen::Vector3d m;
    return LinearMoment(coarse, g, c, t_ref, &m, cost);
  };
  const double z_hi = cz + options.max_height_m;
  const double z0 = std::clamp(cz - 12.0, cz - options.max_height_m, z_hi);
  bool warm_fits = false;
  if (warm != nullptr && warm->valid) {
    // The same line at this t_ref: the along-track position moves with u.
    double d = std::clamp(warm->d_m, r_min, r_max);
    Start st{{d, warm->theta_rad, warm->a0_m + warm->u_mps * (t_ref - warm->t_ref_s), warm->u_mps,
              std::clamp(warm->z_m, cz - options.max_height_m, z_hi)},
             0.0};
    if (cost_of(st.g, &st.cost)) {
      starts.push_back(st);
      // A far ship's line changes little from one fit to the next: it still
      // fits when its whitened RMS per axis is at most 1.5 on these samples.
      warm_fits = st.cost <= 1.5 * 1.5 * 3.0 * static_cast<double>(coarse.size());
    }
  }
  // The grid when there is no previous fit, it no longer fits, or it was
  // refused (its basin may be a wrong one: a mirror of the ship, or a
  // source pressed against the bound while the ship is still far along its
  // line). Three grid nodes are refined: the best, the best whose line's
  // normal differs from it by more than 45° (the other side of the array),
  // and the best on about the same line whose along-line position differs by
  // more than two grid steps (the other end of the line: a ship far along its
  // line and its mirror about the line's closest point fit nearly alike).
  if (!warm_fits || search_grid) {
    if (searched != nullptr) *searched = true;
    constexpr int kAngles = 16;
    const int n_along = static_cast<int>(std::floor(options.along_extent_m / options.along_step_m + 1e-9));
    std::vector<Start> grid;
    for (int k = 0; k < kAngles; ++k) {
      const double th = 2.0 * M_PI * k / kAngles;
      for (double dd : {20.0, 70.0, 150.0}) {
        const double d = std::min(r_min + dd, r_max);
        for (int ia = -n_along; ia <= n_along; ++ia) {
          for (double u : {-3.0, 0.0, 3.0}) {
            Start st{{d, th, ia * options.along_step_m, u, z0}, 0.0};
            if (cost_of(st.g, &st.cost)) grid.push_back(st);
          }
        }
      }
    }
    std::sort(grid.begin(), grid.end(), [](const Start& a, const Start& b) { return a.cost < b.cost; });
    if (!grid.empty()) {
      const Start& best = grid.front();
      starts.push_back(best);
      bool other_side = false, other_end = false;
      for (const Start& st : grid) {
        const bool turned = std::abs(std::remainder(st.g[1] - best.g[1], 2.0 * M_PI)) > M_PI / 4.0 + 1e-9;
        if (turned && !other_side) {
          starts.push_back(st);
          other_side = true;
        } else if (!turned && !other_end && std::abs(st.g[2] - best.g[2]) > 2.0 * options.along_step_m + 1e-9) {
          starts.push_back(st);
          other_end = true;
        }
        if (other_side && other_end) break;
      }
    }
  }
  if (starts.empty()) return out;
  // Refines a start (g, and the moment solved linearly from it) over `set`;
  // its final cost, +inf if it failed.
  const auto refine = [&](const std::vector<FarSourceSample>& set, double* g, double* mu) {
    Eigen::Vector3d m;
    double cost0;
    if (!LinearMoment(set, g, c, t_ref, &m, &cost0)) return std::numeric_limits<double>::infinity();
    mu[0] = m.x() / kMomentUnit;
    mu[1] = m.y() / kMomentUnit;
    mu[2] = m.z() / kMomentUnit;
    ceres::Problem::Options popt;
    popt.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(popt);
    ceres::HuberLoss huber(options.loss_sigmas);
    ceres::CauchyLoss cauchy(options.loss_sigmas);
    ceres::LossFunction* loss = nullptr;  // trivial
    if (options.loss == LossType::kHuber) loss = &huber;
    if (options.loss == LossType::kCauchy) loss = &cauchy;
    for (const FarSourceSample& s : set) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<FarSampleCost, 3, 5, 3>(new FarSampleCost(s, c, t_ref)), loss, g, mu);
    }
    // The bound that keeps the source out of the array: a hard bound of the
    // solver (its steps are projected onto it), not a penalty.
    problem.SetParameterLowerBound(g, 0, r_min);
    problem.SetParameterUpperBound(g, 0, r_max);
    problem.SetParameterLowerBound(g, 4, cz - options.max_height_m);
    problem.SetParameterUpperBound(g, 4, z_hi);
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = 30;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary sum;
    ceres::Solve(so, &problem, &sum);
    if (!(sum.final_cost >= 0.0) || !std::isfinite(sum.final_cost)) return std::numeric_limits<double>::infinity();
    return sum.final_cost;
  };
  // One start: refined over every sample. Several: each refined over the
  // coarse subset, and the one of lowest cost then over every sample.
  double best_g[5];
  double best_mu[3];
  double best_cost = std::numeric_limits<double>::infinity();
  if (starts.size() > 1) {
    for (const Start& st : starts) {
      double g[5], mu[3];
      std::copy(st.g, st.g + 5, g);
      const double cost = refine(coarse, g, mu);
      if (cost < best_cost) {
        best_cost = cost;
        std::copy(g, g + 5, best_g);
      }
    }
  } else {
    std::copy(starts.front().g, starts.front().g + 5, best_g);
  }
  best_cost = refine(samples, best_g, best_mu);
  if (!std::isfinite(best_cost)) return out;
  const double* g = best_g;
  const double* mu = best_mu;
  out.valid = true;
  out.t_ref_s = t_ref;
  out.centroid = c;
  out.min_range_m = r_min;
  out.d_m = g[0];
  out.theta_rad = std::remainder(g[1], 2.0 * M_PI);
  out.a0_m = g[2];
  out.u_mps = g[3];
  out.z_m = g[4];
  out.m_W = Eigen::Vector3d(mu[0], mu[1], mu[2]) * kMomentUnit;
  out.num_samples = static_cast<int>(samples.size());
  out.t_first_s = t0;
  out.t_last_s = t1;
  double ss = 0.0;
  for (const FarSourceSample& s : samples) ss += ((s.r_W - out.BAt(s.p_SinW, s.t_s)) / s.sigma_T).squaredNorm();
  out.rms_whitened = std::sqrt(ss / (3.0 * static_cast<double>(samples.size())));
  return out;
}

bool FarSourceEstimator::WantsEpoch(double t_s) const {
  return options_.enabled && t_s - last_kept_t_ >= options_.sample_interval_s - 1e-6;
}

void FarSourceEstimator::AddEpoch(double t_s, const std::vector<FarSourceSample>& used,
                                  const std::vector<Eigen::Vector3d>& sensors,
                                  const std::vector<Eigen::Vector3d>& p_tracked_W) {
  if (!options_.enabled) return;
  // The time its B was removed from: the kept epochs' spacing while active.
  if (active_ && std::isfinite(last_kept_t_) && t_s > last_kept_t_) stats_.active_s += t_s - last_kept_t_;
  last_kept_t_ = t_s;
  if (!sensors.empty()) sensors_ = sensors;
  kept_.push_back({t_s, used, p_tracked_W});
  while (!kept_.empty() && t_s - kept_.front().t_s > options_.window_s) kept_.pop_front();
  const SensorDriftOptions& d = options_.drift;
  if (d.enabled && t_s - last_drift_kept_t_ >= d.sample_interval_s - 1e-6) {
    last_drift_kept_t_ = t_s;
    drift_kept_.push_back({t_s, used, {}});
    while (!drift_kept_.empty() && t_s - drift_kept_.front().t_s > d.window_s) drift_kept_.pop_front();
  }
}

bool FarSourceEstimator::StepIfDue(double t_s, const PreTrackFieldFn& pre_track) {
  if (!options_.enabled || kept_.empty()) return false;
  if (interval_s_ < 0.0) interval_s_ = options_.solve_interval_s;
  if (t_s - last_fit_t_ < interval_s_ - 1e-6) return false;
  if (kept_.back().t_s - kept_.front().t_s < options_.min_span_s) return false;
  last_fit_t_ = t_s;
  std::vector<FarSourceSample> all;
  const bool correct = options_.back_predict_new_tracks && pre_track;
  for (const Kept& k : kept_) {
    if (!correct) {
      all.insert(all.end(), k.used.begin(), k.used.end());
      continue;
    }
    for (FarSourceSample s : k.used) {
      PreTrackField f;
      pre_track(s, k.p_tracked_W, &f);
      if (f.num_already_tracked > 0) ++stats_.num_pre_track_already_tracked;
      if (f.num_given > 0) {
        // Occupied by the later track's vessel (the quiet store's rule,
        // internal::OccupiedBy, with the sample rules' tensor SNR): left out,
        // not corrected — subtracting a strong back-predicted B moved the fits
        // on the drift files by its error (docs/ACCURACY.md, "The same
        // vessel's B taken out twice ...").
        if (internal::OccupiedBy(f.B_W, f.T_W, s.sigma_T, s.sigma_tensor_Tpm, options_.occupied_tensor_snr)) {
          ++stats_.num_pre_track_occupied;
          continue;
        }
        ++stats_.num_pre_track_corrected;
        s.r_W -= f.B_W;
        s.sigma_T = std::sqrt(s.sigma_T * s.sigma_T + f.var_T2);
      }
      all.push_back(s);
    }
  }
  if (drift_.enabled()) {
    // The drift on the samples minus the previous far source (if removed),
    // then the far source on the samples minus the drift: one block step of
    // each per fit, over successive fits a block coordinate descent.
    std::vector<DriftSample> ds;
    for (const Kept& k : drift_kept_) {
      for (const FarSourceSample& s : k.used) {
        if (s.tracks_B_T > options_.drift.occupied_B_sigmas * s.sigma_T) continue;  // a tracked vessel's B there
        // An untracked near source's B there: its sensor's mean residual tensor.
        if (options_.drift.tensor_mean_window_s > 0.0 && s.residual_tensor_mean_z > options_.drift.tensor_mean_gate) {
          continue;
        }
        const Eigen::Vector3d far = active_ ? model_.BAt(s.p_SinW, s.t_s) : Eigen::Vector3d::Zero();
        ds.push_back({s.sensor_id, s.t_s, s.r_W - far, s.sigma_T});
      }
    }
    drift_.Fit(ds);
    for (FarSourceSample& s : all) s.r_W -= drift_.At(s.sensor_id, s.t_s);
  }
  if (static_cast<int>(all.size()) > options_.max_samples) {
    // An even stride over the samples, the newest kept (what is removed next
    // is near it).
    const double stride = static_cast<double>(all.size()) / static_cast<double>(options_.max_samples);
    std::vector<FarSourceSample> thinned;
    thinned.reserve(static_cast<std::size_t>(options_.max_samples));
    for (int i = options_.max_samples - 1; i >= 0; --i) {
      thinned.push_back(all[all.size() - 1 - static_cast<std::size_t>(std::floor(i * stride))]);
    }
    all.swap(thinned);
  }
  // A refused previous fit is a start, but the grid is searched as well: its
  // basin may be the wrong one.
  const bool search_grid = options_.grid_when_refused && model_.valid && !active_;
  bool searched = false;
  const FarSourceModel fit =
      FitFarSource(all, sensors_, options_, model_.valid ? &model_ : nullptr, search_grid, &searched);
  model_ = fit;
  active_ = false;
  ++stats_.num_fits;
  if (searched) ++stats_.num_grid_searches;
  if (!model_.valid) {
    refusal_ = FarSourceRefusal::kNoFit;
  } else if (model_.m_W.norm() < options_.min_moment_Am2) {
    refusal_ = FarSourceRefusal::kSmallMoment;
  } else if (options_.max_moment_Am2 > 0.0 && model_.m_W.norm() > options_.max_moment_Am2) {
    refusal_ = FarSourceRefusal::kLargeMoment;
  } else if (model_.d_m < model_.min_range_m + options_.bound_slack_m &&
             !(options_.bound_accept_moment_Am2 > 0.0 && model_.m_W.norm() >= options_.bound_accept_moment_Am2)) {
    refusal_ = FarSourceRefusal::kAtBound;
  } else {
    for (const auto& p : sensors_) active_ = active_ || model_.BAt(p, model_.t_last_s).norm() >= options_.min_field_T;
    refusal_ = active_ ? FarSourceRefusal::kNone : FarSourceRefusal::kWeakField;
  }
  switch (refusal_) {
    case FarSourceRefusal::kNone:
      ++stats_.num_accepted;
      stats_.has_accepted = true;
      stats_.last_t_s = model_.t_last_s;
      stats_.last_p_W = model_.PositionAt(model_.t_last_s);
      stats_.last_range_m = model_.RangeAt(model_.t_last_s);
      stats_.last_moment_Am2 = model_.m_W.norm();
      break;
    case FarSourceRefusal::kNoFit:
      ++stats_.num_refused_no_fit;
      break;
    case FarSourceRefusal::kSmallMoment:
      ++stats_.num_refused_moment;
      break;
    case FarSourceRefusal::kAtBound:
      ++stats_.num_refused_bound;
      break;
    case FarSourceRefusal::kWeakField:
      ++stats_.num_refused_weak;
      break;
    case FarSourceRefusal::kLargeMoment:
      ++stats_.num_refused_large;
      break;
  }
  // The back-off: the interval doubles after each refused fit.
  interval_s_ = active_ ? options_.solve_interval_s : std::min(2.0 * interval_s_, options_.max_interval_s);
  return true;
}

Eigen::Vector3d FarSourceEstimator::B(std::uint32_t sensor_id, const Eigen::Vector3d& p_SinW, double t_s,
                                      double* sigma_T) const {
  if (sigma_T != nullptr) *sigma_T = 0.0;
  if (!options_.enabled) return Eigen::Vector3d::Zero();
  double s_drift = 0.0;
  Eigen::Vector3d b = drift_.At(sensor_id, t_s, &s_drift);
  double s_far = 0.0;
  if (active_) {
    const Eigen::Vector3d far = model_.BAt(p_SinW, t_s);
    s_far = options_.model_share * far.norm() / std::sqrt(3.0);
    b += far;
  }
  if (sigma_T != nullptr) *sigma_T = std::hypot(std::hypot(s_far, options_.unexplained_sigma_T), s_drift);
  return b;
}

namespace {

// A 3-vector as every other one in the tracker's checkpoint (state_io.h:
// its shape checked when read).
Eigen::Vector3d GetVector3(StateReader& r) { return internal::GetMatrix(r, 3, 1); }

void PutSample(StateWriter& w, const FarSourceSample& s) {
  w.U32(s.sensor_id);
  w.F64(s.t_s);
  w.Matrix(s.p_SinW);
  w.Matrix(s.r_W);
  for (double v : {s.sigma_T, s.tracks_B_T, s.residual_tensor_mean_z, s.sigma_tensor_Tpm}) w.F64(v);
}
FarSourceSample GetSample(StateReader& r) {
  FarSourceSample s;
  s.sensor_id = r.U32();
  s.t_s = r.F64();
  s.p_SinW = GetVector3(r);
  s.r_W = GetVector3(r);
  s.sigma_T = r.F64();
  s.tracks_B_T = r.F64();
  s.residual_tensor_mean_z = r.F64();
  s.sigma_tensor_Tpm = r.F64();
  return s;
}

template <class Kept>
void PutKept(StateWriter& w, const std::deque<Kept>& kept) {
  w.U64(kept.size());
  for (const Kept& k : kept) {
    w.F64(k.t_s);
    w.U64(k.used.size());
    for (const FarSourceSample& s : k.used) PutSample(w, s);
    w.U64(k.p_tracked_W.size());
    for (const Eigen::Vector3d& p : k.p_tracked_W) w.Matrix(p);
  }
}
template <class Kept>
void GetKept(StateReader& r, std::deque<Kept>* kept) {
  kept->clear();
  for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) {
    Kept k;
    k.t_s = r.F64();
    for (std::size_t m = r.Count(internal::kMaxStateCount); m > 0; --m) k.used.push_back(GetSample(r));
    for (std::size_t m = r.Count(internal::kMaxStateCount); m > 0; --m) k.p_tracked_W.push_back(GetVector3(r));
    kept->push_back(std::move(k));
  }
}

}  // namespace

void FarSourceEstimator::SaveState(StateWriter& w) const {
  PutKept(w, kept_);
  PutKept(w, drift_kept_);
  w.F64(last_drift_kept_t_);
  w.U64(sensors_.size());
  for (const Eigen::Vector3d& p : sensors_) w.Matrix(p);
  w.F64(last_kept_t_);
  w.F64(last_fit_t_);
  const FarSourceModel& m = model_;
  w.U8(m.valid ? 1 : 0);
  for (double v : {m.t_ref_s, m.centroid.x(), m.centroid.y(), m.min_range_m, m.d_m, m.theta_rad, m.a0_m, m.u_mps,
                   m.z_m}) {
    w.F64(v);
  }
  w.Matrix(m.m_W);
  for (double v : {m.rms_whitened, m.t_first_s, m.t_last_s}) w.F64(v);
  w.I64(m.num_samples);
  w.U8(active_ ? 1 : 0);
  drift_.SaveState(w);
  w.U8(static_cast<std::uint8_t>(refusal_));
  w.F64(interval_s_);
  const FarSourceStats& st = stats_;
  for (int v : {st.num_fits, st.num_accepted, st.num_refused_no_fit, st.num_refused_moment, st.num_refused_bound,
                st.num_refused_weak, st.num_refused_large, st.num_grid_searches}) {
    w.I64(v);
  }
  for (long long v : {st.num_pre_track_corrected, st.num_pre_track_occupied, st.num_pre_track_already_tracked}) w.I64(v);
  w.F64(st.active_s);
  w.U8(st.has_accepted ? 1 : 0);
  w.F64(st.last_t_s);
  w.Matrix(st.last_p_W);
  w.F64(st.last_range_m);
  w.F64(st.last_moment_Am2);
}

void FarSourceEstimator::RestoreState(StateReader& r) {
  FarSourceEstimator e(options_);
  GetKept(r, &e.kept_);
  GetKept(r, &e.drift_kept_);
  e.last_drift_kept_t_ = r.F64();
  for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) e.sensors_.push_back(GetVector3(r));
  e.last_kept_t_ = r.F64();
  e.last_fit_t_ = r.F64();
  FarSourceModel& m = e.model_;
  m.valid = r.U8() != 0;
  m.t_ref_s = r.F64();
  m.centroid.x() = r.F64();
  m.centroid.y() = r.F64();
  for (double* v : {&m.min_range_m, &m.d_m, &m.theta_rad, &m.a0_m, &m.u_mps, &m.z_m}) *v = r.F64();
  m.m_W = GetVector3(r);
  m.rms_whitened = r.F64();
  m.t_first_s = r.F64();
  m.t_last_s = r.F64();
  m.num_samples = static_cast<int>(r.I64());
  e.active_ = r.U8() != 0;
  e.drift_.RestoreState(r);
  const std::uint8_t refusal = r.U8();
  if (refusal > static_cast<std::uint8_t>(FarSourceRefusal::kLargeMoment)) {
    throw CheckpointError("corrupt: far source refusal " + std::to_string(refusal));
  }
  e.refusal_ = static_cast<FarSourceRefusal>(refusal);
  e.interval_s_ = r.F64();
  FarSourceStats& st = e.stats_;
  for (int* v : {&st.num_fits, &st.num_accepted, &st.num_refused_no_fit, &st.num_refused_moment,
                 &st.num_refused_bound, &st.num_refused_weak, &st.num_refused_large, &st.num_grid_searches}) {
    *v = static_cast<int>(r.I64());
  }
  for (long long* v : {&st.num_pre_track_corrected, &st.num_pre_track_occupied, &st.num_pre_track_already_tracked}) {
    *v = r.I64();
  }
  st.active_s = r.F64();
  st.has_accepted = r.U8() != 0;
  st.last_t_s = r.F64();
  st.last_p_W = GetVector3(r);
  st.last_range_m = r.F64();
  st.last_moment_Am2 = r.F64();
  *this = std::move(e);
}

}  // namespace magnav::tracker
