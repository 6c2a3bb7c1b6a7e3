// One entry point over every matcher (what `magnav match` and the accuracy
// tests run): a method name and every method's options.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "magnav/mapmatch/correlation.h"
#include "magnav/mapmatch/fast_msd.h"
#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/icp.h"
#include "magnav/mapmatch/observability.h"
#include "magnav/mapmatch/particle_filter.h"
#include "magnav/mapmatch/path.h"
#include "magnav/mapmatch/point_match.h"

namespace magnav::mapmatch {

enum class Method { kPoint, kIcp, kIccp, kMma, kMad, kMsd, kProd, kNprod, kFastMsd, kPf, kAfpf };

// "point", "icp", "iccp", "mma", "mad", "msd", "prod", "nprod", "fast-msd",
// "pf", "afpf" (the sequential filters of particle_filter.h, run over the path).
const char* MethodName(Method method);
std::optional<Method> ParseMethod(std::string_view name);
// Every method name, separated by '|' (for help texts and errors).
std::string MethodNames();

struct MatchOptions {
  PointMatchOptions point;
  IcpOptions icp;
  IccpOptions iccp;
  MmaOptions mma;
  // metric is set from the method; search_window_deg has no default.
  CorrelationOptions correlation;
  FastMsdOptions fast_msd;
  ParticleFilterOptions particle_filter;  // pf and afpf
  // The largest correction (deg) a result may make and still be called
  // converged (the prior on the INS error); 0 = the method's own reach
  // (PlausibleCorrectionDeg).
  double max_correction_deg = 0.0;
  // The prior on the INS error and the "partly observable" threshold
  // (observability.h; --ins-start-sd, --ins-drift-sd, --min-observability).
  // Not given: ResolvedInsPrior (the filters' own; else a constant offset whose 3 sigma is PlausibleCorrectionDeg).
  ObservabilityOptions observability;
};

// How far (deg) a method looks for the path from its INS positions: the
// search window (mad|msd|prod|nprod, fast-msd's coarse stage), the prior's
// half-width (pf, afpf), else 0 (the others start from the INS positions).
double SearchReachDeg(Method method, const MatchOptions& options);

// The largest correction (deg, any point) a result may make and still be
// called converged: max_correction_deg if given; else 2 × the search window
// (mad|msd|prod|nprod, fast-msd with a coarse stage: the shift plus as much
// again for the per-point drift), 2 × the prior's half-width (pf, afpf); else
// (point, icp, iccp, mma, fast-msd without a coarse stage, which refine a
// path from where the INS put it) the diagonal of the INS path's bounding
// box, at least 2 grid cells: a correction larger than the path itself is a
// match somewhere else, not a correction.
double PlausibleCorrectionDeg(Method method, const GeoGrid& grid, const MatchPath& path, const MatchOptions& options);

// Throws InputError "METHOD: the path is entirely off the map: ..." when none
// of the path's INS points lies within SearchReachDeg of the map's grid.
// What the map observes of the INS error along the result (ObservePath with
// `prior`, σ = the matched residuals' rms, at least min_noise_sd_nT): sets
// result->observability (the summary's line) and observability_ratio. When
// the ratio is below options.min_information_ratio (partly observable): each
// point's published covariance (fast-msd: MatchResult::cov_*, against the
// smoothed posterior; pf/afpf: the steps' cov_*, against the filtered one) is
// raised along its least known direction to what the map and the prior can
// know there (FloorAlongLeastKnown), and a converged result becomes "not
// converged: partly observable: along-iso-line error unconstrained (map
// information X of the prior's ...)". Rough (crustal) maps observe both
// directions (ratio >> 1): nothing changes there but the summary's line.
void ReviewObservability(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const InsErrorPrior& prior,
                         const ObservabilityOptions& options, MatchResult* result,
                         std::vector<StepDiagnostics>* steps = nullptr);

void RequirePathNearMap(Method method, const GeoGrid& grid, const MatchPath& path, const MatchOptions& options);

// The prior Match uses: options.observability.prior if given; else for pf and
// afpf their own (start_sd = prior_half_width / sqrt(3), the uniform square's;
// drift_sd = drift_sigma_deg), for the others a constant offset with start_sd
// = PlausibleCorrectionDeg / 3.
InsErrorPrior ResolvedInsPrior(Method method, const GeoGrid& grid, const MatchPath& path, const MatchOptions& options);
// pf and afpf's own prior on the INS error (what ResolvedInsPrior gives them;
// magnav-matcher's): start_sd = prior_half_width / sqrt(3), drift_sd = drift_sigma_deg.
InsErrorPrior ParticleFilterInsPrior(const ParticleFilterOptions& options);

// Runs one method over the path (steps: pf, afpf's per-step diagnostics).
// At the door: RequirePathNearMap. Then the status is reviewed (ReviewResult)
// and the observability (ReviewObservability).
MatchResult Match(Method method, const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                  const MatchOptions& options, std::vector<StepDiagnostics>* steps = nullptr);

// No "converged" that is not: a result with a non-finite position, one that
// moves a point further than `max_correction_deg`, one whose median
// |map − measurement| over its points on the map is no smaller than the INS
// path's, or one no better than its prior (the INS path) is set not
// converged, with the reason (the method's own reason, if any, is kept after
// it). "No better than the prior": the path's mean correction (matched − INS)
// is split along the eigen-directions of the translation's information from
// the map gradient g (nT/deg) at the matched points, J = Σ g gᵀ / s² (s² the
// matched residuals' variance with the 2 translation parameters counted);
// a component smaller than 3 sigma (3 / sqrt(λ)) is not seen by the map; when
// those components make more than half the correction and more than a grid
// cell's diagonal, the correction is a slide along the iso-lines, not a fix
// (smooth main-field maps; the truth is not used). The same test on the last
// 10 % of the points (at least 3; s² still the whole path's) catches a wrong
// shape whose mean is supported but whose end, where the fix is used, slides
// along the iso-lines there: "no better than the prior at the path's end";
// only where the path's iso-lines are nearly parallel (λ_min < 0.01 λ_max of
// J: main-field maps; not rough crustal ones, where it cost right results),
// and only when some of those last points are on the map.
void ReviewResult(const GeoGrid& grid, std::size_t layer, const MatchPath& path, double max_correction_deg,
                  MatchResult* result);

}  // namespace magnav::mapmatch
