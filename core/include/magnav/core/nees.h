// Covariance consistency over Monte-Carlo runs (Bar-Shalom, Li, Kirubarajan,
// "Estimation with Applications to Tracking and Navigation", 2001, §5.4.2):
// the normalized estimation error squared of one estimate,
//
//   NEES = eᵀ P⁻¹ e    (e = estimate − truth, P its published covariance),
//
// is χ²(dof) when P is right. Over N independent runs (same scenario, new
// noise), the run-averaged NEES at one epoch, ε̄ = (1/N) Σ_runs NEES, is
// χ²(N·dof)/N: its two-sided 95 % interval is
//   [χ²⁻¹(0.025; N·dof) / N,  χ²⁻¹(0.975; N·dof) / N].
// ANEES = the NEES averaged over runs and epochs (expected value dof). The
// project's acceptance (issue 25): ANEES within [0.5, 2] × dof.
// Units: NEES is dimensionless; squared errors in the caller's unit².
#pragma once

#include <map>
#include <string>
#include <vector>

namespace magnav {

// One NEES value: run (independent draw), epoch (time step or estimate index;
// epochs with the same number are averaged over runs), regime (e.g.
// "converging", "converged", "lost"; statistics are per regime), the NEES and
// the squared error |e|² (for the RMS; unit² of the estimate).
struct NeesSample {
  long long run = 0;
  long long epoch = 0;
  std::string regime;
  double nees = 0.0;
  double error_sq = 0.0;
};

// The `probability` quantile of χ² with `dof` degrees of freedom (dof > 0):
// +inf for probability >= 1, 0 for probability <= 0 or dof <= 0 (or NaN).
// The gates and score tests of every module (localizer NIS gates, tracker
// variance factors and offset score test).
double ChiSquareQuantile(double probability, double dof);

// Two-sided `confidence` interval of the run-averaged NEES of `runs` runs at
// `dof` degrees of freedom: χ²⁻¹((1 ∓ confidence)/2; runs·dof) / runs.
// Throws std::invalid_argument for runs < 1, dof < 1 or confidence outside (0, 1).
struct NeesInterval {
  double lo = 0.0, hi = 0.0;
};
NeesInterval RunAveragedNeesInterval(int runs, int dof, double confidence = 0.95);

struct NeesRegimeStats {
  std::size_t samples = 0;  // NEES values
  std::size_t runs = 0;     // distinct runs with a value in this regime
  std::size_t epochs = 0;   // distinct epochs with a value
  double anees = 0.0;       // mean NEES over every (run, epoch) value
  double rms = 0.0;         // sqrt(mean error_sq)
  // ANEES within [0.5, 2] × dof.
  bool anees_accepted = false;
  // Epochs whose run-averaged NEES lies in its two-sided 95 % interval (for
  // the number of runs that have a value at that epoch), and the epochs with
  // at least `min_runs_per_epoch` runs (the others are not counted).
  std::size_t epochs_tested = 0, epochs_inside = 0;
  double share_inside() const { return epochs_tested > 0 ? static_cast<double>(epochs_inside) / epochs_tested : 0.0; }
};

// Statistics per regime (the map's key; "all" is added over every sample).
// Non-finite NEES values (a singular covariance) count in samples and make
// the ANEES infinite: never silently dropped. Throws std::invalid_argument for dof < 1.
std::map<std::string, NeesRegimeStats> ComputeNeesStats(const std::vector<NeesSample>& samples, int dof,
                                                        int min_runs_per_epoch = 2);

}  // namespace magnav
