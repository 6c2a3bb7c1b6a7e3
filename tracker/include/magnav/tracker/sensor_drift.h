// Each sensor's background drift (issue 24 item 1): a sensor's B0 that
// moves by a few nT per minute in its own direction. Fitted with the far
// source (far_source.h), on the same quiet samples (no vessel near: the
// sample rule of tracker/src/quiet_sample.h, and the tracks' predicted B
// below occupied_B_sigmas), and removed from every sample with it.
//
// The model, per sensor s, over its own window (window_s, 600 s: far longer
// than the far source's 60 s, so that a far ship's bell, ~100 s wide at
// 150 m and 3 m/s, is not a line over it; world NED; T, s):
//   b_s(t) = a_s + ṙ_s·(t − t_ref)
// a straight line in time per axis (a_s: the offset from the fixed B0 at
// t_ref, the newest sample; ṙ_s: its rate, T/s). It is fitted per sensor by
// weighted least squares on the residual B (sample − B0 − the tracks'
// predicted B − the far source's B), with a Huber loss (iteratively
// reweighted on the whitened residual's norm, from the median; warm_start:
// from the previous line) that
// leaves out the samples far from the line, and a zero-mean Gaussian
// prior on the rate (rate_prior_sigma_T_per_s per axis) — the offset's prior
// is flat: the level comes from the data.
//
// Why a line over 600 s follows a drift and not a near vessel: a drift is
// a line (exactly, for the simulator's drift; to O(t²) for a slow one),
// while a passing vessel's B at a sensor is a bell a few seconds to tens of
// seconds wide; of it a line takes only its projection on {1, t}, and the
// Huber loss (from a median start) less (docs/ACCURACY.md, "A per-sensor
// drift with the far source": the measured leak). The samples near a
// tracked vessel do not enter at all (the sample rule); across them the
// line is carried. What this does not stop (measured there, why it is off
// by default): an untracked vessel's B rising over tens of seconds at the
// start of a file, when the window is short, pulls a line, and a pulled
// line, warm-started, keeps the samples that agree with it.
//
// Between fits a sensor's line is extrapolated; a sensor with too few
// samples in the window (occupied throughout) keeps its previous line.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace magnav {
class StateWriter;  // core/checkpoint.h
class StateReader;
}  // namespace magnav

namespace magnav::tracker {

struct SensorDriftOptions {
  // Off (the default): the fixed B0. On (with the far source, which it is
  // part of): each sensor's line fitted and removed. Not the default: a line
  // is still pulled by the B tails of vessels 35–65 m off before they are
  // tracked (tensor below the noise), which breaks vessels near each other
  // (docs/ACCURACY.md, "The drift lines kept off an untracked vessel's B").
  bool enabled = false;
  // Zero-mean prior on each axis of a sensor's rate (T/s, 1 σ): 20 nT/min,
  // wide against the drifts asked for (a few nT/min) and a far ship's
  // slope (tens of nT/min), tight against a line pulled by a few samples.
  double rate_prior_sigma_T_per_s = 20e-9 / 60.0;
  // Huber loss scale on a sample's whitened residual norm (over √3: per
  // axis); beyond reject_sigmas a sample is left out (a transient: a
  // vessel's B no track explains), judged against the previous line (or,
  // for a sensor's first line, after half the reweighting passes). Inf: the
  // Huber loss alone.
  double huber_sigmas = 3.0;
  double reject_sigmas = 4.0;
  // A fit whose rate exceeds max_rate_T_per_s (norm) is not taken (the
  // sensor keeps its line): 12 nT/min, twice the drifts asked for; a line
  // pulled by a vessel's rising B is steeper.
  double max_rate_T_per_s = 12e-9 / 60.0;
  // A sample where the tracks' predicted B (norm) exceeds this many σ_B of
  // the sample does not enter the drift (a tracked vessel's B there: its
  // model error is the track's; the far source's rule is on the tensor).
  double occupied_B_sigmas = 3.0;
  // A sample does not enter the drift while its sensor's residual tensor
  // (sample minus every live track's predicted tensor), averaged over the
  // last tensor_mean_window_s (s) of every epoch, is above the noise:
  // z = ‖Σ e‖²/Σ σ²/9 > tensor_mean_gate (under noise alone z ~ χ²₉/9; 2.5:
  // p ≈ 0.007). An untracked vessel 25–50 m from a sensor, whose tensor is
  // below one sample's gate while its B (3–30 nT) pulls a line, is seen by
  // its mean; a drift has no tensor (docs/ACCURACY.md, "The drift lines kept
  // off an untracked vessel's B"). 0: off (the single-sample rule alone).
  double tensor_mean_window_s = 10.0;
  double tensor_mean_gate = 2.5;
  // The batch (SolveBatchMulti) refits each sensor's line over the whole
  // pass in every refinement round, given the tracks as they are then (their
  // B subtracted, the samples near any of them left out), and removes that
  // line instead of the finder's causal one: a vessel's B before its track
  // started no longer pulls it.
  bool batch_refit = true;
  // Each refit starts from the sensor's previous line (on) or from the
  // median (off, the default: a pulled line, warm-started, keeps the samples
  // that agree with it and rejects the newer ones).
  bool warm_start = false;
  // The span of recent samples a line is fitted over (s), one epoch kept
  // every sample_interval_s (s): 600 per sensor.
  double window_s = 600.0;
  double sample_interval_s = 1.0;
  // A sensor is (re)fitted only with at least this many samples spanning at
  // least min_span_s (s) in the window.
  int min_samples = 20;
  double min_span_s = 60.0;
  // A fitted line is removed only once its trend is confirmed: its rate
  // (norm) at least confirm_min_rate_T_per_s (1.5 nT/min, below the drifts
  // asked for, 2–8 nT/min, above the 0.6–1.2 nT/min that the B tails of
  // vessels 50–75 m off leave in lines on files with no drift) and at least
  // confirm_rate_sigmas of its own σ; an unconfirmed line is kept (a warm
  // start) but not removed. 0: every fitted line removed.
  double confirm_min_rate_T_per_s = 1.5e-9 / 60.0;
  double confirm_rate_sigmas = 5.0;

  bool IsValid(std::string* error) const;
};

// One sample's residual B at a sensor (world NED, T) and its σ per axis (T).
struct DriftSample {
  std::uint32_t sensor_id = 0;
  double t_s = 0.0;
  Eigen::Vector3d r_W = Eigen::Vector3d::Zero();
  double sigma_T = 1e-9;
};

// One sensor's fitted line and its covariance (per axis: the same for the
// three axes; T², T²/s, T²/s²).
struct DriftLine {
  double t_ref_s = 0.0;
  Eigen::Vector3d offset_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d rate_W = Eigen::Vector3d::Zero();
  double var_offset = 0.0, cov_offset_rate = 0.0, var_rate = 0.0;
  int num_samples = 0;

  Eigen::Vector3d At(double t_s) const { return offset_W + rate_W * (t_s - t_ref_s); }
  // Whether its trend is confirmed (SensorDriftOptions::confirm_*).
  bool Confirmed(const SensorDriftOptions& options) const;
  // σ per axis of At(t_s) (T).
  double SigmaAt(double t_s) const;
};

// Fits one sensor's line to its samples (any order), from `warm` (its
// previous line; may be null). False (line untouched) if there are fewer
// than min_samples or they span less than min_span_s.
bool FitDriftLine(const std::vector<DriftSample>& samples, const SensorDriftOptions& options, DriftLine* line,
                  const DriftLine* warm = nullptr);

// Every sensor's line.
class SensorDrift {
 public:
  explicit SensorDrift(const SensorDriftOptions& options = {}) : options_(options) {}
  bool enabled() const { return options_.enabled; }
  // Refits every sensor that has samples (grouped by sensor_id); the others
  // keep their line.
  void Fit(const std::vector<DriftSample>& samples);
  // The drift to remove at a sensor at t_s and its σ per axis (T): zero
  // and 0 for a sensor never fitted or whose line is not confirmed.
  Eigen::Vector3d At(std::uint32_t sensor_id, double t_s, double* sigma_T = nullptr) const;
  const std::map<std::uint32_t, DriftLine>& lines() const { return lines_; }
  // Every sensor's line, for a checkpoint (core/checkpoint.h); the options
  // are the configuration's.
  void SaveState(StateWriter& w) const;
  void RestoreState(StateReader& r);

 private:
  SensorDriftOptions options_;
  std::map<std::uint32_t, DriftLine> lines_;
};

}  // namespace magnav::tracker
