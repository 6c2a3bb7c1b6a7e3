#include <ceres/covariance.h>
#include <ceres/solver.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <utility>

#include "factors.h"
#include "sensor_offset.h"
#include "magnav/core/error.h"
#include "magnav/core/units.h"
#include "magnav/tracker/cost_functions.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/tracker.h"
#include "magnav/tracker/variance_factor.h"

namespace magnav::tracker {

namespace {

// Segments shorter than this many epochs are not fitted (a change point
// needs evidence on both sides).
constexpr int kMinTurnSegmentEpochs = 10;
// A turn-rate restart is kept only if it lowers the cost (½ Σ ρ, in σ²) by
// at least this: a likelihood ratio of e. Less is the same minimum reached
// again within the solver's tolerance (the reference AUV SQUID pass: its
// moment moved by 1.5e-6 relative), not a better turn.
constexpr double kMinTurnRestartGain = 1.0;

// The least-squares fit of w by a piecewise-constant sequence with exactly
// `change_points` change points (segments of at least
// kMinTurnSegmentEpochs), by dynamic programming over prefix sums; empty if
// w is too short.
std::vector<double> PiecewiseConstantFit(const std::vector<double>& w, int change_points) {
  const int n = static_cast<int>(w.size());
  const int segments = change_points + 1;
  if (n < segments * kMinTurnSegmentEpochs) return {};
  std::vector<double> s1(n + 1, 0.0), s2(n + 1, 0.0);
  for (int i = 0; i < n; ++i) {
    s1[i + 1] = s1[i] + w[i];
    s2[i + 1] = s2[i] + w[i] * w[i];
  }
  const auto sse = [&](int i, int j) {  // segment [i, j)
    const double m = (s1[j] - s1[i]) / (j - i);
    return std::max(0.0, s2[j] - s2[i] - m * (s1[j] - s1[i]));
  };
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // best[c][j]: the first j values in c + 1 segments; from[c][j] the start of the last.
  std::vector<std::vector<double>> best(segments, std::vector<double>(n + 1, kInf));
  std::vector<std::vector<int>> from(segments, std::vector<int>(n + 1, 0));
  for (int j = kMinTurnSegmentEpochs; j <= n; ++j) best[0][j] = sse(0, j);
  for (int c = 1; c < segments; ++c) {
    for (int j = (c + 1) * kMinTurnSegmentEpochs; j <= n; ++j) {
      for (int i = c * kMinTurnSegmentEpochs; i + kMinTurnSegmentEpochs <= j; ++i) {
        const double v = best[c - 1][i] + sse(i, j);
        if (v < best[c][j]) {
          best[c][j] = v;
          from[c][j] = i;
        }
      }
    }
  }
  std::vector<double> fit(n);
  int j = n;
  for (int c = segments - 1; c >= 0; --c) {
    const int i = c == 0 ? 0 : from[c][j];
    const double m = (s1[j] - s1[i]) / (j - i);
    for (int k = i; k < j; ++k) fit[k] = m;
    j = i;
  }
  return fit;
}

}  // namespace

namespace {

// One batch solve, offsets as options.sensor_offset.batch says (without the
// score test); score_offsets: the score test's χ² and dof in its summary.
// *initial: the initial track, computed here when empty and reused when not
// (the second solve of SolveBatch starts where the first did).
TrackEstimate SolveBatchOnce(const std::vector<Epoch>& input, const Eigen::Vector3d& B0_W,
                             const TrackerOptions& options, const std::vector<DipoleFix>* fixes,
                             const std::vector<BatchStart>* starts, bool score_offsets,
                             std::optional<InitialTrack>* initial) {
  std::string why;
  if (!options.IsValid(&why)) throw InputError("tracker options: " + why);
  if (!B0_W.allFinite()) throw InputError("tracker: B0 is not finite");
  const auto t_start = std::chrono::steady_clock::now();
  TrackEstimate out;
  Summary& sum = out.summary;
  // The door: samples that fail core's CheckSample are left out and counted.
  std::vector<Epoch> epochs;
  epochs.reserve(input.size());
  for (const Epoch& e : input) {
    Epoch kept{e.t_s, {}};
    for (const auto& s : e.samples) {
      if (CheckSample(s) == SampleDefect::kNone) {
        kept.samples.push_back(s);
      } else {
        ++sum.num_rejected_samples;
      }
    }
    if (!kept.samples.empty()) epochs.push_back(std::move(kept));
  }
  sum.num_epochs = static_cast<int>(epochs.size());

  if (!initial->has_value()) *initial = InitializeTrack(epochs, B0_W, options, fixes);
  if (!initial->has_value()) {
    sum.message = NoTrackMessage(options, fixes != nullptr);
    sum.total_time_s = Seconds(t_start, std::chrono::steady_clock::now());
    return out;
  }
  const InitialTrack* init = &initial->value();
  sum.initialized = true;
  sum.num_init_fixes = static_cast<int>(init->fixes.size());
  sum.init_from_external_fixes = init->from_external_fixes;

  // Parameters: one state per epoch (straight-line initial guess), one moment.
  const double moment_scale = std::max(init->m_B_Am2.norm(), 1.0);
  std::vector<StateVector> x(epochs.size());
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    const CtState<double> s = PropagateCoordinatedTurn(init->state, epochs[k].t_s - init->t_ref_s);
    x[k] << s.x, s.y, s.z, s.v, s.heading, s.turn_rate;
  }
  Eigen::Vector3d moment = init->m_B_Am2 / moment_scale;

  // Factors grouped by their earliest epoch (measurements of k, process k→k+1).
  const auto turn_loss =
      MakeCeresLoss(options.process.turn_rate_loss, options.process.turn_rate_loss_scale_sigma);
  std::vector<std::vector<internal::Factor>> factors(epochs.size());
  std::vector<internal::Factor> warm_turn;  // Gaussian warm-up turn-rate factors
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    internal::AddMeasurementFactors(epochs[k], B0_W, options, moment_scale, x[k].data(), moment.data(),
                                    &factors[k]);
    sum.num_samples += static_cast<int>(epochs[k].samples.size());
    if (k + 1 < epochs.size()) {
      const double dt = epochs[k + 1].t_s - epochs[k].t_s;
      ProcessNoise q = options.process;
      q.depth_m_per_sqrt_s = internal::DepthWalk(epochs[k], options);
      internal::AddProcessFactors(dt, q, turn_loss.get(), x[k].data(), x[k + 1].data(),
                                  &factors[k]);
      if (options.process.turn_rate_warmup_radps_per_sqrt_s > 0.0) {
        internal::Factor w;
        w.kind = internal::Factor::Kind::kTurnRate;
        w.cost = std::make_unique<TurnRateCost>(dt, options.process.turn_rate_warmup_radps_per_sqrt_s);
        w.blocks = {x[k].data(), x[k + 1].data()};
        warm_turn.push_back(std::move(w));
      }
    }
  }
  // The whole pass's cost at the initial guess, with the nominal losses, so
  // that Summary::initial_cost and final_cost are over the same factors.
  std::size_t i0 = 0, i1 = epochs.size() - 1;
  {
    const auto nominal = MakeCeresLoss(options.measurement_loss, options.measurement_loss_scale_sigma);
    internal::ChainProblem whole;
    for (std::size_t k = 0; k < epochs.size(); ++k) {
      whole.groups.emplace_back();
      for (auto& f : factors[k]) {
        if (f.kind == internal::Factor::Kind::kMeasurement) f.loss = nominal.get();
        if (f.kind == internal::Factor::Kind::kMeasurement || k + 1 < epochs.size()) whole.groups.back().push_back(&f);
      }
    }
    sum.initial_cost = internal::TotalCost(whole.groups, options.num_threads);
    for (auto& group : factors) {
      for (auto& f : group) {
        if (f.kind == internal::Factor::Kind::kMeasurement) f.loss = nullptr;
      }
    }
  }
  // Growing solve: the initialiser's span first, then spans grown by
  // batch_growth_factor with the new epochs predicted from the span's ends
  // by the coordinated-turn model, until the whole pass is included.
  while (i0 + 1 < epochs.size() && epochs[i0].t_s < init->t_first_s) ++i0;
  while (i1 > i0 && epochs[i1].t_s > init->t_last_s) --i1;
  std::vector<internal::Factor*> measurements;
  // The span [i0, i1] as a chain problem; `warm`: Gaussian warm-up
  // turn-rate factors instead of the robust ones.
  const auto build = [&](bool warm) {
    internal::ChainProblem chain;
    chain.moment = moment.data();
    chain.groups.resize(i1 - i0 + 1);
    for (std::size_t k = i0; k <= i1; ++k) {
      chain.states.push_back(x[k].data());
      auto& group = chain.groups[k - i0];
      for (const auto& f : factors[k]) {
        const bool process = f.kind != internal::Factor::Kind::kMeasurement;
        if (process && (k == i1 || (warm && f.kind == internal::Factor::Kind::kTurnRate))) continue;
        group.push_back(&f);
      }
      if (warm && k < i1) group.push_back(&warm_turn[k]);
    }
    return chain;
  };
  const auto state_of = [&](std::size_t k) {
    return CtState<double>{x[k](0), x[k](1), x[k](2), x[k](3), x[k](4), x[k](5)};
  };
  internal::PassResult pr;
  bool r_final_pass = false;
  // The per-sensor B offset (sensor_offset): one per sensor and segment of
  // segment_s from the first epoch. After each stage's solve, up to `passes`
  // rounds over the span: every offset set to its conditional mean given the
  // track, then the track solved again; the rounds stop once no offset moves
  // by more than tolerance_T. The restarts below keep the last offsets.
  const SensorOffsetOptions& so = options.sensor_offset;
  const double t_first = epochs.empty() ? 0.0 : epochs.front().t_s;
  using OffsetKey = std::pair<std::uint32_t, long>;
  const auto key_of = [&](const GradiometerSample& smp, double t_s) {
    return OffsetKey{smp.sensor_id, static_cast<long>(std::floor((t_s - t_first) / so.segment_s))};
  };
  std::map<OffsetKey, Eigen::Vector3d> own;
  // Every sample's factor set up with its segment's offset in `own` (zero where none).
  const auto set_offsets = [&] {
    for (std::size_t k = 0; k < epochs.size(); ++k) {
      for (std::size_t j = 0; j < epochs[k].samples.size(); ++j) {
        const auto it = own.find(key_of(epochs[k].samples[j], epochs[k].t_s));
        static_cast<MeasurementCost*>(factors[k][j].cost.get())
            ->SetBackgroundOffset(it == own.end() ? Eigen::Vector3d::Zero() : it->second);
      }
    }
  };
  const auto offset_rounds = [&](bool intermediate) {
    for (int pass = 0; pass < so.batch_passes && r_final_pass && pr.last.IsSolutionUsable(); ++pass) {
      std::map<OffsetKey, internal::SensorOffsetAccumulator> acc;
      // Only sensors where the track's predicted tensor SNR reaches
      // min_tensor_snr in the span (0: every sensor); the others' offsets back to zero.
      std::map<std::uint32_t, double> tensor_snr;
      if (so.min_tensor_snr > 0.0) {
        const Eigen::Vector3d m_B = moment * moment_scale;
        for (std::size_t k = i0; k <= i1; ++k) {
          for (const GradiometerSample& smp : epochs[k].samples) {
            double& best = tensor_snr[smp.sensor_id];
            best = std::max(best, internal::PredictedTensorSnr(smp, x[k].data(), m_B, SigmaT(smp, options)));
          }
        }
        for (auto it = own.begin(); it != own.end();) {
          it = tensor_snr[it->first.first] < so.min_tensor_snr ? own.erase(it) : std::next(it);
        }
      }
      for (std::size_t k = i0; k <= i1; ++k) {
        for (std::size_t j = 0; j < epochs[k].samples.size(); ++j) {
          const GradiometerSample& smp = epochs[k].samples[j];
          if (so.min_tensor_snr > 0.0 && tensor_snr[smp.sensor_id] < so.min_tensor_snr) continue;
          const OffsetKey key = key_of(smp, epochs[k].t_s);
          const auto it = own.find(key);
          acc[key].Add(factors[k][j], SigmaB(smp, options), it == own.end() ? Eigen::Vector3d::Zero() : it->second);
        }
      }
      // Per sensor, its segments from the first to the last with samples,
      // joined by the random walk (SegmentOffsets).
      double largest_change = 0.0;
      for (auto first = acc.begin(); first != acc.end();) {
        auto last = first;
        while (std::next(last) != acc.end() && std::next(last)->first.first == first->first.first) ++last;
        const long k0 = first->first.second, k1 = last->first.second;
        std::vector<const internal::SensorOffsetAccumulator*> segments(static_cast<std::size_t>(k1 - k0 + 1), nullptr);
        std::vector<double> sigma(segments.size());
        for (long k = k0; k <= k1; ++k) sigma[k - k0] = so.PriorSigma(t_first + (static_cast<double>(k) + 0.5) * so.segment_s);
        for (auto it = first; it != std::next(last); ++it) segments[it->first.second - k0] = &it->second;
        const std::vector<Eigen::Vector3d> o = internal::SegmentOffsets(segments, sigma, so.StepSigma());
        for (long k = k0; k <= k1; ++k) {
          const OffsetKey key{first->first.first, k};
          const auto it = own.find(key);
          const Eigen::Vector3d& ok = o[k - k0];
          largest_change = std::max(largest_change, (ok - (it == own.end() ? Eigen::Vector3d::Zero() : it->second)).norm());
          own[key] = ok;
        }
        first = std::next(last);
      }
      set_offsets();
      internal::PassResult r = internal::SolveWithContinuation(options, options.max_num_iterations, intermediate,
                                                               measurements, false, build);
      pr.iterations += r.iterations;
      pr.solve_time_s += r.solve_time_s;
      pr.last = r.last;
      pr.final_loss = std::move(r.final_loss);
      r_final_pass = r.reached_final_pass;
      if (largest_change <= so.tolerance_T) break;
    }
  };
  for (int stage = 0;; ++stage) {
    measurements.clear();
    for (std::size_t k = i0; k <= i1; ++k) {
      for (auto& f : factors[k]) {
        if (f.kind == internal::Factor::Kind::kMeasurement) measurements.push_back(&f);
      }
    }
    const bool last_stage = i0 == 0 && i1 + 1 == epochs.size();
    internal::PassResult r = internal::SolveWithContinuation(options, options.max_num_iterations, !last_stage,
                                                             measurements, !warm_turn.empty(), build);
    if (stage == 0) pr.first_initial_cost = r.first_initial_cost;
    pr.iterations += r.iterations;
    pr.solve_time_s += r.solve_time_s;
    pr.last = r.last;
    pr.final_loss = std::move(r.final_loss);
    r_final_pass = r.reached_final_pass;
    if (so.batch) offset_rounds(!last_stage);
    if (i0 == 0 && i1 + 1 == epochs.size()) break;
    const double grow = (epochs[i1].t_s - epochs[i0].t_s) * (options.batch_growth_factor - 1.0) * 0.5 + 1.0;
    const std::size_t old0 = i0, old1 = i1;
    while (i0 > 0 && epochs[i0 - 1].t_s >= epochs[old0].t_s - grow) --i0;
    while (i1 + 1 < epochs.size() && epochs[i1 + 1].t_s <= epochs[old1].t_s + grow) ++i1;
    // A span that would cover most of the pass becomes the whole pass (one
    // stage less, the cost of a stage being proportional to its length).
    if (3 * (i1 - i0 + 1) >= 2 * epochs.size()) {
      i0 = 0;
      i1 = epochs.size() - 1;
    }
    for (std::size_t k = old1 + 1; k <= i1; ++k) {
      const CtState<double> s = PropagateCoordinatedTurn(state_of(old1), epochs[k].t_s - epochs[old1].t_s);
      x[k] << s.x, s.y, s.z, s.v, s.heading, s.turn_rate;
    }
    for (std::size_t k = i0; k < old0; ++k) {
      const CtState<double> s = PropagateCoordinatedTurn(state_of(old0), epochs[k].t_s - epochs[old0].t_s);
      x[k] << s.x, s.y, s.z, s.v, s.heading, s.turn_rate;
    }
  }
  // Restarts: from the estimate with a piecewise-constant turn rate
  // (TrackerOptions::batch_turn_change_points), then from each of `starts`;
  // each kept if it ends lower by kMinTurnRestartGain. Every usable end is a
  // candidate model (its change points, its turn) for the covariance below.
  struct Candidate {
    double cost;
    std::vector<StateVector> x;
  };
  std::vector<Candidate> candidates;
  const bool restarting = r_final_pass && pr.last.IsSolutionUsable() &&
                          (options.batch_turn_change_points > 0 || (starts != nullptr && !starts->empty()));
  if (restarting) {
    const auto cost_now = [&] { return internal::TotalCost(build(false).groups, options.num_threads); };
    double cost = cost_now();
    candidates.push_back({cost, x});
    // Solves from x as set by `set` (which returns false if it set nothing).
    const auto restart = [&](const std::function<bool()>& set) {
      const std::vector<StateVector> x_kept = x;
      const Eigen::Vector3d moment_kept = moment;
      if (!set()) return;
      internal::PassResult r = internal::SolveWithContinuation(options, options.max_num_iterations, false,
                                                               measurements, false, build);
      pr.iterations += r.iterations;
      pr.solve_time_s += r.solve_time_s;
      const double cost_r = cost_now();
      ++sum.num_turn_restarts;
      const bool usable = r.reached_final_pass && r.last.IsSolutionUsable() && std::isfinite(cost_r);
      if (usable) candidates.push_back({cost_r, x});
      if (usable && cost_r < cost - kMinTurnRestartGain) {
        cost = cost_r;
        pr.last = r.last;
        pr.final_loss = std::move(r.final_loss);
        ++sum.num_turn_restarts_kept;
      } else {
        x = x_kept;
        moment = moment_kept;
        for (internal::Factor* f : measurements) f->loss = pr.final_loss.get();
      }
    };
    bool fitted = true;
    for (int cps = 1; cps <= options.batch_turn_change_points && fitted; ++cps) {
      restart([&] {
        std::vector<double> w;
        for (std::size_t k = i0; k <= i1; ++k) w.push_back(x[k](5));
        const std::vector<double> fit = PiecewiseConstantFit(w, cps);
        fitted = !fit.empty();
        for (std::size_t k = i0; k < i0 + fit.size(); ++k) x[k](5) = fit[k - i0];
        return fitted;
      });
    }
    if (starts != nullptr) {
      for (const BatchStart& start : *starts) {
        restart([&] {
          bool any = false;
          for (std::size_t k = i0; k <= i1; ++k) {
            const std::optional<CtState<double>> s = start(epochs[k].t_s);
            if (!s) continue;
            x[k] << s->x, s->y, s->z, s->v, s->heading, s->turn_rate;
            any = true;
          }
          return any;
        });
      }
    }
  }
  // The problem with every solved (sensor, segment) offset a parameter block
  // (nT): each sample's factor then depends on its segment's offset
  // (OffsetMeasurementCost, at the offset its factor was set up with), with
  // the offsets' priors and the random walk between a sensor's consecutive
  // segments. The joint solve below and the covariance use it.
  struct OffsetProblem {
    std::map<OffsetKey, Eigen::Vector3d> offset_nT;  // the offset blocks
    std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  };
  const auto add_offset_problem = [&](ceres::Problem* problem, OffsetProblem* op) {
    for (const auto& [key, o] : own) op->offset_nT.emplace(key, o * 1e9);
    std::map<const internal::Factor*, OffsetKey> keyed;
    for (std::size_t k = 0; k < epochs.size(); ++k) {
      for (std::size_t j = 0; j < epochs[k].samples.size(); ++j) {
        const OffsetKey key = key_of(epochs[k].samples[j], epochs[k].t_s);
        if (own.count(key) != 0) keyed[&factors[k][j]] = key;
      }
    }
    for (const auto& group : build(false).groups) {
      for (const internal::Factor* f : group) {
        const auto it = keyed.find(f);
        if (it == keyed.end()) {
          internal::AddToProblem(*f, problem);
          continue;
        }
        Eigen::Vector3d& o = op->offset_nT.at(it->second);
        op->costs.push_back(std::make_unique<internal::OffsetMeasurementCost>(
            static_cast<const MeasurementCost*>(f->cost.get()), o));
        problem->AddResidualBlock(op->costs.back().get(), const_cast<ceres::LossFunction*>(f->loss), f->blocks[0],
                                  f->blocks[1], o.data());
      }
    }
    for (auto it = op->offset_nT.begin(); it != op->offset_nT.end(); ++it) {
      const double t_mid = t_first + (static_cast<double>(it->first.second) + 0.5) * so.segment_s;
      op->costs.push_back(std::make_unique<internal::OffsetPriorCost>(so.PriorSigma(t_mid) * 1e9));
      problem->AddResidualBlock(op->costs.back().get(), nullptr, it->second.data());
      const auto next = std::next(it);
      if (next != op->offset_nT.end() && next->first.first == it->first.first &&
          next->first.second == it->first.second + 1) {
        op->costs.push_back(std::make_unique<internal::OffsetStepCost>(so.StepSigma() * 1e9));
        problem->AddResidualBlock(op->costs.back().get(), nullptr, it->second.data(), next->second.data());
      }
    }
  };
  // The joint solve (SensorOffsetOptions::batch_joint), from the rounds' end;
  // its summary is the batch's (a joint solve that fails keeps the rounds').
  if (so.batch && so.batch_joint && !own.empty() && r_final_pass && pr.last.IsSolutionUsable()) {
    ceres::Problem problem(internal::NonOwningProblemOptions());
    OffsetProblem op;
    add_offset_problem(&problem, &op);
    const ceres::Solver::Options sopt =
        internal::SparseSolverOptions(options, options.max_num_iterations, options.function_tolerance);
    const std::vector<StateVector> x_kept = x;
    const Eigen::Vector3d moment_kept = moment;
    ceres::Solver::Summary js;
    ceres::Solve(sopt, &problem, &js);
    pr.iterations += static_cast<int>(js.iterations.size()) - 1;
    pr.solve_time_s += js.total_time_in_seconds;
    if (js.IsSolutionUsable()) {
      for (const auto& [key, o] : op.offset_nT) own[key] = o * 1e-9;
      set_offsets();
      pr.last = js;
    } else {
      x = x_kept;
      moment = moment_kept;
    }
  }
  const ceres::Solver::Summary& cs = pr.last;
  sum.usable = cs.IsSolutionUsable();
  sum.converged = r_final_pass && cs.termination_type == ceres::CONVERGENCE;
  sum.iterations = pr.iterations;
  sum.final_cost = cs.final_cost;
  sum.solve_time_s = pr.solve_time_s;
  sum.message = cs.message;

  out.m_B_Am2 = moment * moment_scale;
  out.epochs.resize(epochs.size());
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    EpochEstimate& e = out.epochs[k];
    e.t_s = epochs[k].t_s;
    e.p_VinW = x[k].head<3>();
    e.speed_mps = x[k](3);
    e.heading_rad = WrapAngle(x[k](4));
    e.turn_rate_radps = x[k](5);
    e.num_samples = static_cast<int>(epochs[k].samples.size());
    e.usable = sum.usable && x[k].allFinite() && moment.allFinite();
  }
  if (score_offsets && sum.usable) {
    // The score test of the segment offsets at zero (SensorOffsetOptions::
    // batch_score_test): per (sensor, segment) the robust score ‖Σ w r/σ²‖²
    // over its information Σ w/σ² (r the sample's B residual, w the loss's
    // weight ρ′ at the solution: n ‖ē‖² of the whitened residuals where
    // every w is 1; a gross outlier weighs little, as in the solve).
    std::map<OffsetKey, internal::SensorOffsetAccumulator> scores;
    for (std::size_t k = 0; k < epochs.size(); ++k) {
      for (std::size_t j = 0; j < epochs[k].samples.size(); ++j) {
        const GradiometerSample& smp = epochs[k].samples[j];
        scores[key_of(smp, epochs[k].t_s)].Add(factors[k][j], SigmaB(smp, options), Eigen::Vector3d::Zero());
      }
    }
    internal::SumScores(scores, &sum.offset_score_chi2, &sum.offset_score_dof);
  }

  if (options.compute_covariance && sum.usable) {
    const auto t_cov = std::chrono::steady_clock::now();
    std::vector<StateCovariance> P(x.size());
    Eigen::Matrix3d P_m;
    // With the sensor offsets solved, the covariance has them marginalised:
    // each (sensor, segment) offset a parameter block of the covariance's
    // problem, with its prior and the random walk between a sensor's
    // consecutive segments (the chain method has one global block only).
    const bool marginal_offsets = so.batch && !own.empty();
    if (options.covariance_method == TrackerOptions::CovarianceMethod::kChain && !marginal_offsets) {
      sum.covariance_ok = internal::ChainCovariance(build(false), &P, &P_m);
    } else {
      ceres::Covariance::Options co;
      co.algorithm_type = ceres::SPARSE_QR;
      co.num_threads = options.num_threads;
      ceres::Covariance cov(co);
      ceres::Problem problem(internal::NonOwningProblemOptions());
      OffsetProblem op;
      if (!marginal_offsets) {
        internal::AddToProblem(build(false), &problem);
      } else {
        add_offset_problem(&problem, &op);
      }
      std::vector<std::pair<const double*, const double*>> blocks;
      for (auto& s : x) blocks.emplace_back(s.data(), s.data());
      blocks.emplace_back(moment.data(), moment.data());
      sum.covariance_ok = cov.Compute(blocks, &problem);
      if (sum.covariance_ok) {
        for (std::size_t k = 0; k < x.size(); ++k) {
          Eigen::Matrix<double, 6, 6, Eigen::RowMajor> C;
          cov.GetCovarianceBlock(x[k].data(), x[k].data(), C.data());
          P[k] = C;
        }
        Eigen::Matrix<double, 3, 3, Eigen::RowMajor> Cm;
        cov.GetCovarianceBlock(moment.data(), moment.data(), Cm.data());
        P_m = Cm;
      }
    }
    if (sum.covariance_ok && options.batch_variance_factor.enabled && !epochs.empty() &&
        (!marginal_offsets || options.batch_variance_factor_with_offsets)) {
      // The a-posteriori variance factor per epoch (TrackerOptions::
      // batch_variance_factor): the conditional covariance scaled where the
      // residuals say the samples hold more than the noise; the spread of
      // the other models (below) is added unscaled. On top of solved offsets
      // too unless batch_variance_factor_with_offsets is off.
      std::vector<WhitenedResidual> residuals;
      residuals.reserve(static_cast<std::size_t>(sum.num_samples));
      for (std::size_t k = 0; k < epochs.size(); ++k) {
        std::size_t j = 0;
        for (const internal::Factor& f : factors[k]) {
          if (f.kind != internal::Factor::Kind::kMeasurement) continue;
          WhitenedResidual r;
          r.t_s = epochs[k].t_s;
          r.sensor_id = epochs[k].samples[j++].sensor_id;
          if (f.cost->Evaluate(f.blocks.data(), r.e.data(), nullptr)) residuals.push_back(r);  // non-finite: left out there
        }
      }
      std::vector<double> times(epochs.size());
      for (std::size_t k = 0; k < epochs.size(); ++k) times[k] = epochs[k].t_s;
      double pass_factor = 1.0;
      const std::vector<double> factor =
          SlidingVarianceFactors(residuals, times, options.batch_variance_factor_span_s,
                                 options.measurement_loss_scale_sigma, options.batch_variance_factor, &pass_factor);
      for (std::size_t k = 0; k < x.size(); ++k) P[k] *= factor[k];
      P_m *= pass_factor;
      for (const double f : factor) {
        sum.max_variance_factor = std::max(sum.max_variance_factor, f);
        if (f > 1.0) ++sum.num_variance_factor_epochs;
      }
    }
    if (sum.covariance_ok && options.batch_model_spread && candidates.size() > 1) {
      // The covariance above is conditional on the chosen model (its change
      // points, its turn). Averaged over the candidate ends with weights
      // exp(−cost) (cost = ½ Σ ρ: a log-likelihood), the error of the chosen
      // estimate gets Σ_i w_i (x_i − x)(x_i − x)ᵀ more.
      double c_min = std::numeric_limits<double>::infinity();
      for (const Candidate& c : candidates) c_min = std::min(c_min, c.cost);
      double w_sum = 0.0;
      for (const Candidate& c : candidates) w_sum += std::exp(-(c.cost - c_min));
      for (const Candidate& c : candidates) {
        const double w = std::exp(-(c.cost - c_min)) / w_sum;
        if (!(w > 1e-12)) continue;
        for (std::size_t k = 0; k < x.size(); ++k) {
          StateVector d = c.x[k] - x[k];
          d(4) = WrapAngle(d(4));
          P[k] += w * d * d.transpose();
        }
        ++sum.num_model_spread_candidates;
      }
    }
    if (sum.covariance_ok) {
      for (std::size_t k = 0; k < x.size(); ++k) {
        if (!P[k].allFinite()) {
          out.epochs[k].usable = false;
          continue;
        }
        out.epochs[k].cov_state = P[k];
        out.epochs[k].has_covariance = true;
      }
      out.cov_m_B = P_m * (moment_scale * moment_scale);
    } else {
      for (auto& e : out.epochs) e.usable = false;  // a covariance was asked for and cannot be given
    }
    sum.covariance_time_s = Seconds(t_cov, std::chrono::steady_clock::now());
  }
  sum.offsets_solved = options.sensor_offset.batch;
  sum.total_time_s = Seconds(t_start, std::chrono::steady_clock::now());
  return out;
}

}  // namespace

TrackEstimate SolveBatch(const std::vector<Epoch>& input, const Eigen::Vector3d& B0_W,
                         const TrackerOptions& options, const std::vector<DipoleFix>* fixes,
                         const std::vector<BatchStart>* starts) {
  const SensorOffsetOptions& so = options.sensor_offset;
  std::optional<InitialTrack> init;
  if (!so.batch || !so.batch_score_test) return SolveBatchOnce(input, B0_W, options, fixes, starts, false, &init);
  TrackerOptions without = options;
  without.sensor_offset.batch = false;
  TrackEstimate est = SolveBatchOnce(input, B0_W, without, fixes, starts, true, &init);
  const Summary& s0 = est.summary;
  if (!s0.usable ||
      !internal::ScoreTestFires(s0.offset_score_chi2, s0.offset_score_dof, options.batch_variance_factor.quantile)) {
    return est;
  }
  TrackEstimate with = SolveBatchOnce(input, B0_W, options, fixes, starts, false, &init);
  with.summary.offset_score_chi2 = s0.offset_score_chi2;
  with.summary.offset_score_dof = s0.offset_score_dof;
  with.summary.total_time_s += s0.total_time_s;
  if (!with.summary.usable) {
    // The solve with the offsets failed: the one without them, saying so.
    est.summary.message += " (the solve with sensor offsets failed: " + with.summary.message + ")";
    est.summary.total_time_s = with.summary.total_time_s;
    return est;
  }
  return with;
}

}  // namespace magnav::tracker
