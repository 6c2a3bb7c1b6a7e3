// A far ship modelled as what it is: one dipole outside the array (issue 24
// items 1 and 3). Its B at the sensors (6–30 nT for a 4e5 A·m² ship 100–200
// m off a 3 × 3 grid of 36 m spacing, with a 4× contrast across the grid) is
// not a low-order field and its tensor is below the noise, so neither a
// per-sensor background nor an array-wide field follows it; a dipole does,
// exactly, at every sensor.
//
// The model, over a window of recent samples (world NED, m, T, s):
//   p(t) = c + d·n(θ) + (a0 + u·(t − t_ref))·e(θ),  z(t) = z
//   n(θ) = (cos θ, sin θ), e(θ) = (−sin θ, cos θ)
//   B_far(p_S, t) = dipole B at p_S − p(t) of the moment m_W (world, constant)
// c is the sensors' horizontal centroid: the source moves on a straight line
// at constant velocity u along it, and d is the line's distance from c, held
// by a hard bound d ≥ min_range_m (a parameter bound of the solver, not a
// penalty that data can outweigh): every point of the line, at every time,
// is at least min_range_m from the centroid. A near vessel's 1/r³ bell at
// one sensor cannot be fitted by a source that far, and is not absorbed.
// Parameters: d, θ, a0, u, z, m_W (8); fitted by Ceres (a robust loss,
// Cauchy by default, on the whitened residual) over the samples given, each
// sample's B minus B0 minus every track's predicted B. The moment is linear:
// the start is the previous fit (warm) and, when there is none, it no longer
// fits or it was refused, a grid over (θ, d, a0, u) with the moment solved by
// least squares at each node; its three best distinct nodes and the warm start
// are refined on a coarse subset, the best over every sample. While fits are
// refused the estimator backs off (fits less often).
//
// On by default since 2026-11-26 (MultiTrackerOptions::far_source;
// docs/ACCURACY.md, "A far ship as a dipole outside the array": the measured
// table, and "The far source on by default": every set with it on). Where
// there is no ship its fit is refused by the rules below and nothing is
// removed.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "magnav/core/loss.h"
#include "magnav/tracker/sensor_drift.h"

namespace magnav::tracker {

struct FarSourceOptions {
  // On (the default); false: no far source is estimated or removed.
  bool enabled = true;
  // The span of recent samples a fit is made over (s): a ship's B bell is
  // ~50 s wide at 100–200 m and 3 m/s; over 60 s its straight course at
  // constant velocity is exact.
  double window_s = 60.0;
  // A fit every solve_interval_s (s), warm-started from the previous one.
  double solve_interval_s = 1.0;
  // Samples kept for the fit: one epoch every sample_interval_s (s); a far
  // ship's B changes by < 1 nT per 0.5 s.
  double sample_interval_s = 0.5;
  // No fit before the samples span this long (s).
  double min_span_s = 10.0;
  // The source stays at least min_range_m = extent_factor · R + margin_m
  // from the sensors' horizontal centroid, R the largest horizontal
  // distance of a sensor from it (3 × 3 at 36 m: R = 50.9 m, min_range 86 m,
  // 35 m outside the corner sensors; a near vessel's reach is 15 m). Both 0:
  // no constraint (for the test that shows what it is for).
  double extent_factor = 1.5;
  double margin_m = 10.0;
  // Farthest the source may be (m): a weak uniform field is not a ship at
  // infinity.
  double max_range_m = 1000.0;
  // Its height range about the sensors' mean z (m, either way).
  double max_height_m = 50.0;
  // The robust loss on the whitened B residual (per axis) and its scale.
  // Cauchy: an untracked or poorly predicted near vessel's B at the sensors
  // beside it (7–30 nT at 20–30 m from an AUV, its tensor below the noise, so
  // the sample rules below let it in) weighs little; with Huber (its first
  // form) those samples outweighed a ship still 200–300 m along its line (2–6
  // nT) and the fit went to a wrong basin or against the bound while the AUV
  // passed (docs/ACCURACY.md, "The far source's fit while the ship is far
  // along its line").
  LossType loss = LossType::kCauchy;
  double loss_sigmas = 3.0;
  // Sample rules (as the cluster background's): a sample enters the fit
  // only if its residual tensor (sample minus the tracks' predicted tensor,
  // whitened, ‖·‖²/9) is at most tensor_gate (no untracked near source) and
  // the tracks' predicted tensor SNR there is below occupied_tensor_snr (no
  // tracked vessel near).
  double tensor_gate = 4.0;
  double occupied_tensor_snr = 3.0;
  // The removed B's uncertainty: this share of its norm (per axis over √3),
  // added in quadrature to σ_B of every sample it is removed from.
  double model_share = 0.1;
  // The far field the model does not explain (T, per axis): added in
  // quadrature to σ_B of every sample the far source acts on, whether or not
  // a fit is accepted (model_share covers an accepted fit's error in
  // proportion to its B; this covers the ship's B while no fit is accepted or
  // while the accepted one is still off, 1–9 nT at the sensors on the
  // far-ship files of docs/ACCURACY.md, "A weak AUV beside a far ship: the
  // window's failures and an allowance ..."): a weak vessel's start leans on
  // its tensor, which a far ship's does not reach. Off by default: it costs
  // weak starts elsewhere (held-out abreast: no track). 0: off.
  double unexplained_sigma_T = 0.0;
  // Whether that allowance also reaches the initiator's searches (true, as
  // when it was built) or only the fits (false: InitOptions::
  // fix_sigma_B_allowance_T takes it out of the single-sample fixes and the
  // pair start's two-dipole fit, whose misfit gates decide whether a weak
  // vessel is started; the single start's moment fit, the association and
  // the solves keep it). Only with unexplained_sigma_T > 0.
  bool unexplained_in_fix_search = true;
  // A fit whose largest B at the sensors is below this (T) is not removed
  // (nothing far to remove).
  double min_field_T = 2e-9;
  // What is removed is a ship: a fit whose moment is below min_moment_Am2
  // (an AUV's is ~2e3, a ship's 1e5–1e6) or whose line lies within
  // bound_slack_m of min_range_m (pressed against the bound: the data want
  // a nearer source, the tracks' business) is not removed. On the tuning
  // files the fits made of near vessels' fields (no ship there) had 1e4–4e4
  // A·m², each at the bound; the ship's 4.4e5 A·m², 95 m inside it.
  double min_moment_Am2 = 1e5;
  double bound_slack_m = 5.0;
  // A fit at the bound whose moment is at least this (A·m²) is not refused
  // for being at the bound (0 = off, the default: every fit at the bound is
  // refused, as before). A ship still far along its line is fitted at the
  // bound (nearer than it is) with a ship's moment: on
  // fresh_farsrc3/far_ship_112 main refused
  // such fits at 52–57 s (2.4e5–4.2e5 A·m², their B 1.5–2.4 nT from the
  // ship's) and so left its 11–19 nT in the samples, then backed off for 8 s
  // (docs/ACCURACY.md, "Far-ship files that still failed ..."); the fits made
  // of a near vessel's field had 1e4–6e4 A·m² (refused by min_moment_Am2
  // before this rule is reached).
  double bound_accept_moment_Am2 = 0.0;
  // A fit whose moment is above this (A·m²) is not removed: no ship is that
  // strong (the scenarios' 4e5–5e5, a large ship's ~1e6), and a drift of every
  // sensor's B0 is mimicked by a source of 4e6–4e7 A·m² 350–620 m off, at the
  // limits of the fit's box (fresh_drift2/drift_4_crossing, fresh_drift/
  // drift_6_farship: docs/ACCURACY.md, "The AUV's B from before its track in
  // the far source's samples"). 0 = off, the default: any moment is removed.
  double max_moment_Am2 = 0.0;
  // A track started after some of the kept samples: its field there was not
  // subtracted when they were kept (it had no track yet), so a weak AUV's B
  // before its track (7–25 nT at the sensors beside it, its tensor below the
  // sample rules' gate) sits in the fit's window until it leaves it — the
  // cause of far_ship_112's and crossing_far_ship_140's bad fits
  // (docs/ACCURACY.md, "Far-ship files that still failed ..."). On: at each
  // fit every kept sample older than a live track's start gets that track's
  // field as its state now predicts it back to the sample's time (its
  // coordinated-turn model run backwards, the moment constant): where its
  // predicted tensor SNR is at least occupied_tensor_snr or its predicted B
  // at least 3 σ_B (the quiet store's rule for a new track's approach; since
  // session 19: subtracting a strong back-predicted B moved the fits by its
  // error) the sample is left out of the fit (occupied), else its B is
  // subtracted and its model error added to σ (MultiTracker:
  // MultiTrackerOptions::kOtherFieldRelativeError of it, as for the tracks
  // known when it was kept).
  // Nothing is given back where a track live when the sample was kept was
  // within TrackManagementOptions::min_separation_m of the new track's
  // back-predicted position (its vessel's B was subtracted then): a track
  // re-acquired or restarted after an earlier one of the same vessel ended
  // would have that B taken out twice (fresh_drift/drift_6_farship:
  // docs/ACCURACY.md, "The same vessel's B taken out twice ..."). On by
  // default since session 20 (docs/ACCURACY.md, "The far source's
  // back-prediction on by default": 8 scenario rows meet every target that did
  // not, the crossing pairs beside a ship among them; one row, already at the
  // bound, leaves it by 0.006 m); false: kept as kept.
  bool back_predict_new_tracks = true;
  // At most this many samples enter one fit: beyond it, an even stride over
  // the window's samples (epoch after epoch, so the sensors kept change from
  // one epoch to the next). A 3 × 3 grid over 60 s at 0.5 s has 1080, all
  // kept; 100 sensors would have 12 000, whose refit every second cost
  // 0.11 CPU s per s of data (docs/BENCHMARKS.md), 3× the whole tracker.
  int max_samples = 1500;
  // Each sensor's drift (sensor_drift.h), fitted on the same kind of samples
  // (over its own, longer window) minus the far source's B, the far source
  // then on its samples minus the drift (one block step each per fit; the
  // previous fit's far source for the drift); both removed. Off by default
  // (sensor_drift.h says why).
  SensorDriftOptions drift;
  // Back-off: while fits are refused (no ship-like source: the rules above)
  // or there are no samples, the interval to the next fit doubles after each
  // refused one, up to max_interval_s (s); an accepted fit sets it back to
  // solve_interval_s. max_interval_s = solve_interval_s: no back-off. A ship
  // that appears is found at most max_interval_s later (its B changes by
  // < 1 nT in 8 s at 100–200 m).
  double max_interval_s = 8.0;
  // The start grid's along-line positions of the source at the newest sample
  // reach ±along_extent_m from the line's closest point to the centroid
  // (step along_step_m): a ship 150 m off at 3 m/s is 250–300 m along its
  // line when its B (~5 nT) first matters.
  double along_extent_m = 300.0;
  double along_step_m = 60.0;
  // After a refused fit the next one searches the start grid as well (the
  // refused fit's basin may be a wrong one: a mirror of the ship, or a source
  // pressed against the bound while the ship is still far along its line);
  // false: the grid only when the previous fit no longer fits (its first form).
  bool grid_when_refused = true;

  bool IsValid(std::string* error) const;
};

// Why the newest fit was not removed (kNone: it was, or no fit yet).
enum class FarSourceRefusal { kNone, kNoFit, kSmallMoment, kAtBound, kWeakField, kLargeMoment };
const char* FarSourceRefusalName(FarSourceRefusal r);

// What the far source did over the data so far: a user must see when it
// acted (magnav track's summary, magnav-tracker's stats line).
struct FarSourceStats {
  int num_fits = 0;               // fits made
  int num_accepted = 0;           // fits whose source was removed
  int num_refused_no_fit = 0;     // too few samples or sensors, or the solver failed
  int num_refused_moment = 0;     // moment below min_moment_Am2
  int num_refused_bound = 0;      // line within bound_slack_m of the bound
  int num_refused_weak = 0;       // its B below min_field_T at every sensor
  int num_refused_large = 0;      // moment above max_moment_Am2
  int num_grid_searches = 0;      // fits that searched the start grid
  // FarSourceOptions::back_predict_new_tracks: kept samples (counted once per
  // fit) given a later track's back-predicted B, and left out as occupied by it.
  long long num_pre_track_corrected = 0;
  long long num_pre_track_occupied = 0;
  // ... and (per fit) given nothing by a later track because a track live
  // when it was kept was at that track's vessel then (its B already out).
  long long num_pre_track_already_tracked = 0;
  double active_s = 0.0;          // time of data from which its B was removed (s)
  bool has_accepted = false;      // the last accepted fit:
  double last_t_s = 0.0;          //   its newest sample's time (s)
  Eigen::Vector3d last_p_W = Eigen::Vector3d::Zero();  // its position then (world NED, m)
  double last_range_m = 0.0;      //   horizontal distance from the sensors' centroid (m)
  double last_moment_Am2 = 0.0;   //   |m| (A·m²)
  // "far source: F fits (A accepted, R refused: ...), its B removed for T s; last at ..."
  std::string BriefReport() const;
};

// One sample's residual B (sample − B0 − every track's predicted B; world
// NED, T) at a sensor position (world NED, m) and time (s), its σ per axis (T).
struct FarSourceSample {
  std::uint32_t sensor_id = 0;  // for the drift (sensor_drift.h)
  double t_s = 0.0;
  Eigen::Vector3d p_SinW = Eigen::Vector3d::Zero();
  Eigen::Vector3d r_W = Eigen::Vector3d::Zero();
  double sigma_T = 1e-9;
  double tracks_B_T = 0.0;  // ‖Σ tracks' predicted B‖ there (T): the drift's occupied rule
  // z of the sensor's residual tensor averaged over the drift's
  // tensor_mean_window_s (sensor_drift.h): the drift's near-source rule.
  double residual_tensor_mean_z = 0.0;
  // The sample's tensor σ per element (T/m): the occupied rule of a track
  // started after it (FarSourceOptions::back_predict_new_tracks).
  double sigma_tensor_Tpm = 0.0;
};

// FarSourceOptions::back_predict_new_tracks: whether a later track's
// back-predicted position at a kept sample's time (world NED, m) was already
// tracked when the sample was kept — a track whose B was subtracted from it
// (`p_tracked_W`, AddEpoch) within `same_vessel_m` horizontally (m;
// MultiTracker: TrackManagementOptions::min_separation_m, within which two
// tracks are one vessel). Then that vessel's B is not in the sample: nothing
// is given back.
bool TrackedWhenKept(const Eigen::Vector3d& p_then_W, const std::vector<Eigen::Vector3d>& p_tracked_W,
                     double same_vessel_m);

// A fitted far source (see the model above).
struct FarSourceModel {
  bool valid = false;
  double t_ref_s = 0.0;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  // sensors' horizontal centroid (m)
  double min_range_m = 0.0;                             // the bound d was held to
  double d_m = 0.0, theta_rad = 0.0, a0_m = 0.0, u_mps = 0.0, z_m = 0.0;
  Eigen::Vector3d m_W = Eigen::Vector3d::Zero();  // A·m², world NED
  double rms_whitened = 0.0;                      // the fit's residual RMS per axis / σ
  int num_samples = 0;
  double t_first_s = 0.0, t_last_s = 0.0;         // samples' span

  Eigen::Vector3d PositionAt(double t_s) const;
  // Its B (T) at a sensor position at time t_s (zero if not valid).
  Eigen::Vector3d BAt(const Eigen::Vector3d& p_SinW, double t_s) const;
  // Horizontal distance of its position from the centroid at t_s (m).
  double RangeAt(double t_s) const;
};

// The bound for a set of sensor positions (options' extent_factor, margin_m).
double FarSourceMinRange(const std::vector<Eigen::Vector3d>& sensors, const FarSourceOptions& options,
                         Eigen::Vector2d* centroid = nullptr);

// Fits the model to `samples` (any order); `sensors`: the sensors' positions
// (for the centroid and the bound). `warm` (may be null): a previous fit, one
// more start; the start grid is searched too when there is none, when it no
// longer fits, or when `search_grid` (the previous fit was refused: its basin
// may be the wrong one). Invalid model if there are fewer than 10 samples or
// fewer than 4 sensors (an array's model). `searched` (may be null): whether
// the grid was searched.
FarSourceModel FitFarSource(const std::vector<FarSourceSample>& samples, const std::vector<Eigen::Vector3d>& sensors,
                            const FarSourceOptions& options, const FarSourceModel* warm = nullptr,
                            bool search_grid = false, bool* searched = nullptr);

// The streaming side: residuals of recent epochs in, a fit every
// solve_interval_s, the far source's B at a sample out.
class FarSourceEstimator {
 public:
  explicit FarSourceEstimator(const FarSourceOptions& options = {}) : options_(options), drift_(options.drift) {}
  bool enabled() const { return options_.enabled; }
  // Whether an epoch at t_s is kept for the fit (one per sample_interval_s).
  bool WantsEpoch(double t_s) const;
  // One epoch's residual samples (those that passed the sample rules), the
  // positions of every sensor in it, and the positions of the live tracks
  // whose predicted B was subtracted from them (world NED, m; for
  // FarSourceOptions::back_predict_new_tracks).
  void AddEpoch(double t_s, const std::vector<FarSourceSample>& used, const std::vector<Eigen::Vector3d>& sensors,
                const std::vector<Eigen::Vector3d>& p_tracked_W = {});
  // What a kept sample gets from the tracks started after its time
  // (FarSourceOptions::back_predict_new_tracks).
  struct PreTrackField {
    Eigen::Vector3d B_W = Eigen::Vector3d::Zero();  // their B there, as they now predict it back (world NED, T)
    Eigen::Matrix3d T_W = Eigen::Matrix3d::Zero();  // their tensor there (T/m)
    double var_T2 = 0.0;                            // its model error's variance per axis of B (T²)
    int num_given = 0;                              // tracks whose field is in B_W, T_W
    // Tracks started after it whose back-predicted position was within
    // reach of a track live when it was kept (`p_tracked_W`): that vessel's
    // B was subtracted then, nothing given.
    int num_already_tracked = 0;
  };
  // The correction of one kept sample, given the positions of the tracks
  // whose B was subtracted from it when it was kept.
  using PreTrackFieldFn =
      std::function<void(const FarSourceSample&, const std::vector<Eigen::Vector3d>& p_tracked_W, PreTrackField*)>;
  // Refits when due at t_s; returns whether it did. `pre_track` (may be
  // empty; used only with back_predict_new_tracks): the correction above.
  bool StepIfDue(double t_s, const PreTrackFieldFn& pre_track = {});
  // The far source's B and the sensor's drift to remove at a sensor at t_s,
  // and their σ per axis (T, in quadrature); the far source's part zero while
  // there is no fit or its field is below min_field_T, the drift's while the
  // sensor has none; unexplained_sigma_T always in the σ.
  Eigen::Vector3d B(std::uint32_t sensor_id, const Eigen::Vector3d& p_SinW, double t_s, double* sigma_T) const;
  const FarSourceModel& model() const { return model_; }
  const SensorDrift& drift() const { return drift_; }
  bool active() const { return active_; }
  FarSourceRefusal refusal() const { return refusal_; }
  const FarSourceStats& stats() const { return stats_; }
  // The interval to the next fit (s): solve_interval_s, or longer while
  // fits are refused (the back-off).
  double interval_s() const { return interval_s_; }
  // Its whole state for a checkpoint (core/checkpoint.h: every kept sample,
  // the drift's samples and lines, the fit, its refusal, back-off and
  // counters): a restored estimator goes on bit for bit. The options are the
  // configuration's (RestoreState keeps this estimator's).
  void SaveState(StateWriter& w) const;
  void RestoreState(StateReader& r);

 private:
  FarSourceOptions options_;
  struct Kept {
    double t_s;
    std::vector<FarSourceSample> used;
    std::vector<Eigen::Vector3d> p_tracked_W;  // the live tracks whose B was subtracted (world NED, m)
  };
  std::deque<Kept> kept_;
  std::deque<Kept> drift_kept_;  // the drift's window (sensor_drift.h)
  double last_drift_kept_t_ = -std::numeric_limits<double>::infinity();
  std::vector<Eigen::Vector3d> sensors_;
  double last_kept_t_ = -std::numeric_limits<double>::infinity();
  double last_fit_t_ = -std::numeric_limits<double>::infinity();
  FarSourceModel model_;
  bool active_ = false;
  SensorDrift drift_;
  FarSourceRefusal refusal_ = FarSourceRefusal::kNone;
  double interval_s_ = -1.0;  // < 0: solve_interval_s (set on the first fit)
  FarSourceStats stats_;
};

}  // namespace magnav::tracker
