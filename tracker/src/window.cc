#include <ceres/solver.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

#include "factors.h"
#include "offset_marginal.h"
#include "sensor_offset.h"
#include "state_io.h"
#include "magnav/core/csv.h"
#include "magnav/core/dipole.h"
#include "magnav/core/error.h"
#include "magnav/core/frames.h"
#include "magnav/core/units.h"
#include "magnav/tracker/cost_functions.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

namespace {

// With sensor_offset.window_lines the variance factor's residual means are
// per sensor and per this many equal parts of the window (ResidualMeansChi2):
// a line takes a sensor's mean over the whole window, not the curvature of
// an untracked vessel's B within it.
constexpr int kLineSegments = 4;

// One epoch inside the window: its state and the factors it owns (its
// measurements and the process factors to the next epoch).
struct WindowEpoch {
  Epoch epoch;
  StateVector x = StateVector::Zero();
  std::vector<internal::Factor> measurements;
  std::vector<internal::Factor> to_next;
};

// Information on [a (6); b (6); m (3)]; eliminating a leaves information on
// [b; m] (Schur complement), returned as H (9×9) and gradient g (9).
void EliminateFirstState(const internal::LocalH& H, const internal::LocalG& g,
                         Eigen::Matrix<double, 9, 9>* H_out, Eigen::Matrix<double, 9, 1>* g_out) {
  const Eigen::Matrix<double, 6, 6> Haa = H.topLeftCorner<6, 6>();
  const Eigen::Matrix<double, 6, 9> Har = H.topRightCorner<6, 9>();
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(Haa);
  *H_out = H.bottomRightCorner<9, 9>() - Har.transpose() * ldlt.solve(Har);
  *g_out = g.tail<9>() - Har.transpose() * ldlt.solve(g.head<6>());
  *H_out = 0.5 * (*H_out + H_out->transpose());
}

// The onset model's shortest segment before and after the onset (s), and the
// walk of its free jump (a σ so large the jump costs nothing).
constexpr double kMinOnsetSegmentS = 1.0;
constexpr double kFreeTurnRateRadpsPerSqrtS = 1e3;

}  // namespace

struct WindowTracker::Impl {
  Eigen::Vector3d B0_W;
  TrackerOptions options;
  std::unique_ptr<ceres::LossFunction> meas_loss, turn_loss;

  // Before a track exists: recent epochs, and fixes handed in, for the
  // initialiser (any_fix: a fix has been handed in, ever).
  std::deque<Epoch> buffer;
  std::deque<DipoleFix> fixes;
  bool any_fix = false;
  // Sample stream: the epoch being filled.
  bool has_pending = false;
  Epoch pending;

  bool initialized = false;
  double moment_scale = 1.0;
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();  // m_B / moment_scale
  Eigen::Matrix3d cov_m_B = Eigen::Matrix3d::Zero();
  std::deque<WindowEpoch> window;
  internal::Factor prior;  // on (window.front().x, moment); cost null = none
  Summary summary;
  int unsolved = 0;  // epochs appended since the last window solve
  double last_solve_t = -std::numeric_limits<double>::infinity();
  int rejected_samples = 0;  // refused at the door (CheckSample)
  int dropped_factors = 0;   // left out of a marginalisation
  // Factorisation of the window at the current estimate (chain solver).
  internal::ChainFactorization chain;
  bool chain_ok = false;
  bool chain_fresh = false;
  // Marginal covariances (every state's, the moment's unscaled) already
  // computed at a solution that is about to be emitted (the turn-onset
  // model's: the default's for the trigger's noise test, the onset model's
  // for its guard); NewestCovariances takes them from `emit_covariance`.
  struct CovarianceCache {
    bool valid = false;
    std::vector<StateCovariance> P;
    Eigen::Matrix3d Pm = Eigen::Matrix3d::Zero();
  };
  CovarianceCache default_covariance, onset_covariance;
  const CovarianceCache* emit_covariance = nullptr;
  // The default solution's factorisation, kept while the onset candidates
  // are solved and put back if the onset model is not chosen.
  internal::ChainFactorization saved_chain;
  bool saved_chain_fresh = false;
  // Per-sensor background offsets added to B0 (SetBackgroundOffsets).
  WindowTracker::BackgroundOffsetFn offsets;
  // The track's own per-sensor B offset over the window (world NED, T;
  // TrackerOptions::sensor_offset), added to B0 and to `offsets`.
  std::map<std::uint32_t, Eigen::Vector3d> own_offsets;
  // sensor_offset.window_score_test: the test has fired on this track (its
  // offsets are solved from then on).
  bool offsets_called = false;
  // sensor_offset.window_score_persist_s: when the test began to fire at
  // every solve (NaN: it did not fire at the last), and the prior folded
  // from the leaving samples' tensors alone, the window's prior at the latch.
  double first_fired_t_s = std::numeric_limits<double>::quiet_NaN();
  internal::Factor tensor_prior;  // on (window.front().x, moment); cost null = none
  // With sensor_offset.window_lines: each sensor's rate (world NED, T/s)
  // about own_offset_t_s, the window's middle time when they were fitted.
  std::map<std::uint32_t, Eigen::Vector3d> own_rates;
  double own_offset_t_s = 0.0;
  // What the samples that left the window say of each sensor's offset
  // (sensor_offset.carry): the window's offsets' prior.
  std::map<std::uint32_t, internal::CarriedOffset> carried_offsets;
  // The sensor's own offset from its quiet data (sensor_offset.quiet;
  // SetSensorOffsetPrior): the window's offsets' prior where it answers.
  WindowTracker::SensorOffsetPriorFn quiet_prior;

  // The track's own offset of a sensor at time t_s (world NED, T).
  Eigen::Vector3d OwnOffset(std::uint32_t sensor_id, double t_s) const {
    const auto it = own_offsets.find(sensor_id);
    if (it == own_offsets.end()) return Eigen::Vector3d::Zero();
    const auto r = own_rates.find(sensor_id);
    return r == own_rates.end() ? it->second : Eigen::Vector3d(it->second + r->second * (t_s - own_offset_t_s));
  }

  // `force`: set every factor's offset even with none (back to zero).
  void ApplyOffsets(WindowEpoch& w, bool force = false) const {
    if (!force && !offsets && own_offsets.empty()) return;
    for (std::size_t i = 0; i < w.measurements.size(); ++i) {
      auto* cost = static_cast<MeasurementCost*>(w.measurements[i].cost.get());
      const std::uint32_t id = w.epoch.samples[i].sensor_id;
      Eigen::Vector3d o = OwnOffset(id, w.epoch.t_s);
      if (offsets) o += offsets(id, w.epoch.t_s);
      cost->SetBackgroundOffset(o);
    }
  }

  // sensor_offset.window_score_test: the score test of a zero offset per
  // sensor over the window at the current solution (the batch's,
  // SensorOffsetAccumulator::Score: 3 dof per sensor) against the
  // batch_variance_factor.quantile point; its χ² and dof go in the summary.
  bool OffsetsCalledFor() {
    std::map<std::uint32_t, internal::SensorOffsetAccumulator> acc;
    for (const WindowEpoch& w : window) {
      for (std::size_t i = 0; i < w.measurements.size(); ++i) {
        const GradiometerSample& smp = w.epoch.samples[i];
        acc[smp.sensor_id].Add(w.measurements[i], SigmaB(smp, options), Eigen::Vector3d::Zero());
      }
    }
    double chi2 = 0.0;
    int dof = 0;
    internal::SumScores(acc, &chi2, &dof);
    summary.offset_score_chi2 = chi2;
    summary.offset_score_dof = dof;
    return internal::ScoreTestFires(chi2, dof, options.batch_variance_factor.quantile);
  }

  // Every sensor's own offset set to its conditional mean given the window's
  // track (sensor_offset.h), the prior σ at the window's middle time.
  void UpdateOwnOffsets() {
    const SensorOffsetOptions& so = options.sensor_offset;
    std::map<std::uint32_t, internal::SensorOffsetAccumulator> acc;
    std::map<std::uint32_t, double> tensor_snr;  // the track's largest predicted, per sensor
    const Eigen::Vector3d m_B = moment * moment_scale;
    for (const WindowEpoch& w : window) {
      for (std::size_t i = 0; i < w.measurements.size(); ++i) {
        const GradiometerSample& smp = w.epoch.samples[i];
        acc[smp.sensor_id].Add(w.measurements[i], SigmaB(smp, options), OwnOffset(smp.sensor_id, w.epoch.t_s));
        if (so.min_tensor_snr > 0.0) {
          double& best = tensor_snr[smp.sensor_id];
          best = std::max(best, internal::PredictedTensorSnr(smp, w.x.data(), m_B, SigmaT(smp, options)));
        }
      }
    }
    const double t_mid = 0.5 * (window.front().epoch.t_s + window.back().epoch.t_s);
    const double sigma = so.PriorSigma(t_mid);
    if (so.window_lines) {
      UpdateOwnLines(t_mid, sigma, tensor_snr);
      return;
    }
    std::map<std::uint32_t, Eigen::Vector3d> next;
    for (const auto& [id, a] : acc) {
      const auto c = so.carry ? carried_offsets.find(id) : carried_offsets.end();
      Eigen::Vector3d quiet_W;
      double quiet_sigma = 0.0;
      const bool quiet = so.quiet && quiet_prior && quiet_prior(id, t_mid, &quiet_W, &quiet_sigma);
      if (so.min_tensor_snr > 0.0 && tensor_snr[id] < so.min_tensor_snr) {
        // Where the tensor does not pin the track the window's samples do not
        // move the offset: the sensor's quiet one, the carried one (the
        // samples that left), or none.
        if (quiet) {
          next[id] = quiet_W;
        } else if (c != carried_offsets.end()) {
          next[id] = c->second.mean_W;
        }
        continue;
      }
      if (quiet) {
        next[id] = a.Mean(quiet_W, quiet_sigma);
        continue;
      }
      next[id] = c == carried_offsets.end()
                     ? a.Mean(sigma)
                     : a.Mean(c->second.mean_W, std::sqrt(c->second.VarianceAt(t_mid, so.max_rate_T_per_s)));
    }
    own_offsets = std::move(next);
    for (WindowEpoch& w : window) ApplyOffsets(w, true);
    chain_fresh = false;
  }

  // sensor_offset.window_lines: every sensor's offset a line in time about
  // t_mid (the level's prior σ level_sigma_T, the rate's
  // line_rate_sigma_T_per_s); a sensor below min_tensor_snr gets none.
  void UpdateOwnLines(double t_mid, double level_sigma_T, const std::map<std::uint32_t, double>& tensor_snr) {
    const SensorOffsetOptions& so = options.sensor_offset;
    std::map<std::uint32_t, internal::LineOffsetAccumulator> acc;
    for (const WindowEpoch& w : window) {
      for (std::size_t i = 0; i < w.measurements.size(); ++i) {
        const GradiometerSample& smp = w.epoch.samples[i];
        acc[smp.sensor_id].Add(w.measurements[i], SigmaB(smp, options), OwnOffset(smp.sensor_id, w.epoch.t_s),
                               w.epoch.t_s - t_mid);
      }
    }
    std::map<std::uint32_t, Eigen::Vector3d> levels, rates;
    for (const auto& [id, a] : acc) {
      if (so.min_tensor_snr > 0.0) {
        const auto it = tensor_snr.find(id);
        if (it == tensor_snr.end() || it->second < so.min_tensor_snr) continue;
      }
      Eigen::Vector3d level, rate;
      if (!a.Solve(level_sigma_T, so.line_rate_sigma_T_per_s, &level, &rate)) continue;
      levels[id] = level;
      rates[id] = rate;
    }
    own_offsets = std::move(levels);
    own_rates = std::move(rates);
    own_offset_t_s = t_mid;
    for (WindowEpoch& w : window) ApplyOffsets(w, true);
    chain_fresh = false;
  }

  void Append(const Epoch& e, const StateVector& x0) {
    if (!window.empty()) {
      WindowEpoch& last = window.back();
      window.emplace_back();
      window.back().x = x0;
      ProcessNoise q = options.process;
      q.turn_rate_radps_per_sqrt_s = q.window_turn_rate_radps_per_sqrt_s;
      q.depth_m_per_sqrt_s = internal::DepthWalk(last.epoch, options);
      internal::AddProcessFactors(e.t_s - last.epoch.t_s, q, turn_loss.get(), last.x.data(),
                                  window.back().x.data(), &last.to_next);
    } else {
      window.emplace_back();
      window.back().x = x0;
    }
    WindowEpoch& w = window.back();
    w.epoch = e;
    internal::AddMeasurementFactors(e, B0_W, options, moment_scale, w.x.data(), moment.data(),
                                    &w.measurements);
    for (auto& f : w.measurements) f.loss = meas_loss.get();
    ApplyOffsets(w);
  }

  // Local system over [front state, second state, moment] from the factors of
  // the front epoch (prior, measurements, process to the next).
  // Returns the number of factors that could not be evaluated (left out).
  int FrontSystem(const WindowEpoch& a, const WindowEpoch* b, internal::LocalH* H, internal::LocalG* g,
                  const internal::Factor* prior_factor) const {
    H->setZero();
    g->setZero();
    const internal::LocalOffset offset{a.x.data(), b != nullptr ? b->x.data() : nullptr, moment.data()};
    int failed = 0;
    if (prior_factor != nullptr && prior_factor->cost && !internal::AccumulateFactor(*prior_factor, offset, H, g))
      ++failed;
    for (const auto& f : a.measurements) failed += internal::AccumulateFactor(f, offset, H, g) ? 0 : 1;
    if (b != nullptr) {
      for (const auto& f : a.to_next) failed += internal::AccumulateFactor(f, offset, H, g) ? 0 : 1;
    }
    return failed;
  }

  // The oldest epoch's samples folded into their sensors' carried offsets
  // (sensor_offset.carry), their residuals at the current estimate.
  void CarryFrontOffsets() {
    const SensorOffsetOptions& so = options.sensor_offset;
    if (!so.window || !so.carry) return;
    const WindowEpoch& a = window.front();
    std::map<std::uint32_t, internal::SensorOffsetAccumulator> acc;
    for (std::size_t i = 0; i < a.measurements.size(); ++i) {
      const GradiometerSample& smp = a.epoch.samples[i];
      acc[smp.sensor_id].Add(a.measurements[i], SigmaB(smp, options), OwnOffset(smp.sensor_id, a.epoch.t_s));
    }
    const double t = a.epoch.t_s;
    for (const auto& [id, s] : acc) {
      if (!(s.information() > 0.0)) continue;
      auto [it, fresh] = carried_offsets.try_emplace(id);
      if (fresh) {  // from the zero-mean prior of the drift model
        const double sigma = so.PriorSigma(t);
        it->second.variance_T2 = sigma * sigma;
        it->second.t_s = t;
      }
      it->second.Update(s, t, so.max_rate_T_per_s);
    }
  }

  // Drops the oldest epoch, folding its information into the prior.
  // The front epoch `a` folded into a prior on the next state `b` and the
  // moment, from the prior `prev`, into *out (empty if it failed).
  void FoldFront(WindowEpoch& a, WindowEpoch& b, const internal::Factor* prev, internal::Factor* out) {
    internal::LocalH H;
    internal::LocalG g;
    // A factor that cannot be evaluated is left out (and counted): its NaN
    // would otherwise live on in the prior and fail every later solve.
    dropped_factors += FrontSystem(a, &b, &H, &g, prev);
    Eigen::Matrix<double, 9, 9> Hm;
    Eigen::Matrix<double, 9, 1> gm;
    EliminateFirstState(H, g, &Hm, &gm);
    if (!Hm.allFinite() || !gm.allFinite()) {
      // Cannot happen with finite factors (the front state's information is
      // positive definite through the process factor); if it does, the window
      // goes on without a prior rather than with a poisoned one.
      ++dropped_factors;
      *out = internal::Factor{};
      return;
    }
    // ½ δᵀHδ + gᵀδ = ½‖Lδ + c‖² + const with H = V Λ Vᵀ, L = Λ^½ Vᵀ,
    // c = Λ^-½ Vᵀ g (directions with no information are dropped).
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(Hm);
    const Eigen::Matrix<double, 9, 1> lam = es.eigenvalues();
    const double floor = std::max(lam.maxCoeff(), 0.0) * 1e-14;
    Eigen::Matrix<double, 9, 9> L = Eigen::Matrix<double, 9, 9>::Zero();
    Eigen::Matrix<double, 9, 1> c = Eigen::Matrix<double, 9, 1>::Zero();
    const Eigen::Matrix<double, 9, 9> Vt = es.eigenvectors().transpose();
    for (int i = 0; i < 9; ++i) {
      if (lam(i) <= floor) continue;
      const double s = std::sqrt(lam(i));
      L.row(i) = s * Vt.row(i);
      c(i) = Vt.row(i).dot(gm) / s;
    }
    Eigen::Matrix<double, 9, 1> x_bar;
    x_bar << b.x, moment;
    internal::Factor next;
    next.cost = std::make_unique<PriorCost>(L, x_bar, c);
    next.blocks = {b.x.data(), moment.data()};
    *out = std::move(next);
  }

  // A prior as PutPrior wrote it, on the window's front state and the moment.
  void GetPrior(StateReader& r, internal::Factor* f) {
    if (r.U8() == 0) return;
    const Eigen::Matrix<double, 9, 9> L = internal::GetMatrix(r, 9, 9);
    const Eigen::Matrix<double, 9, 1> x_bar = internal::GetMatrix(r, 9, 1);
    const Eigen::Matrix<double, 9, 1> c = internal::GetMatrix(r, 9, 1);
    if (window.empty()) throw CheckpointError("corrupt: a window prior without a window");
    f->cost = std::make_unique<PriorCost>(L, x_bar, c);
    f->blocks = {window.front().x.data(), moment.data()};
  }

  // Whether the window keeps its tensor-only prior (window_score_persist_s,
  // which IsValid allows only with the score test and the window's offsets).
  bool KeepTensorPrior() const { return options.sensor_offset.window_score_persist_s > 0.0 && !offsets_called; }

  void MarginalizeFront() {
    CarryFrontOffsets();
    WindowEpoch& a = window[0];
    WindowEpoch& b = window[1];
    // Before the score test latches (window_score_persist_s), the same fold
    // with every leaving sample's B left out, into the tensor-only prior.
    const auto use_field = [&a](std::size_t i, bool used) {
      static_cast<MeasurementCost*>(a.measurements[i].cost.get())->SetFieldUsed(used);
    };
    if (KeepTensorPrior()) {
      for (std::size_t i = 0; i < a.measurements.size(); ++i) use_field(i, false);
      internal::Factor next_tensor;
      FoldFront(a, b, &tensor_prior, &next_tensor);
      tensor_prior = std::move(next_tensor);
    }
    // A sensor with its own offset (sensor_offset) leaves its B level to the
    // window: the offset is solved again from the window's samples (or
    // carried, or the sensor's quiet one) at every solve, so the level a
    // leaving sample's B gives, with the offset of this moment taken as
    // exact, is not the state's information — kept in the prior it pins the
    // moment and the range to an offset the next windows move (far_ship_105:
    // the moment 7 % off at 55 σ). Its tensor stays in the prior; its B
    // informs the state only while it is in the window.
    for (std::size_t i = 0; i < a.measurements.size(); ++i) {
      use_field(i, own_offsets.count(a.epoch.samples[i].sensor_id) == 0);
    }
    internal::Factor next;
    FoldFront(a, b, &prior, &next);
    prior = std::move(next);
    window.pop_front();
  }

  // Marginal covariances of every state of the factorisation `f` (of the
  // window's first f.D_inv.size() epochs at their current values) and of the
  // moment (parameter units): the chain's selected inversion, prior
  // included; with sensor_offset.window_lines each sensor's offset line
  // marginalised too (offset_marginal.h) — the lines are solved by
  // alternation, and the chain's covariance alone is the track's given them.
  // Should that fail (S not positive definite: not seen), the chain's.
  bool WindowCovariance(const internal::ChainFactorization& f, std::vector<StateCovariance>* P,
                        Eigen::Matrix3d* Pm) const {
    if (!internal::ChainCovariance(f, P, Pm)) return false;
    const SensorOffsetOptions& so = options.sensor_offset;
    if (!so.window_lines || own_rates.empty()) return true;
    const std::size_t n = std::min(f.D_inv.size(), window.size());
    if (n != f.D_inv.size()) return true;
    std::vector<std::uint32_t> ids;
    for (const auto& [id, rate] : own_rates) ids.push_back(id);
    internal::OffsetLineMarginal lines(n, ids);
    for (std::size_t k = 0; k < n; ++k) {
      const WindowEpoch& w = window[k];
      for (std::size_t i = 0; i < w.measurements.size(); ++i) {
        const GradiometerSample& smp = w.epoch.samples[i];
        lines.Add(w.measurements[i], k, smp.sensor_id, SigmaB(smp, options), w.epoch.t_s - own_offset_t_s);
      }
    }
    lines.AddPriors(so.PriorSigma(own_offset_t_s), so.line_rate_sigma_T_per_s);
    std::vector<StateCovariance> P_lines = *P;
    Eigen::Matrix3d Pm_lines = *Pm;
    if (lines.Marginalize(f, &P_lines, &Pm_lines)) {
      *P = std::move(P_lines);
      *Pm = Pm_lines;
    }
    return true;
  }

  // Marginal covariances of the newest `count` states and of the moment
  // (WindowCovariance over the window); P_states in window order.
  bool NewestCovariances(std::size_t count, std::vector<StateCovariance>* P_states, Eigen::Matrix3d* P_moment) {
    std::vector<StateCovariance> P;
    Eigen::Matrix3d Pm;
    // With the offset lines (sensor_offset.window_lines) the cache, the
    // chain's alone, is not used: WindowCovariance marginalises them over the
    // factorisation of the solution emitted (the onset model's, refactorised
    // for its guard, or the default's, kept across a refused try).
    const bool lines = options.sensor_offset.window_lines && !own_rates.empty();
    if (emit_covariance != nullptr && emit_covariance->valid && !lines) {
      // Already computed at this solution (the onset model's guard, or the
      // trigger's noise test on the default's): the same selected inversion.
      P = emit_covariance->P;
      Pm = emit_covariance->Pm;
    } else {
      if (!chain_fresh)
        chain_fresh = internal::FactorizeChain(Chain(), &chain);
      if (!chain_fresh || !WindowCovariance(chain, &P, &Pm)) return false;
    }
    count = std::min(count, P.size());
    P_states->assign(P.end() - static_cast<std::ptrdiff_t>(count), P.end());
    *P_moment = Pm * (moment_scale * moment_scale);
    return true;
  }

  EpochEstimate Estimate(const WindowEpoch& w) const {
    EpochEstimate e;
    e.t_s = w.epoch.t_s;
    e.p_VinW = w.x.head<3>();
    e.speed_mps = w.x(3);
    e.heading_rad = WrapAngle(w.x(4));
    e.turn_rate_radps = w.x(5);
    e.num_samples = static_cast<int>(w.epoch.samples.size());
    return e;
  }

  // The window as a chain problem: the prior and the front epoch's factors
  // in group 0, each later epoch's measurements and process factors in its own.
  internal::ChainProblem Chain() {
    internal::ChainProblem chain;
    chain.moment = moment.data();
    chain.groups.resize(window.size());
    for (std::size_t k = 0; k < window.size(); ++k) {
      chain.states.push_back(window[k].x.data());
      if (k == 0 && prior.cost) chain.groups[k].push_back(&prior);
      for (const auto& f : window[k].measurements) chain.groups[k].push_back(&f);
      for (const auto& f : window[k].to_next) chain.groups[k].push_back(&f);
    }
    return chain;
  }

  // Gauss-Newton on the window by chain elimination, with step halving;
  // leaves the factorisation at the final point in `chain` (for covariance).
  // With factorize_final = false the factorisation is not redone at a point
  // where the solve stops by its tolerances (an onset candidate, whose
  // factorisation nothing uses: chain_fresh is then false).
  void ChainGaussNewton(ceres::Solver::Summary* cs, int* iterations, double* initial_cost, int max_iterations = -1,
                        bool factorize_final = true) {
    if (max_iterations < 0) max_iterations = options.window_max_num_iterations;
    const internal::ChainProblem problem = Chain();
    const auto& groups = problem.groups;
    const int threads = options.num_threads;
    double cost = internal::TotalCost(groups, threads);
    *initial_cost = cost;
    *iterations = 0;
    cs->initial_cost = cost;
    cs->final_cost = cost;
    if (!std::isfinite(cost)) {
      chain_ok = chain_fresh = false;
      cs->termination_type = ceres::FAILURE;
      cs->message = "chain Gauss-Newton: the window's cost is not finite";
      return;
    }
    chain_ok = internal::FactorizeChain(problem, &chain);
    cs->termination_type = ceres::NO_CONVERGENCE;
    cs->message = "chain Gauss-Newton: iteration limit";
    std::vector<StateVector> dx;
    Eigen::Vector3d dm;
    std::vector<StateVector> x0(window.size());
    bool stale = false;  // the factorisation is of the step's start, not of its end
    for (int it = 0; chain_ok && it < max_iterations; ++it) {
      internal::ChainStep(chain, &dx, &dm);
      for (std::size_t k = 0; k < window.size(); ++k) x0[k] = window[k].x;
      const Eigen::Vector3d m0 = moment;
      double alpha = 1.0, new_cost = cost;
      bool accepted = false;
      for (int halving = 0; halving < 5 && !accepted; ++halving, alpha *= 0.5) {
        for (std::size_t k = 0; k < window.size(); ++k) window[k].x = x0[k] + alpha * dx[k];
        moment = m0 + alpha * dm;
        new_cost = internal::TotalCost(groups, threads);
        accepted = new_cost <= cost;
      }
      if (!accepted) {
        for (std::size_t k = 0; k < window.size(); ++k) window[k].x = x0[k];
        moment = m0;
        cs->message = "chain Gauss-Newton: no descent step (estimate kept)";
        break;
      }
      ++*iterations;
      // Parameter tolerance (Ceres' rule): the step is tiny against the state.
      double step_sq = (alpha * 2.0) * (alpha * 2.0) * dm.squaredNorm(), x_sq = moment.squaredNorm();
      for (std::size_t k = 0; k < window.size(); ++k) {
        step_sq += (alpha * 2.0) * (alpha * 2.0) * dx[k].squaredNorm();
        x_sq += window[k].x.squaredNorm();
      }
      const bool tiny_step =
          std::sqrt(step_sq) <= options.parameter_tolerance * (std::sqrt(x_sq) + options.parameter_tolerance);
      const double decrease = cost - new_cost;
      cost = new_cost;
      const bool converged = decrease <= options.window_function_tolerance * cost || tiny_step;
      if (converged && !factorize_final) {
        stale = true;
      } else {
        chain_ok = internal::FactorizeChain(problem, &chain);
      }
      if (converged) {
        cs->termination_type = ceres::CONVERGENCE;
        cs->message = "chain Gauss-Newton: function tolerance reached";
        break;
      }
    }
    cs->initial_cost = *initial_cost;
    cs->final_cost = cost;
    if (!chain_ok) {
      cs->termination_type = ceres::FAILURE;
      cs->message = "chain Gauss-Newton: singular window information";
    }
    chain_fresh = chain_ok && !stale;
  }

  // The turn-onset model (TrackerOptions::window_turn_onset_model): the
  // window's turn-rate factors swapped for the batch's stiff walk with one
  // free jump, solved from the default solution, chosen by data cost.
  struct SavedTurnFactor {
    std::unique_ptr<ceres::CostFunction> cost;
    const ceres::LossFunction* loss = nullptr;
  };
  std::vector<SavedTurnFactor> saved_turn;  // non-empty: the onset model's factors are in place
  std::vector<StateVector> saved_x;
  Eigen::Vector3d saved_moment = Eigen::Vector3d::Zero();

  static internal::Factor* TurnFactor(WindowEpoch& w) {
    for (auto& f : w.to_next) {
      if (f.kind == internal::Factor::Kind::kTurnRate) return &f;
    }
    return nullptr;
  }

  // Data cost: the prior and the measurement factors (½ Σ ρ).
  double DataCost() {
    internal::ChainProblem c = Chain();
    for (auto& g : c.groups) {
      std::vector<const internal::Factor*> keep;
      for (const internal::Factor* f : g) {
        if (f->kind == internal::Factor::Kind::kMeasurement || f->kind == internal::Factor::Kind::kPrior) keep.push_back(f);
      }
      g = std::move(keep);
    }
    return internal::TotalCost(c.groups, options.num_threads);
  }

  // Puts the onset model's turn-rate factors in place: the stiff walk, free
  // between epochs onset − 1 and onset (onset = 0: no jump, ω free at the front).
  void SetOnsetFactors(std::size_t onset) {
    const bool first = saved_turn.empty();
    if (first) saved_turn.resize(window.size());
    for (std::size_t k = 0; k + 1 < window.size(); ++k) {
      internal::Factor* f = TurnFactor(window[k]);
      if (f == nullptr) continue;
      if (first) {
        saved_turn[k].cost = std::move(f->cost);
        saved_turn[k].loss = f->loss;
      }
      const double dt = window[k + 1].epoch.t_s - window[k].epoch.t_s;
      const bool free_jump = k + 1 == onset;
      f->cost = std::make_unique<TurnRateCost>(
          dt, free_jump ? kFreeTurnRateRadpsPerSqrtS : options.process.turn_rate_radps_per_sqrt_s);
      f->loss = free_jump ? nullptr : turn_loss.get();
    }
    chain_fresh = false;
  }

  // Puts the default model back (factors, states, moment).
  void RestoreDefaultModel() {
    if (saved_turn.empty()) return;
    for (std::size_t k = 0; k + 1 < window.size() && k < saved_turn.size(); ++k) {
      internal::Factor* f = TurnFactor(window[k]);
      if (f == nullptr || !saved_turn[k].cost) continue;
      f->cost = std::move(saved_turn[k].cost);
      f->loss = saved_turn[k].loss;
    }
    saved_turn.clear();
    for (std::size_t k = 0; k < window.size() && k < saved_x.size(); ++k) window[k].x = saved_x[k];
    moment = saved_moment;
    chain_fresh = false;
  }

  // The default model put back after a try that did not choose the onset
  // model, with the default solution's own factorisation (the same one a
  // new factorisation at the restored states would give).
  void RestoreDefaultAfterRefusal() {
    RestoreDefaultModel();
    if (saved_chain_fresh) {
      chain = std::move(saved_chain);
      chain_fresh = true;
    }
    saved_chain_fresh = false;
  }

  // The default solution's marginal covariances (default_covariance), from
  // its factorisation. False if singular.
  bool DefaultCovariance() {
    if (default_covariance.valid) return true;
    if (!chain_fresh) chain_fresh = internal::FactorizeChain(Chain(), &chain);
    default_covariance.valid =
        chain_fresh && internal::ChainCovariance(chain, &default_covariance.P, &default_covariance.Pm) &&
        default_covariance.P.size() == window.size();
    return default_covariance.valid;
  }

  // The previous try's best onset (absolute time, s; NaN: none), chosen or
  // refused, where the fast search looks first (window_turn_onset_search).
  double carried_onset_t = std::numeric_limits<double>::quiet_NaN();
  bool carried_onset_chosen = false;  // else refused (by the BIC or the jump's guard)
  bool onset_side_later = false;      // HillClimb's side near a carried onset
  // That try's best onset-model states (their epochs' times) and moment:
  // the fast search's start near the carried onset (a warm start).
  std::vector<std::pair<double, StateVector>> carried_x;
  Eigen::Vector3d carried_m = Eigen::Vector3d::Zero();

  // The warm start: each epoch's state from the previous onset solution
  // (same time), the epochs after it propagated by the coordinated turn.
  // False if the previous solution does not reach the window's front.
  bool WarmStart() {
    if (carried_x.empty()) return false;
    std::size_t j = 0;
    const double tol = options.epoch_tolerance_s;
    while (j < carried_x.size() && carried_x[j].first < window.front().epoch.t_s - tol) ++j;
    if (j == carried_x.size() || std::abs(carried_x[j].first - window.front().epoch.t_s) > tol) return false;
    for (std::size_t k = 0; k < window.size(); ++k) {
      if (j < carried_x.size() && std::abs(carried_x[j].first - window[k].epoch.t_s) <= tol) {
        window[k].x = carried_x[j++].second;
      } else {
        const StateVector& a = window[k - 1].x;
        const CtState<double> s = PropagateCoordinatedTurn(CtState<double>{a(0), a(1), a(2), a(3), a(4), a(5)},
                                                           window[k].epoch.t_s - window[k - 1].epoch.t_s);
        window[k].x << s.x, s.y, s.z, s.v, s.heading, s.turn_rate;
      }
    }
    moment = carried_m;
    return true;
  }

  // One onset candidate solved from the default solution (ω its own mean on
  // each side), or with `warm` from the carried solution (WarmStart); the
  // best by the cost of its own problem is kept in `best`.
  struct OnsetBest {
    double cost = std::numeric_limits<double>::infinity();
    std::size_t onset = 0;
    std::vector<StateVector> x;
    Eigen::Vector3d m = Eigen::Vector3d::Zero();
  };
  void SolveOnsetCandidate(std::size_t onset, OnsetBest* best, bool warm = false) {
    const std::size_t n = window.size();
    SetOnsetFactors(onset);
    if (!warm || !WarmStart()) {
      double before = 0.0, after = 0.0;
      for (std::size_t k = 0; k < n; ++k) (k < onset ? before : after) += saved_x[k](5);
      if (onset > 0) before /= static_cast<double>(onset);
      after /= static_cast<double>(n - onset);
      for (std::size_t k = 0; k < n; ++k) {
        window[k].x = saved_x[k];
        window[k].x(5) = k < onset ? before : after;
      }
      moment = saved_moment;
    }
    ceres::Solver::Summary cs;
    int iterations = 0;
    double initial = 0.0;
    ChainGaussNewton(&cs, &iterations, &initial, options.window_turn_onset_iterations, false);
    ++summary.num_turn_onset_candidate_solves;
    summary.num_turn_onset_iterations += iterations;
    if (!chain_ok || !std::isfinite(cs.final_cost) || !(cs.final_cost < best->cost)) return;
    best->cost = cs.final_cost;
    best->onset = onset;
    best->x.resize(n);
    for (std::size_t k = 0; k < n; ++k) best->x[k] = window[k].x;
    best->m = moment;
  }

  // Fast search from grid position `i` (window_turn_onset_search): the grid
  // points either side of it, moving on while the best is at an edge.
  // With `one_side` (near a carried onset) only one neighbour of i is tried
  // at first, on alternate sides from solve to solve.
  void HillClimb(const std::vector<std::size_t>& grid, std::size_t i, std::vector<bool>* tried, OnsetBest* best,
                 bool warm, bool one_side) {
    auto eval = [&](std::size_t j) {
      if ((*tried)[j]) return;
      (*tried)[j] = true;
      SolveOnsetCandidate(grid[j], best, warm);
    };
    std::size_t lo = i > 0 ? i - 1 : 0, hi = std::min(i + 1, grid.size() - 1);
    bool down = true, up = true;  // directions the climb may go on in
    if (one_side) {
      onset_side_later = !onset_side_later;
      (onset_side_later ? lo : hi) = i;
      (onset_side_later ? down : up) = false;
    }
    for (std::size_t j = lo; j <= hi; ++j) eval(j);
    for (;;) {
      if (down && best->onset == grid[lo] && lo > 0) {
        eval(--lo);
      } else if (up && best->onset == grid[hi] && hi + 1 < grid.size()) {
        eval(++hi);
      } else {
        break;
      }
    }
  }

  // Tries the onset model after a default solve. True: it is chosen, and its
  // states and factors are in place (RestoreDefaultModel after emitting).
  bool TryTurnOnsetModel() {
    const bool fast = options.window_turn_onset_search == TrackerOptions::OnsetSearch::kFast;
    const double carried = carried_onset_t;
    carried_onset_t = std::numeric_limits<double>::quiet_NaN();
    const std::size_t n = window.size();
    const double span = window.back().epoch.t_s - window.front().epoch.t_s;
    if (n < 4 || span < 2.0 * kMinOnsetSegmentS) return false;
    // Onsets on the grid inside the window (not its first or last 1 s).
    // The fast search's grid is at whole multiples of the grid step (so a
    // carried onset stays on it as the window slides); the full search's
    // starts 1 s after the window's front.
    std::vector<std::size_t> grid;
    const double t0 = window.front().epoch.t_s, g = options.window_turn_onset_grid_s;
    double next_t = t0 + kMinOnsetSegmentS;
    if (fast) next_t = std::ceil((next_t - options.epoch_tolerance_s) / g) * g;
    for (std::size_t k = 1; k < n; ++k) {
      if (window[k].epoch.t_s > window.back().epoch.t_s - kMinOnsetSegmentS) break;
      if (window[k].epoch.t_s + options.epoch_tolerance_s >= next_t) {
        grid.push_back(k);
        next_t = fast ? (std::floor((window[k].epoch.t_s + options.epoch_tolerance_s) / g) + 1.0) * g
                      : window[k].epoch.t_s + g;
      }
    }
    if (fast && grid.empty()) return false;
    // The trigger: the default's turn-rate span against the stiff walk's σ
    // over the window.
    bool trigger = false;
    if (fast) {
      std::size_t k_lo = 0, k_hi = 0;
      for (std::size_t k = 1; k < n; ++k) {
        if (window[k].x(5) < window[k_lo].x(5)) k_lo = k;
        if (window[k].x(5) > window[k_hi].x(5)) k_hi = k;
      }
      const double range = window[k_hi].x(5) - window[k_lo].x(5);
      const double stiff = options.process.turn_rate_radps_per_sqrt_s * std::sqrt(span);
      trigger = range >= options.window_turn_onset_trigger_sigmas * stiff;
      if (trigger) ++summary.num_turn_onset_triggered;
      // The noise test (window_turn_onset_trigger_noise_sigmas): the span
      // against the stiff walk and the default's own σ of ω at both ends.
      const double kn = options.window_turn_onset_trigger_noise_sigmas;
      if (trigger && kn > 0.0 && DefaultCovariance()) {
        const double var = stiff * stiff + default_covariance.P[k_lo](5, 5) + default_covariance.P[k_hi](5, 5);
        if (std::isfinite(var) && range * range < kn * kn * var) {
          trigger = false;
          ++summary.num_turn_onset_noise_vetoes;
        }
      }
    }
    // The fast search's start: the previous try's best onset if still inside
    // the grid (chosen, or refused while the trigger still fires), else the
    // coarse grid if the trigger fires.
    std::optional<std::size_t> near;
    if (fast && std::isfinite(carried) && (carried_onset_chosen || trigger) &&
        carried >= window[grid.front()].epoch.t_s - options.epoch_tolerance_s &&
        carried <= window[grid.back()].epoch.t_s + options.epoch_tolerance_s) {
      std::size_t i = 0;
      for (std::size_t j = 1; j < grid.size(); ++j) {
        if (std::abs(window[grid[j]].epoch.t_s - carried) < std::abs(window[grid[i]].epoch.t_s - carried)) i = j;
      }
      near = i;
    }
    if (fast && !near && !trigger) return false;
    const double d_default = DataCost();
    if (!std::isfinite(d_default)) return false;
    saved_x.resize(n);
    for (std::size_t k = 0; k < n; ++k) saved_x[k] = window[k].x;
    saved_moment = moment;
    saved_chain_fresh = chain_fresh;
    if (chain_fresh) saved_chain = chain;
    if (!fast || !near) ++summary.num_turn_onset_grid_searches;
    OnsetBest best;
    if (!fast) {
      SolveOnsetCandidate(0, &best);  // no jump
      for (const std::size_t onset : grid) SolveOnsetCandidate(onset, &best);
    } else {
      std::vector<bool> tried(grid.size(), false);
      const bool warm = near.has_value();
      if (!near) {
        // Coarse grid, then the fine grid next to its best.
        const double coarse = std::max(options.window_turn_onset_coarse_grid_s, options.window_turn_onset_grid_s);
        double next = -std::numeric_limits<double>::infinity();
        for (std::size_t j = 0; j < grid.size(); ++j) {
          if (window[grid[j]].epoch.t_s + options.epoch_tolerance_s < next) continue;
          tried[j] = true;
          SolveOnsetCandidate(grid[j], &best);
          next = window[grid[j]].epoch.t_s + coarse;
        }
        if (!std::isfinite(best.cost)) {
          RestoreDefaultAfterRefusal();
          return false;
        }
        near = static_cast<std::size_t>(std::find(grid.begin(), grid.end(), best.onset) - grid.begin());
      }
      HillClimb(grid, *near, &tried, &best, warm, warm);
    }
    int residuals = 0;
    for (const WindowEpoch& w : window) {
      for (const auto& f : w.measurements) residuals += f.cost->num_residuals();
    }
    const double penalty = options.window_turn_onset_bic_params * 0.5 * std::log(std::max(residuals, 1));
    // The best candidate's data cost, once (the measurement and prior factors
    // do not depend on which turn-rate model is in place).
    bool chosen = false;
    if (std::isfinite(best.cost)) {
      for (std::size_t k = 0; k < n; ++k) window[k].x = best.x[k];
      moment = best.m;
      chosen = DataCost() <= d_default + penalty;
    }
    ++summary.num_turn_onset_tries;
    if (fast && std::isfinite(best.cost) && best.onset > 0) {
      // Carried to the next try (its start and warm start), chosen or not.
      carried_onset_t = window[best.onset].epoch.t_s;
      carried_x.clear();
      for (std::size_t k = 0; k < n; ++k) carried_x.emplace_back(window[k].epoch.t_s, best.x[k]);
      carried_m = best.m;
    }
    carried_onset_chosen = false;
    if (chosen) {
      SetOnsetFactors(best.onset);
      for (std::size_t k = 0; k < n; ++k) window[k].x = best.x[k];
      moment = best.m;
      chain_fresh = false;
    }
    if (chosen && options.window_turn_onset_jump_sigmas > 0.0) {
      // The guard: the jump of ω at the onset against its σ (no jump: refused).
      chain_fresh = internal::FactorizeChain(Chain(), &chain);
      std::vector<StateCovariance> P;
      Eigen::Matrix3d Pm;
      bool significant = false;
      if (best.onset > 0 && chain_fresh && internal::ChainCovariance(chain, &P, &Pm)) {
        onset_covariance.valid = P.size() == n;
        onset_covariance.P = P;
        onset_covariance.Pm = Pm;
        const std::size_t k = best.onset;
        const double jump = window[k].x(5) - window[k - 1].x(5);
        const double var = P[k](5, 5) + P[k - 1](5, 5);
        const double kk = options.window_turn_onset_jump_sigmas;
        significant = std::isfinite(var) && var > 0.0 && jump * jump >= kk * kk * var;
      }
      if (!significant) {
        ++summary.num_turn_onset_refused_jump;
        chosen = false;
      }
    }
    if (!chosen) {
      onset_covariance.valid = false;
      RestoreDefaultAfterRefusal();
      return false;
    }
    saved_chain_fresh = false;
    ++summary.num_turn_onset_chosen;
    carried_onset_chosen = true;
    return true;
  }

  // Solves the window; `start` = first solve from the initialiser's guess
  // (robust-loss continuation, more iterations). With the per-sensor offset
  // (sensor_offset), each solve is followed by sensor_offset.passes rounds of
  // the offsets' update and a Gauss-Newton solve of the track given them.
  void Solve(bool start) {
    SolveOnce(start);
    if (!options.sensor_offset.WindowOffsets()) return;
    if (options.sensor_offset.window_score_test && !offsets_called) {
      // Not on the start's solve (the robust-loss continuation from the
      // initialiser's guess).
      if (start || !summary.usable) return;
      if (!OffsetsCalledFor()) {
        first_fired_t_s = std::numeric_limits<double>::quiet_NaN();
        return;
      }
      const double persist_s = options.sensor_offset.window_score_persist_s;
      if (persist_s > 0.0) {
        const double t_now = window.back().epoch.t_s;
        if (std::isnan(first_fired_t_s)) first_fired_t_s = t_now;
        if (t_now - first_fired_t_s < persist_s) return;
        // The latch: the prior without the B of the samples that left.
        if (prior.cost) prior = std::move(tensor_prior);
        tensor_prior = internal::Factor{};
      }
      offsets_called = true;
    }
    summary.offsets_solved = true;
    for (int pass = 0; pass < options.sensor_offset.passes && summary.usable; ++pass) {
      UpdateOwnOffsets();
      SolveOnce(false);
    }
  }

  void SolveOnce(bool start) {
    const auto t0 = std::chrono::steady_clock::now();
    chain_fresh = false;
    ceres::Solver::Summary cs;
    int iterations = 0;
    double initial_cost = 0.0, solve_time = 0.0;
    if (start) {
      std::vector<internal::Factor*> meas;
      for (auto& w : window) {
        for (auto& f : w.measurements) meas.push_back(&f);
      }
      internal::PassResult pr =
          internal::SolveWithContinuation(options, options.max_num_iterations, false, meas, false,
                                          [this](bool) { return Chain(); });
      for (auto* f : meas) f->loss = meas_loss.get();  // the nominal loss from now on
      cs = pr.last;
      iterations = pr.iterations;
      initial_cost = pr.first_initial_cost;
      solve_time = pr.solve_time_s;
    } else if (options.window_solver == TrackerOptions::WindowSolver::kChainGaussNewton) {
      ChainGaussNewton(&cs, &iterations, &initial_cost);
      solve_time = Seconds(t0, std::chrono::steady_clock::now());
    } else {
      ceres::Problem problem(internal::NonOwningProblemOptions());
      internal::AddToProblem(Chain(), &problem);
      const ceres::Solver::Options so =
          internal::SparseSolverOptions(options, options.window_max_num_iterations, options.window_function_tolerance);
      ceres::Solve(so, &problem, &cs);
      iterations = static_cast<int>(cs.iterations.size()) - 1;
      initial_cost = cs.initial_cost;
      solve_time = cs.total_time_in_seconds;
    }
    int num_samples = 0;
    for (const auto& w : window) num_samples += static_cast<int>(w.epoch.samples.size());
    summary.initialized = true;
    summary.usable = cs.IsSolutionUsable() && std::isfinite(cs.final_cost);
    summary.converged = cs.termination_type == ceres::CONVERGENCE;
    summary.num_epochs = static_cast<int>(window.size());
    summary.num_samples = num_samples;
    summary.iterations = iterations;
    summary.initial_cost = initial_cost;
    summary.final_cost = cs.final_cost;
    summary.solve_time_s = solve_time;
    summary.message = cs.message;
    summary.covariance_ok = false;
    summary.covariance_time_s = 0.0;
    summary.total_time_s = Seconds(t0, std::chrono::steady_clock::now());
  }

  // Starts the track from `init` over the buffered `epochs` (the first window
  // solve, with robust-loss continuation).
  std::vector<EpochEstimate> Start(const InitialTrack& init, const std::vector<Epoch>& epochs) {
    const auto t0 = std::chrono::steady_clock::now();
    initialized = true;
    fixes.clear();
    buffer.clear();
    moment_scale = std::max(init.m_B_Am2.norm(), 1.0);
    moment = init.m_B_Am2 / moment_scale;
    for (const Epoch& b : epochs) {
      const CtState<double> s = PropagateCoordinatedTurn(init.state, b.t_s - init.t_ref_s);
      StateVector x0;
      x0 << s.x, s.y, s.z, s.v, s.heading, s.turn_rate;
      Append(b, x0);
    }
    Solve(true);
    summary.num_init_fixes = static_cast<int>(init.fixes.size());
    summary.init_from_external_fixes = init.from_external_fixes;
    unsolved = 0;
    last_solve_t = window.back().epoch.t_s;
    return Emit(1, t0);
  }

  std::vector<EpochEstimate> Process(const Epoch& e) {
    const auto t0 = std::chrono::steady_clock::now();
    if (!initialized) {
      if (e.samples.empty()) return {};
      buffer.push_back(e);
      while (e.t_s - buffer.front().t_s > options.window_s + options.epoch_tolerance_s) buffer.pop_front();
      while (!fixes.empty() && fixes.front().t_s < buffer.front().t_s - options.epoch_tolerance_s) fixes.pop_front();
      const std::vector<Epoch> epochs(buffer.begin(), buffer.end());
      const std::vector<DipoleFix> given(fixes.begin(), fixes.end());
      const std::optional<InitialTrack> init = InitializeTrack(epochs, B0_W, options, any_fix ? &given : nullptr);
      if (!init) return {};
      return Start(*init, epochs);
    }
    const WindowEpoch& last = window.back();
    const CtState<double> s0{last.x(0), last.x(1), last.x(2), last.x(3), last.x(4), last.x(5)};
    const CtState<double> s = PropagateCoordinatedTurn(s0, e.t_s - last.epoch.t_s);
    StateVector x0;
    x0 << s.x, s.y, s.z, s.v, s.heading, s.turn_rate;
    Append(e, x0);
    while (window.size() > 2 &&
           e.t_s - window.front().epoch.t_s > options.window_s + options.epoch_tolerance_s) {
      MarginalizeFront();
    }
    ++unsolved;
    // Solve every window_solve_interval_s of data (every epoch with 0); the
    // epochs appended since the last solve get their estimates from this one.
    if (e.t_s - last_solve_t < options.window_solve_interval_s - options.epoch_tolerance_s &&
        static_cast<std::size_t>(unsolved) + 2 < window.size()) {
      return {};
    }
    return SolvePending(t0);
  }

  // Solves the window and emits the epochs appended since the last solve.
  std::vector<EpochEstimate> SolvePending(std::chrono::steady_clock::time_point t0) {
    if (unsolved == 0) return {};
    Solve(false);
    summary.num_init_fixes = 0;
    summary.init_from_external_fixes = false;
    const std::size_t count = static_cast<std::size_t>(unsolved);
    unsolved = 0;
    last_solve_t = window.back().epoch.t_s;
    ++summary.num_window_solves;
    default_covariance.valid = onset_covariance.valid = false;
    if (!options.window_turn_onset_model || !summary.usable) return Emit(count, t0);
    // With the onset model chosen its newest states and covariance, else the
    // default's; the window goes on with the default model.
    const bool chosen = TryTurnOnsetModel();
    emit_covariance = chosen ? &onset_covariance : &default_covariance;
    std::vector<EpochEstimate> out = Emit(count, t0);
    emit_covariance = nullptr;
    if (chosen) RestoreDefaultModel();
    return out;
  }

  // Estimates of the newest `count` epochs after a solve.
  std::vector<EpochEstimate> Emit(std::size_t count, std::chrono::steady_clock::time_point t0) {
    summary.num_rejected_samples = rejected_samples;
    summary.num_dropped_factors = dropped_factors;
    count = std::min(count, window.size());
    std::vector<EpochEstimate> out;
    const bool ok = summary.usable && moment.allFinite();
    for (std::size_t k = window.size() - count; k < window.size(); ++k) {
      EpochEstimate est = Estimate(window[k]);
      est.usable = ok && window[k].x.allFinite();
      out.push_back(est);
    }
    if (options.compute_covariance && ok) {
      const auto tc = std::chrono::steady_clock::now();
      std::vector<StateCovariance> P;
      Eigen::Matrix3d Pm;
      const bool have = NewestCovariances(count, &P, &Pm) && Pm.allFinite();
      if (have) {
        cov_m_B = Pm;
        summary.covariance_ok = true;
      }
      for (std::size_t i = 0; i < out.size(); ++i) {
        if (have && P[i].allFinite()) {
          out[i].cov_state = P[i];
          out[i].has_covariance = true;
        } else {
          out[i].usable = false;  // a covariance was asked for and cannot be given
        }
      }
      summary.covariance_time_s = Seconds(tc, std::chrono::steady_clock::now());
    }
    summary.total_time_s = Seconds(t0, std::chrono::steady_clock::now());
    return out;
  }

  std::size_t Solved() const {
    return window.size() - std::min<std::size_t>(static_cast<std::size_t>(unsolved), window.size());
  }

  // WindowTracker::FirstStrongEpoch.
  double FirstStrongEpoch(double min_tensor_snr) const {
    if (!initialized || window.empty()) return std::numeric_limits<double>::quiet_NaN();
    const Eigen::Vector3d m_B = moment * moment_scale;
    for (std::size_t k = 0; k < Solved(); ++k) {
      const WindowEpoch& w = window[k];
      const Eigen::Vector3d m_W = HeadingRotation(w.x(4)) * m_B;
      for (const auto& smp : w.epoch.samples) {
        Eigen::Vector3d B;
        Eigen::Matrix3d T;
        DipoleBT(smp.p_SinW - w.x.head<3>(), m_W, &B, &T);
        if (T.norm() >= min_tensor_snr * SigmaT(smp, options)) return w.epoch.t_s;
      }
    }
    return std::numeric_limits<double>::quiet_NaN();
  }

  // WindowTracker::SolvedBetween.
  std::vector<EpochEstimate> SolvedBetween(double t_from_s, double t_until_s) {
    if (!initialized || window.empty()) return {};
    const double tol = options.epoch_tolerance_s;
    const std::size_t solved = Solved();
    std::size_t first = 0;
    while (first < solved && window[first].epoch.t_s < t_from_s - tol) ++first;
    std::size_t end = first;
    while (end < solved && window[end].epoch.t_s <= t_until_s + tol) ++end;
    if (first >= end) return {};
    const bool ok = summary.usable && moment.allFinite();
    // The marginals at the last solve's factorisation when it is still the
    // window's (its newest state is window[solved − 1]'s; epochs appended
    // since are not in it), else of the window now, factorised here (the
    // tracker's own factorisation is left as it is).
    std::vector<StateCovariance> P;
    Eigen::Matrix3d Pm;
    bool have = false;
    std::size_t newest = solved;  // P.back() is window[newest − 1]'s
    if (options.compute_covariance && ok) {
      if (chain_fresh) {
        have = WindowCovariance(chain, &P, &Pm);
      } else {
        internal::ChainFactorization local;
        have = internal::FactorizeChain(Chain(), &local) && WindowCovariance(local, &P, &Pm);
        newest = window.size();
      }
    }
    std::vector<EpochEstimate> out;
    for (std::size_t k = first; k < end; ++k) {
      EpochEstimate est = Estimate(window[k]);
      est.usable = ok && window[k].x.allFinite();
      if (options.compute_covariance) {
        const std::size_t back = newest - k;  // >= 1
        if (have && back <= P.size() && P[P.size() - back].allFinite()) {
          est.cov_state = P[P.size() - back];
          est.has_covariance = true;
        } else {
          est.usable = false;
        }
      }
      out.push_back(est);
    }
    return out;
  }

  std::optional<CtState<double>> PredictState(double t_s) const {
    if (!initialized || window.empty()) return std::nullopt;
    const WindowEpoch& last = window.back();
    const CtState<double> s0{last.x(0), last.x(1), last.x(2), last.x(3), last.x(4), last.x(5)};
    return PropagateCoordinatedTurn(s0, t_s - last.epoch.t_s);
  }
};

WindowTracker::WindowTracker(const Eigen::Vector3d& B0_W, const TrackerOptions& options)
    : impl_(std::make_unique<Impl>()) {
  std::string why;
  if (!options.IsValid(&why)) throw InputError("tracker options: " + why);
  impl_->B0_W = B0_W;
  impl_->options = options;
  impl_->meas_loss = MakeCeresLoss(options.measurement_loss, options.measurement_loss_scale_sigma);
  impl_->turn_loss =
      MakeCeresLoss(options.process.turn_rate_loss, options.process.turn_rate_loss_scale_sigma);
}

WindowTracker::~WindowTracker() = default;

std::vector<EpochEstimate> WindowTracker::AddSample(const GradiometerSample& sample) {
  Impl& m = *impl_;
  if (CheckSample(sample) != SampleDefect::kNone) {  // the door
    ++m.rejected_samples;
    m.summary.num_rejected_samples = m.rejected_samples;
    return {};
  }
  if (m.has_pending && std::abs(sample.t_s - m.pending.t_s) <= m.options.epoch_tolerance_s) {
    m.pending.samples.push_back(sample);
    return {};
  }
  if (m.has_pending && sample.t_s < m.pending.t_s) {
    throw InputError("tracker: sample time " + FormatNumber(sample.t_s) +
                     " s is earlier than the current epoch " + FormatNumber(m.pending.t_s) + " s");
  }
  std::vector<EpochEstimate> out;
  if (m.has_pending) out = AddEpoch(m.pending);
  m.pending = Epoch{sample.t_s, {sample}};
  m.has_pending = true;
  return out;
}

std::vector<EpochEstimate> WindowTracker::Flush() {
  Impl& m = *impl_;
  std::vector<EpochEstimate> out;
  if (m.has_pending) {
    m.has_pending = false;
    out = AddEpoch(m.pending);
  }
  if (m.initialized) {
    for (auto& e : m.SolvePending(std::chrono::steady_clock::now())) out.push_back(e);
  }
  return out;
}

std::vector<EpochEstimate> WindowTracker::Start(const InitialTrack& init, const std::vector<Epoch>& epochs) {
  Impl& m = *impl_;
  if (m.initialized) throw InputError("tracker: Start on a tracker that already has a track");
  if (epochs.empty()) throw InputError("tracker: Start needs the epochs of its initial track");
  for (std::size_t k = 1; k < epochs.size(); ++k) {
    if (!(epochs[k].t_s > epochs[k - 1].t_s + m.options.epoch_tolerance_s)) {
      throw InputError("tracker: Start: epochs are not in increasing time order");
    }
  }
  m.has_pending = false;
  return m.Start(init, epochs);
}

std::optional<CtState<double>> WindowTracker::PredictState(double t_s) const { return impl_->PredictState(t_s); }

double WindowTracker::last_epoch_time() const {
  return impl_->initialized ? impl_->window.back().epoch.t_s : -std::numeric_limits<double>::infinity();
}

std::vector<EpochEstimate> WindowTracker::AddEpoch(const Epoch& raw) {
  Impl& m = *impl_;
  Epoch epoch{raw.t_s, {}};
  for (const auto& s : raw.samples) {  // the door, for epochs handed in whole
    if (CheckSample(s) == SampleDefect::kNone) {
      epoch.samples.push_back(s);
    } else {
      ++m.rejected_samples;
    }
  }
  m.summary.num_rejected_samples = m.rejected_samples;
  if (!std::isfinite(epoch.t_s)) throw InputError("tracker: epoch time is not finite");
  // With no sample an epoch only carries the motion model: a track coasts
  // through it; before a track exists it is ignored.
  if (epoch.samples.empty() && !m.initialized) return {};
  const double last_t =
      m.initialized ? m.window.back().epoch.t_s
                    : (m.buffer.empty() ? -std::numeric_limits<double>::infinity() : m.buffer.back().t_s);
  if (!(epoch.t_s > last_t + m.options.epoch_tolerance_s)) {
    throw InputError("tracker: epoch at " + FormatNumber(epoch.t_s) +
                     " s is not later than the previous one");
  }
  return m.Process(epoch);
}

void WindowTracker::AddFix(const DipoleFix& fix) {
  Impl& m = *impl_;
  if (!std::isfinite(fix.t_s) || (fix.valid && !fix.p_DinW.allFinite())) {
    throw InputError("tracker: fix of sensor " + std::to_string(fix.sensor_id) + " at t = " + FormatNumber(fix.t_s) +
                     " s: time or position is not finite");
  }
  m.any_fix = true;
  if (!fix.valid || m.initialized || m.options.init.source == InitSource::kSamples) return;
  // Older than every buffered epoch: its sample is gone (or never came).
  if (!m.buffer.empty() && fix.t_s < m.buffer.front().t_s - m.options.epoch_tolerance_s) return;
  m.fixes.push_back(fix);
  if (m.fixes.size() > kMaxPendingFixes) m.fixes.pop_front();
}

namespace {

// A window prior (PriorCost on the front state and the moment) in a
// checkpoint: a flag, then L, x̄ and c.
void PutPrior(StateWriter& w, const internal::Factor& f) {
  const auto* prior = dynamic_cast<const PriorCost*>(f.cost.get());
  if (f.cost && !prior) throw std::logic_error("WindowTracker::SaveState: a prior of another kind");
  w.U8(prior ? 1 : 0);
  if (prior) {
    w.Matrix(prior->L());
    w.Matrix(prior->x_bar());
    w.Matrix(prior->c());
  }
}

}  // namespace

void WindowTracker::SaveState(StateWriter& w) const {
  const Impl& m = *impl_;
  internal::PutDeque(w, m.buffer);
  internal::PutDeque(w, m.fixes);
  w.U8(m.any_fix ? 1 : 0);
  w.U8(m.has_pending ? 1 : 0);
  internal::Put(w, m.pending);
  w.U8(m.initialized ? 1 : 0);
  w.F64(m.moment_scale);
  w.Matrix(m.moment);
  w.Matrix(m.cov_m_B);
  w.U64(m.window.size());
  for (const WindowEpoch& e : m.window) {
    internal::Put(w, e.epoch);
    w.Matrix(e.x);
  }
  PutPrior(w, m.prior);
  internal::Put(w, m.summary);
  w.I64(m.unsolved);
  w.F64(m.last_solve_t);
  w.I64(m.rejected_samples);
  w.I64(m.dropped_factors);
  if (m.options.sensor_offset.WindowOffsets()) {  // the options are the restoring tracker's too
    w.U64(m.own_offsets.size());
    for (const auto& [id, o] : m.own_offsets) {
      w.U64(id);
      w.Matrix(o);
    }
    if (m.options.sensor_offset.window_score_test) w.U8(m.offsets_called ? 1 : 0);
    if (m.options.sensor_offset.window_score_persist_s > 0.0) {
      w.F64(m.first_fired_t_s);
      PutPrior(w, m.tensor_prior);
    }
    if (m.options.sensor_offset.window_lines) {
      w.F64(m.own_offset_t_s);
      w.U64(m.own_rates.size());
      for (const auto& [id, rate] : m.own_rates) {
        w.U64(id);
        w.Matrix(rate);
      }
    }
    if (m.options.sensor_offset.carry) {
      w.U64(m.carried_offsets.size());
      for (const auto& [id, c] : m.carried_offsets) {
        w.U64(id);
        w.Matrix(c.mean_W);
        w.F64(c.variance_T2);
        w.F64(c.t_s);
      }
    }
  }
  w.U8(m.chain_ok ? 1 : 0);
  w.U8(m.chain_fresh ? 1 : 0);
}

void WindowTracker::RestoreState(StateReader& r) {
  // Into a new Impl, swapped in once everything has been read.
  auto fresh = std::make_unique<Impl>();
  Impl& m = *fresh;
  m.B0_W = impl_->B0_W;
  m.options = impl_->options;
  m.meas_loss = MakeCeresLoss(m.options.measurement_loss, m.options.measurement_loss_scale_sigma);
  m.turn_loss = MakeCeresLoss(m.options.process.turn_rate_loss, m.options.process.turn_rate_loss_scale_sigma);
  internal::GetDeque(r, &m.buffer);
  internal::GetDeque(r, &m.fixes);
  m.any_fix = r.U8() != 0;
  m.has_pending = r.U8() != 0;
  internal::Get(r, &m.pending);
  m.initialized = r.U8() != 0;
  m.moment_scale = r.F64();
  m.moment = internal::GetMatrix(r, 3, 1);
  m.cov_m_B = internal::GetMatrix(r, 3, 3);
  for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) {
    Epoch e;
    internal::Get(r, &e);
    const StateVector x = internal::GetMatrix(r, 6, 1);
    m.Append(e, x);  // the measurement and process factors, as when it was first appended
  }
  m.GetPrior(r, &m.prior);
  internal::Get(r, &m.summary);
  m.unsolved = static_cast<int>(r.I64());
  m.last_solve_t = r.F64();
  m.rejected_samples = static_cast<int>(r.I64());
  m.dropped_factors = static_cast<int>(r.I64());
  if (m.options.sensor_offset.WindowOffsets()) {
    for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) {
      const auto id = static_cast<std::uint32_t>(r.U64());
      m.own_offsets[id] = internal::GetMatrix(r, 3, 1);
    }
    if (m.options.sensor_offset.window_score_test) m.offsets_called = r.U8() != 0;
    if (m.options.sensor_offset.window_score_persist_s > 0.0) {
      m.first_fired_t_s = r.F64();
      if (std::isinf(m.first_fired_t_s)) throw CheckpointError("corrupt: the score test's first firing");
      m.GetPrior(r, &m.tensor_prior);
    }
    if (m.options.sensor_offset.window_lines) {
      m.own_offset_t_s = r.F64();
      for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) {
        const auto id = static_cast<std::uint32_t>(r.U64());
        m.own_rates[id] = internal::GetMatrix(r, 3, 1);
      }
      if (!std::isfinite(m.own_offset_t_s)) throw CheckpointError("corrupt: a sensor offset's time");
    }
    if (m.options.sensor_offset.carry) {
      for (std::size_t n = r.Count(internal::kMaxStateCount); n > 0; --n) {
        const auto id = static_cast<std::uint32_t>(r.U64());
        internal::CarriedOffset& c = m.carried_offsets[id];
        c.mean_W = internal::GetMatrix(r, 3, 1);
        c.variance_T2 = r.F64();
        c.t_s = r.F64();
        if (!(c.variance_T2 > 0.0) || !std::isfinite(c.variance_T2) || !std::isfinite(c.t_s) || !c.mean_W.allFinite())
          throw CheckpointError("corrupt: a carried sensor offset");
      }
    }
    for (WindowEpoch& e : m.window) m.ApplyOffsets(e, true);
  }
  m.chain_ok = r.U8() != 0;
  // The factorisation is of the window at its current estimate: made again.
  if (r.U8() != 0 && !m.window.empty()) m.chain_fresh = internal::FactorizeChain(m.Chain(), &m.chain);
  if (m.initialized && m.window.empty()) throw CheckpointError("corrupt: a track without a window");
  impl_ = std::move(fresh);
}

void WindowTracker::SetSensorOffsetPrior(SensorOffsetPriorFn prior) { impl_->quiet_prior = std::move(prior); }

void WindowTracker::SetBackgroundOffsets(BackgroundOffsetFn offset) {
  Impl& m = *impl_;
  m.offsets = std::move(offset);
  for (WindowEpoch& w : m.window) {
    m.ApplyOffsets(w, true);
  }
  m.chain_fresh = false;  // the factorisation was of the old measurements
}

std::vector<WindowTracker::WindowEpochView> WindowTracker::WindowView() const {
  std::vector<WindowEpochView> out;
  if (!impl_->initialized) return out;
  out.reserve(impl_->window.size());
  for (const WindowEpoch& w : impl_->window) {
    WindowEpochView v;
    v.t_s = w.epoch.t_s;
    v.state = {w.x(0), w.x(1), w.x(2), w.x(3), w.x(4), w.x(5)};
    for (const auto& smp : w.epoch.samples) v.sensor_ids.push_back(smp.sensor_id);
    out.push_back(std::move(v));
  }
  return out;
}

double WindowTracker::FirstStrongEpoch(double min_tensor_snr) const { return impl_->FirstStrongEpoch(min_tensor_snr); }
std::vector<EpochEstimate> WindowTracker::SolvedBetween(double t_from_s, double t_until_s) {
  return impl_->SolvedBetween(t_from_s, t_until_s);
}

bool WindowTracker::initialized() const { return impl_->initialized; }
Eigen::Vector3d WindowTracker::m_B_Am2() const { return impl_->moment * impl_->moment_scale; }
Eigen::Matrix3d WindowTracker::cov_m_B() const { return impl_->cov_m_B; }
const Summary& WindowTracker::last_summary() const { return impl_->summary; }

void WindowTracker::ResidualMeansChi2(double* chi2, double* dof) const {
  *chi2 = 0.0;
  *dof = 0.0;
  if (!impl_->initialized || !impl_->summary.usable) return;
  // Per sensor, or with the offset lines per (sensor, quarter of the window).
  std::map<std::pair<std::uint32_t, int>, std::pair<Eigen::Matrix<double, 8, 1>, int>> sums;
  const std::size_t solved = impl_->Solved();
  if (solved == 0) return;
  const bool lines = impl_->options.sensor_offset.window_lines && !impl_->own_rates.empty();
  const double t_front = impl_->window.front().epoch.t_s;
  const double span = impl_->window[solved - 1].epoch.t_s - t_front;
  for (std::size_t k = 0; k < solved; ++k) {
    const auto& w = impl_->window[k];
    const int segment =
        lines && span > 0.0
            ? std::min(kLineSegments - 1, static_cast<int>(kLineSegments * (w.epoch.t_s - t_front) / span))
            : 0;
    for (std::size_t i = 0; i < w.measurements.size() && i < w.epoch.samples.size(); ++i) {
      const internal::Factor& f = w.measurements[i];
      Eigen::Matrix<double, 8, 1> e;
      if (!f.cost || !f.cost->Evaluate(f.blocks.data(), e.data(), nullptr) || !e.allFinite()) continue;
      auto& s = sums.try_emplace({w.epoch.samples[i].sensor_id, segment}, Eigen::Matrix<double, 8, 1>::Zero(), 0)
                    .first->second;
      s.first += e;
      ++s.second;
    }
  }
  std::map<std::uint32_t, int> segments;  // per sensor
  for (const auto& [key, s] : sums) {
    *chi2 += s.first.squaredNorm() / s.second;  // n ‖ē‖² = ‖Σ e‖² / n
    *dof += 8.0;
    ++segments[key.first];
  }
  // Each sensor's line (level and rate, 3 axes) took 6 of its segment means' dof.
  for (const auto& [id, n] : segments) {
    if (lines && n > 2 && impl_->own_rates.count(id) != 0) *dof -= 6.0;
  }
}

}  // namespace magnav::tracker
