// Scoring a track against the reference truth, shared by the tracker tests
// (docs/ACCURACY.md, "Tracker"): metrics over the epochs whose true position
// is within 30 m horizontal range of a gradiometer, and the NEES check.
#pragma once

#include <string>
#include <vector>

#include "magnav/core/gradiometer.h"
#include "magnav/tracker/tracker.h"
#include "reference_truth.h"

namespace magnav::testing {

inline constexpr double kEvalRangeM = 30.0;

struct TrackMetrics {
  int n = 0;                 // epochs in the window with an estimate
  double rms = 0.0, max = 0.0;  // 3-D position error, m
  double nees = 0.0;         // mean eᵀP⁻¹e of the 3-D position
  // Integrated autocorrelation time of the per-epoch NEES (epochs; sum of
  // the autocorrelations up to their first negative value): n / nees_tau is
  // the effective number of independent epochs behind the mean NEES.
  double nees_tau = 1.0;
  double moment_err = 0.0;   // ‖m̂_B − m_B‖/‖m_B‖, set by the caller
  double time_s = 0.0;       // set by the caller
};

// `samples` give the gradiometer positions; estimates at instants not in
// `truth` are skipped.
TrackMetrics ScoreTrack(const std::vector<tracker::EpochEstimate>& est,
                        const std::vector<GradiometerSample>& samples, const TruthTrack& truth);

// The 99.5 % quantile of χ²(3 n_eff)/n_eff, n_eff = n / nees_tau: the largest
// mean NEES an honest covariance gives (docs/ACCURACY.md, "NEES band").
double NeesUpperBound(const TrackMetrics& m);

// Below the χ² bound (not overconfident), τ ≤ 150 epochs, and within
// kFigureMargin of the documented NEES either way. There is no χ² lower
// bound: the covariance is conservative by design (docs/ACCURACY.md).
void ExpectHonestNees(const TrackMetrics& m, double documented, const std::string& what);

}  // namespace magnav::testing
