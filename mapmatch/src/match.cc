#include "magnav/mapmatch/match.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"

namespace magnav::mapmatch {
namespace {

constexpr std::array<std::pair<Method, const char*>, 11> kMethods = {{{Method::kPoint, "point"},
                                                                     {Method::kIcp, "icp"},
                                                                     {Method::kIccp, "iccp"},
                                                                     {Method::kMma, "mma"},
                                                                     {Method::kMad, "mad"},
                                                                     {Method::kMsd, "msd"},
                                                                     {Method::kProd, "prod"},
                                                                     {Method::kNprod, "nprod"},
                                                                     {Method::kFastMsd, "fast-msd"},
                                                                     {Method::kPf, "pf"},
                                                                     {Method::kAfpf, "afpf"}}};

MatchResult Correlate(CorrelationMetric metric, const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                      CorrelationOptions options) {
  options.metric = metric;
  return MatchCorrelation(grid, layer, path, options);
}

}  // namespace

const char* MethodName(Method method) {
  for (const auto& [m, name] : kMethods) {
    if (m == method) return name;
  }
  return "?";
}

std::optional<Method> ParseMethod(std::string_view name) {
  for (const auto& [m, n] : kMethods) {
    if (name == n) return m;
  }
  return std::nullopt;
}

std::string MethodNames() {
  std::string s;
  for (const auto& [m, n] : kMethods) {
    if (!s.empty()) s += '|';
    s += n;
  }
  return s;
}

double SearchReachDeg(Method method, const MatchOptions& options) {
  switch (method) {
    case Method::kMad:
    case Method::kMsd:
    case Method::kProd:
    case Method::kNprod:
      return options.correlation.search_window_deg;
    case Method::kFastMsd:
      return options.fast_msd.search_window_deg;
    case Method::kPf:
    case Method::kAfpf:
      return options.particle_filter.prior_half_width_deg;
    default:
      return 0.0;
  }
}

double PlausibleCorrectionDeg(Method method, const GeoGrid& grid, const MatchPath& path, const MatchOptions& options) {
  if (options.max_correction_deg > 0.0) return options.max_correction_deg;
  const double reach = SearchReachDeg(method, options);
  if (reach > 0.0) return 2.0 * reach;
  const auto [lat_lo, lat_hi] = std::minmax_element(path.lat_deg.begin(), path.lat_deg.end());
  const auto [lon_lo, lon_hi] = std::minmax_element(path.lon_deg.begin(), path.lon_deg.end());
  return std::max(std::hypot(*lat_hi - *lat_lo, *lon_hi - *lon_lo),
                  2.0 * std::hypot(grid.lat().step_deg, grid.lon().step_deg));
}

namespace {

// A component of the mean correction is supported when it exceeds this many
// sigmas of the map's constraint along it; a result whose unsupported part is
// more than kUnsupportedFraction of the correction, and longer than a grid
// cell's diagonal (a shorter slide stays within the map's resolution of the
// prior), is no better than its prior.
constexpr double kSupportSigma = 3.0;
constexpr double kUnsupportedFraction = 0.5;
// The end check looks at the last kEndFraction of the path's points, at least
// kEndMinPoints (the window whose gradient constrains the final fix).
constexpr double kEndFraction = 0.1;
constexpr std::size_t kEndMinPoints = 3;
// The iso-lines on the path are nearly parallel when the smaller eigenvalue of
// J is below this fraction of the larger (gradient directions within ~0.1 rad;
// measured at the INS points of the generated paths: WMM ≤ 0.0025, crustal
// ≥ 0.03; docs/ACCURACY.md "Wrong shape at the path's end").
constexpr double kParallelIsoLines = 0.01;

// Median |map − measurement| over the points of (lat, lon) on the map with a
// finite measurement; NaN when none is.
double MedianMisfit(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const std::vector<double>& lat,
                    const std::vector<double>& lon) {
  std::vector<double> r;
  for (std::size_t p = 0; p < path.size(); ++p) {
    if (!std::isfinite(path.measured_nT[p])) continue;
    if (const auto s = grid.Sample(layer, lat[p], lon[p])) r.push_back(std::abs(s->value_nT - path.measured_nT[p]));
  }
  if (r.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2);
  std::nth_element(r.begin(), mid, r.end());
  return *mid;
}

// What the map says about the mean correction (matched − INS, deg) of the
// points [first, path.size()): the translation's information from the map
// gradient at those matched points, J = Σ g gᵀ / s² (g in nT/deg), s² = Σ r² /
// (n − 2) the matched residuals' variance over the whole path (noise and
// whatever the fit leaves, with the 2 translation parameters counted). Along
// each eigen-direction e of J the shift is known to ±1/sqrt(λ); the part of the
// mean correction along directions where it is smaller than kSupportSigma of
// that is not a fix, only a slide the map does not see.
struct CorrectionSupport {
  double correction_deg = 0.0;   // |mean correction|
  double unsupported_deg = 0.0;  // its part along directions the map does not constrain to it
  double sd_weak_deg = 0.0;      // 1 sigma along the least constrained direction
  double residual_rms_nT = 0.0;  // s
  double weak_to_strong = 1.0;   // λ_min / λ_max of J: ≪ 1 when the iso-lines are nearly parallel
  int points = 0;                // measured points on the map in [first, end)
};

CorrectionSupport SupportOfCorrection(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                                      const MatchResult& r, std::size_t first = 0) {
  CorrectionSupport c;
  double ss = 0.0;
  int n_all = 0;
  for (std::size_t p = 0; p < path.size(); ++p) {
    if (!std::isfinite(path.measured_nT[p])) continue;
    const auto s = grid.Sample(layer, r.lat_deg[p], r.lon_deg[p]);
    if (!s) continue;
    const double res = s->value_nT - path.measured_nT[p];
    ss += res * res;
    ++n_all;
  }
  double dlat = 0.0, dlon = 0.0;
  for (std::size_t p = first; p < path.size(); ++p) {
    dlat += r.lat_deg[p] - path.lat_deg[p];
    dlon += r.lon_deg[p] - path.lon_deg[p];
  }
  dlat /= static_cast<double>(path.size() - first);
  dlon /= static_cast<double>(path.size() - first);
  c.correction_deg = std::hypot(dlat, dlon);
  double jaa = 0.0, jab = 0.0, jbb = 0.0;
  int n = 0;
  for (std::size_t p = first; p < path.size(); ++p) {
    if (!std::isfinite(path.measured_nT[p])) continue;
    const auto s = grid.Sample(layer, r.lat_deg[p], r.lon_deg[p]);
    if (!s) continue;
    const double ga = s->dvalue_dlat_nT_per_deg, gb = s->dvalue_dlon_nT_per_deg;
    jaa += ga * ga;
    jab += ga * gb;
    jbb += gb * gb;
    ++n;
  }
  c.points = n;
  if (n == 0 || n_all <= 2) {  // nothing measured: nothing of the correction is supported
    c.unsupported_deg = c.correction_deg;
    c.sd_weak_deg = std::numeric_limits<double>::infinity();
    return c;
  }
  const double s2 = std::max(ss / (n_all - 2), 1e-300);
  c.residual_rms_nT = std::sqrt(s2);
  // Eigen-decomposition of the symmetric 2×2 [jaa jab; jab jbb] / s².
  const double tr = jaa + jbb, det = jaa * jbb - jab * jab;
  const double disc = std::sqrt(std::max(tr * tr / 4.0 - det, 0.0));
  const double lam[2] = {(tr / 2.0 + disc) / s2, std::max(tr / 2.0 - disc, 0.0) / s2};
  if (lam[0] > 0.0) c.weak_to_strong = lam[1] / lam[0];
  // Eigenvector of the larger eigenvalue.
  double ea = 1.0, eb = 0.0;
  if (std::abs(jab) > 0.0) {
    ea = jab;
    eb = tr / 2.0 + disc - jaa;
    const double nrm = std::hypot(ea, eb);
    ea /= nrm;
    eb /= nrm;
  } else if (jbb > jaa) {
    ea = 0.0;
    eb = 1.0;
  }
  const double comp[2] = {dlat * ea + dlon * eb, -dlat * eb + dlon * ea};
  double un2 = 0.0;
  for (int i = 0; i < 2; ++i) {
    const double sd = lam[i] > 0.0 ? 1.0 / std::sqrt(lam[i]) : std::numeric_limits<double>::infinity();
    if (i == 1) c.sd_weak_deg = sd;
    if (std::abs(comp[i]) < kSupportSigma * sd) un2 += comp[i] * comp[i];
  }
  c.unsupported_deg = std::sqrt(un2);
  return c;
}

std::string Significant(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

void NotConverged(const std::string& why, MatchResult* r) {
  // The filters' own review (RunStatus) may have said the same already (non-finite, implausible).
  if (!r->converged && r->reason.compare(0, why.size(), why) == 0) return;
  r->reason = r->converged || r->reason.empty() ? why : why + "; " + r->reason;
  r->converged = false;
}

}  // namespace

void ReviewResult(const GeoGrid& grid, std::size_t layer, const MatchPath& path, double max_correction_deg,
                  MatchResult* r) {
  for (std::size_t p = 0; p < r->lat_deg.size(); ++p) {
    if (!std::isfinite(r->lat_deg[p]) || !std::isfinite(r->lon_deg[p])) {
      NotConverged("non-finite position in the result (k = " + std::to_string(path.k[p]) + ")", r);
      return;
    }
  }
  if (!r->converged) return;
  double moved = 0.0;
  for (std::size_t p = 0; p < path.size(); ++p) {
    moved = std::max(moved, std::hypot(r->lat_deg[p] - path.lat_deg[p], r->lon_deg[p] - path.lon_deg[p]));
  }
  if (max_correction_deg > 0.0 && moved > max_correction_deg) {
    NotConverged("implausible: moved a point " + FormatNumber(moved) + " deg, beyond the plausible correction of " +
                     FormatNumber(max_correction_deg) + " deg (max_correction_deg, --max-correction)",
                 r);
    return;
  }
  const double ins = MedianMisfit(grid, layer, path, path.lat_deg, path.lon_deg);
  const double matched = MedianMisfit(grid, layer, path, r->lat_deg, r->lon_deg);
  if (std::isfinite(ins) && moved > 0.0 && !(matched < ins)) {
    NotConverged("no better than the INS path: median |map - measurement| " + FormatNumber(matched) +
                     " nT against " + FormatNumber(ins) + " nT at the INS positions",
                 r);
    return;
  }
  const CorrectionSupport c = SupportOfCorrection(grid, layer, path, *r);
  const double cell_deg = std::hypot(grid.lat().step_deg, grid.lon().step_deg);
  if (c.unsupported_deg > kUnsupportedFraction * c.correction_deg && c.unsupported_deg > cell_deg) {
    NotConverged("no better than the prior: " + FormatNumber(c.unsupported_deg) + " deg of the mean correction " +
                     FormatNumber(c.correction_deg) +
                     " deg lies along directions the map gradient on the path does not constrain to 3 sigma "
                     "(least constrained: 1 sigma " +
                     FormatNumber(c.sd_weak_deg) + " deg at the matched residuals' rms " +
                     FormatNumber(c.residual_rms_nT) + " nT)",
                 r);
    return;
  }
  // The same at the path's end, where the fix is used: a correction that the
  // whole path supports through the map's curvature can still end as a slide
  // along the iso-lines (a wrong shape: a rotation or a bend the end's
  // gradient does not see). The last kEndFraction of the points, at least
  // kEndMinPoints; only where the iso-lines on the path are nearly parallel (a
  // main-field map): on a rough map the end's gradients point every way.
  if (!(c.weak_to_strong < kParallelIsoLines)) return;
  const std::size_t end_points = std::min(
      path.size(), std::max<std::size_t>(kEndMinPoints, static_cast<std::size_t>(std::lround(kEndFraction * path.size()))));
  const CorrectionSupport e = SupportOfCorrection(grid, layer, path, *r, path.size() - end_points);
  // An end entirely off the map is not judged here (the map says nothing
  // there; the summary counts the off-map points).
  if (e.points == 0) return;
  if (e.unsupported_deg > kUnsupportedFraction * e.correction_deg && e.unsupported_deg > cell_deg) {
    NotConverged("no better than the prior at the path's end: " + FormatNumber(e.unsupported_deg) +
                     " deg of the last " + std::to_string(end_points) + " points' mean correction " +
                     FormatNumber(e.correction_deg) +
                     " deg lies along directions the map gradient there does not constrain to 3 sigma "
                     "(least constrained: 1 sigma " +
                     FormatNumber(e.sd_weak_deg) + " deg)",
                 r);
  }
}

InsErrorPrior ParticleFilterInsPrior(const ParticleFilterOptions& options) {
  InsErrorPrior p;
  p.start_sd_deg = options.prior_half_width_deg / std::sqrt(3.0);
  p.drift_sd_deg = options.drift_sigma_deg;
  return p;
}

InsErrorPrior ResolvedInsPrior(Method method, const GeoGrid& grid, const MatchPath& path, const MatchOptions& options) {
  if (options.observability.prior.given()) return options.observability.prior;
  if (method == Method::kPf || method == Method::kAfpf) {  // the filters' own prior and motion model
    return ParticleFilterInsPrior(options.particle_filter);
  }
  InsErrorPrior p;
  p.start_sd_deg = PlausibleCorrectionDeg(method, grid, path, options) / 3.0;
  return p;
}

void ReviewObservability(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const InsErrorPrior& prior,
                         const ObservabilityOptions& options, MatchResult* r, std::vector<StepDiagnostics>* steps) {
  if (r->lat_deg.size() != path.size()) return;
  for (std::size_t p = 0; p < path.size(); ++p) {
    if (!std::isfinite(r->lat_deg[p]) || !std::isfinite(r->lon_deg[p])) return;
  }
  double sigma = MatchedResidualRms(grid, layer, path, r->lat_deg, r->lon_deg);
  if (!(sigma >= options.min_noise_sd_nT)) sigma = options.min_noise_sd_nT;
  const PathObservability o = ObservePath(grid, layer, path, r->lat_deg, r->lon_deg, prior, sigma);
  r->observability = o.Summary();
  if (!o.valid) return;
  r->observability_ratio = o.ratio_weak();
  // Partly observable: the map adds less than the prior along the least
  // observed direction at the end. Only then is the linear posterior imposed
  // as a floor: where the map observes both directions, its curvature within
  // the uncertainty can tell a nonlinear method more than the linearisation
  // (and rough crustal maps keep every covariance as the method gave it).
  const bool partly = o.ratio_weak() < options.min_information_ratio;
  if (!partly) return;
  int raised = 0;
  if (r->cov_lat_lat.size() == path.size()) {
    for (std::size_t p = 0; p < path.size(); ++p) {
      Cov2 c{r->cov_lat_lat[p], r->cov_lat_lon[p], r->cov_lon_lon[p]};
      if (FloorAlongLeastKnown(o.smoothed[p], &c)) {
        ++raised;
        r->cov_lat_lat[p] = c.lat_lat;
        r->cov_lat_lon[p] = c.lat_lon;
        r->cov_lon_lon[p] = c.lon_lon;
      }
    }
  }
  if (steps != nullptr && steps->size() == path.size()) {
    for (std::size_t p = 0; p < path.size(); ++p) {
      StepDiagnostics& d = (*steps)[p];
      Cov2 c{d.cov_lat_lat, d.cov_lat_lon, d.cov_lon_lon};
      if (FloorAlongLeastKnown(o.filtered[p], &c)) {
        ++raised;
        d.cov_lat_lat = c.lat_lat;
        d.cov_lat_lon = c.lat_lon;
        d.cov_lon_lon = c.lon_lon;
      }
    }
  }
  if (raised > 0) {
    r->observability += "; covariance raised to the map and prior's along the least known direction at " +
                        std::to_string(raised) + " of " + std::to_string(path.size()) + " points";
  }
  if (r->converged) {
    NotConverged("partly observable: along-iso-line error unconstrained (map information " +
                     Significant(o.ratio_weak()) + " of the prior's along the least observed direction at the path's "
                     "end, bearing " + FormatNumber(std::round(o.weak_bearing_deg() * 10.0) / 10.0) +
                     " deg, below " + FormatNumber(options.min_information_ratio) + ")",
                 r);
  }
}

void RequirePathNearMap(Method method, const GeoGrid& grid, const MatchPath& path, const MatchOptions& options) {
  path.Check();
  const double reach = std::max(SearchReachDeg(method, options), 0.0);
  const GridAxis& la = grid.lat();
  const GridAxis& lo = grid.lon();
  for (std::size_t p = 0; p < path.size(); ++p) {
    if (path.lat_deg[p] >= la.first_deg - reach && path.lat_deg[p] <= la.last_deg() + reach &&
        path.lon_deg[p] >= lo.first_deg - reach && path.lon_deg[p] <= lo.last_deg() + reach) {
      return;
    }
  }
  const auto [lat_lo, lat_hi] = std::minmax_element(path.lat_deg.begin(), path.lat_deg.end());
  const auto [lon_lo, lon_hi] = std::minmax_element(path.lon_deg.begin(), path.lon_deg.end());
  throw InputError(std::string(MethodName(method)) + ": the path is entirely off the map: none of its " +
                   std::to_string(path.size()) + " INS points lies within " + FormatNumber(reach) +
                   " deg of it (map lat " + FormatNumber(la.first_deg) + " .. " + FormatNumber(la.last_deg()) +
                   ", lon " + FormatNumber(lo.first_deg) + " .. " + FormatNumber(lo.last_deg()) + "; path lat " +
                   FormatNumber(*lat_lo) + " .. " + FormatNumber(*lat_hi) + ", lon " + FormatNumber(*lon_lo) + " .. " +
                   FormatNumber(*lon_hi) + ")");
}

MatchResult Match(Method method, const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                  const MatchOptions& options, std::vector<StepDiagnostics>* steps) {
  if (!(std::isfinite(options.max_correction_deg) && options.max_correction_deg >= 0.0)) {
    throw InputError(std::string(MethodName(method)) + ": max_correction_deg must be finite and >= 0 (0 = the method's own)");
  }
  if (std::string error; !options.observability.IsValid(&error)) throw InputError(std::string(MethodName(method)) + ": " + error);
  RequirePathNearMap(method, grid, path, options);
  MatchResult r;
  switch (method) {
    case Method::kPoint:
      r = MatchPoints(grid, layer, path, options.point);
      break;
    case Method::kIcp:
      r = MatchIcp(grid, layer, path, options.icp);
      break;
    case Method::kIccp:
      r = MatchIccp(grid, layer, path, options.iccp);
      break;
    case Method::kMma:
      r = MatchMma(grid, layer, path, options.mma);
      break;
    case Method::kMad:
      r = Correlate(CorrelationMetric::kMad, grid, layer, path, options.correlation);
      break;
    case Method::kMsd:
      r = Correlate(CorrelationMetric::kMsd, grid, layer, path, options.correlation);
      break;
    case Method::kProd:
      r = Correlate(CorrelationMetric::kProd, grid, layer, path, options.correlation);
      break;
    case Method::kNprod:
      r = Correlate(CorrelationMetric::kNprod, grid, layer, path, options.correlation);
      break;
    case Method::kFastMsd:
      r = MatchFastMsd(grid, layer, path, options.fast_msd);
      break;
    case Method::kPf:
      r = MatchParticleFilter(ParticleFilterKind::kPf, grid, layer, path, options.particle_filter, steps,
                              options.max_correction_deg);
      break;
    case Method::kAfpf:
      r = MatchParticleFilter(ParticleFilterKind::kAfpf, grid, layer, path, options.particle_filter, steps,
                              options.max_correction_deg);
      break;
  }
  ReviewResult(grid, layer, path, PlausibleCorrectionDeg(method, grid, path, options), &r);
  ReviewObservability(grid, layer, path, ResolvedInsPrior(method, grid, path, options), options.observability, &r, steps);
  return r;
}

}  // namespace magnav::mapmatch
