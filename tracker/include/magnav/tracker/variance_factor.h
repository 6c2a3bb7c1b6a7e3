// The a-posteriori variance factor of a track's window solve (issue 24
// item 6; docs/ACCURACY.md, "The a-posteriori variance factor").
//
// A source the window does not model (an untracked vessel's field, a
// neighbour's field removed with the wrong model) leaves whitened
// residuals larger than the noise σ says, and the window's covariance,
// conditional on the model being right, is then too small. The factor
// s² = χ² / dof of the window's whitened residuals (by default of their
// per-sensor means: VarianceFactorOptions::statistic) measures that misfit;
// when it exceeds what chance allows (the `quantile` point of χ²_dof / dof),
// the track's reported covariance is scaled by s². Never below 1: a fit as
// good as the noise leaves the covariance as it is.
//
// Only the reported σ changes (the rows of MultiTracker, `magnav track`,
// `magnav-tracker`): the estimates, the association gates and the end
// rules use the unscaled covariance.
#pragma once

#include <string>

#include "magnav/tracker/options.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

struct VarianceFactorOptions {
  // On by default (docs/ACCURACY.md, "The a-posteriori variance factor"):
  // over 20 draws it moves the window's overconfident overtaking cells into
  // [1.5, 6] and fails no cell that passed. Off: covariances as the window
  // solve gives them.
  bool enabled = true;
  // The factor applies when χ²/dof exceeds this quantile of χ²_dof/dof
  // (0.99: a fit this poor happens by chance once in 100 solves). In (0, 1).
  double quantile = 0.99;
  // The factor is at most this (≥ 1): a bound against a diverged solve.
  double max_factor = 1e4;
  // What χ² and dof are:
  //  - kResiduals: every whitened residual of the window's samples (white
  //    noise assumed): χ² = 2·final_cost, dof = 8·samples (WindowVarianceFactor
  //    from the Summary; no pass over the samples);
  //  - kSensorMeans: the per-sensor means of the whitened residuals over the
  //    window, χ² = Σ_j n_j ‖ē_j‖², dof = 8·sensors
  //    (WindowTracker::ResidualMeansChi2): a slowly varying unmodelled field
  //    is a bias over the window's n_j samples, and shifts the estimate as
  //    much as n_j independent errors would, which this χ² counts (the white
  //    χ² sees it once per sample). One more evaluation of the window's
  //    measurement factors per solve.
  enum class Statistic { kResiduals, kSensorMeans };
  // kSensorMeans by default: on the held-out overtaking's window (3 draws)
  // the inside ANEES 60.8 → 3.02 with it, → 38.7 with kResiduals
  // (docs/ACCURACY.md).
  Statistic statistic = Statistic::kSensorMeans;

  bool IsValid(std::string* error) const;
};

// s² = chi2 / dof when the factor applies (enabled, dof > 0, s² above the
// quantile point), capped at max_factor; 1 otherwise.
double VarianceFactor(double chi2, double dof, const VarianceFactorOptions& options);

// The factor of a window solve from its summary, with no pass over the
// samples: χ² = 2·final_cost (½ Σ ρ(‖r‖²), r whitened; the robust loss
// only lowers it, so the factor errs low), dof = 8·num_samples — 8
// residuals per sample (B, and the trace-free T's 5), the process factors
// and the marginalisation prior together having as many residuals as the
// window has states and moment. 1 for a solve that is not usable.
double WindowVarianceFactor(const Summary& summary, const VarianceFactorOptions& options);

// The factor of a window tracker's last solve by options.statistic.
double WindowVarianceFactor(const WindowTracker& window, const VarianceFactorOptions& options);

// cov_state ×= factor (when the estimate has a covariance).
void ScaleCovariance(double factor, EpochEstimate* estimate);

}  // namespace magnav::tracker
