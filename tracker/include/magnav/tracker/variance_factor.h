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

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "magnav/tracker/options.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

// VarianceFactorOptions: options.h (the batch's factor is a TrackerOptions field).

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

// The batch's factor per epoch (TrackerOptions::batch_variance_factor,
// applied in SolveBatch): the whitened 8-residuals of a batch's samples at
// its solution, each clipped to norm ≤ clip_sigma (one wild sample moves a
// sensor's mean by at most clip_sigma / n); for each time in times_s, the
// samples within ±span_s/2 of it, χ² and dof as kSensorMeans (per sensor j,
// n_j ‖ē_j‖², 8 dof) or kResiduals (Σ ‖e‖², 8 per sample), and the factor
// VarianceFactor(χ², dof) — the window's question, asked of the span
// centred on each epoch. `pass_factor`, if given: the same over the whole
// pass (for the moment's covariance).
struct WhitenedResidual {
  double t_s = 0.0;
  std::uint32_t sensor_id = 0;
  Eigen::Matrix<double, 8, 1> e = Eigen::Matrix<double, 8, 1>::Zero();
};
std::vector<double> SlidingVarianceFactors(const std::vector<WhitenedResidual>& residuals,
                                           const std::vector<double>& times_s, double span_s, double clip_sigma,
                                           const VarianceFactorOptions& options, double* pass_factor = nullptr);

// cov_state ×= factor (when the estimate has a covariance).
void ScaleCovariance(double factor, EpochEstimate* estimate);

}  // namespace magnav::tracker
