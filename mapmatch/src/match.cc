#include "magnav/mapmatch/match.h"

#include <algorithm>
#include <array>
#include <cmath>
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

void NotConverged(const std::string& why, MatchResult* r) {
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
      r = MatchParticleFilter(ParticleFilterKind::kPf, grid, layer, path, options.particle_filter, steps);
      break;
    case Method::kAfpf:
      r = MatchParticleFilter(ParticleFilterKind::kAfpf, grid, layer, path, options.particle_filter, steps);
      break;
  }
  ReviewResult(grid, layer, path, PlausibleCorrectionDeg(method, grid, path, options), &r);
  return r;
}

}  // namespace magnav::mapmatch
