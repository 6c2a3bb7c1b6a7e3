#include "magnav/mapmatch/correlation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "magnav/core/csv.h"
#include "magnav/core/option_check.h"
#include "match_common.h"

namespace magnav::mapmatch {
namespace {

// A usable point: its base cell and bilinear weights, which every whole-step shift keeps.
struct CellPoint {
  int i, j;
  double w00, w01, w10, w11;
  double measured_nT;
};

}  // namespace

const char* CorrelationMetricName(CorrelationMetric metric) {
  switch (metric) {
    case CorrelationMetric::kMad:
      return "mad";
    case CorrelationMetric::kMsd:
      return "msd";
    case CorrelationMetric::kProd:
      return "prod";
    case CorrelationMetric::kNprod:
      return "nprod";
  }
  return "?";
}

bool CorrelationOptions::IsValid(std::string* error) const {
  if (!PositiveFinite(search_window_deg)) {
    return Fail(error, "search_window_deg must be finite and > 0 (it must cover the INS error; no default)");
  }
  if (!(min_on_map_fraction > 0.0 && min_on_map_fraction <= 1.0)) {
    return Fail(error, "min_on_map_fraction must be in (0, 1]");
  }
  return true;
}

MatchResult MatchCorrelation(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                             const CorrelationOptions& options) {
  internal::CheckInputs(grid, layer, path, options, CorrelationMetricName(options.metric));
  const std::string unit = options.metric == CorrelationMetric::kMad     ? "nT"
                           : options.metric == CorrelationMetric::kNprod ? "1"
                                                                         : "nT^2";
  MatchResult r = internal::StartResult(CorrelationMetricName(options.metric),
                                        std::string(CorrelationMetricName(options.metric)) + ", " + unit, path);
  const std::vector<std::size_t> used = internal::FiniteMeasurements(path, &r);
  if (!internal::EnoughPoints(used, 1, &r)) return r;
  const GridAxis& la = grid.lat();
  const GridAxis& lo = grid.lon();
  std::vector<CellPoint> pts;
  pts.reserve(used.size());
  for (std::size_t p : used) {
    const double fi = (path.lat_deg[p] - la.first_deg) / la.step_deg;
    const double fj = (path.lon_deg[p] - lo.first_deg) / lo.step_deg;
    const double bi = std::floor(fi), bj = std::floor(fj);
    const double u = fi - bi, v = fj - bj;
    pts.push_back({static_cast<int>(bi), static_cast<int>(bj), (1 - u) * (1 - v), (1 - u) * v, u * (1 - v), u * v,
                   path.measured_nT[p]});
  }
  const int A = static_cast<int>(std::floor(options.search_window_deg / la.step_deg + 1e-9));
  const int B = static_cast<int>(std::floor(options.search_window_deg / lo.step_deg + 1e-9));
  const double* val = grid.values(layer).data();
  const int n_lon = lo.count;
  const std::size_t needed =
      static_cast<std::size_t>(std::ceil(options.min_on_map_fraction * static_cast<double>(pts.size()) - 1e-9));
  const bool maximise = options.metric == CorrelationMetric::kProd || options.metric == CorrelationMetric::kNprod;
  double best = maximise ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
  int best_a = 0, best_b = 0;
  std::size_t best_on = 0;
  bool found = false;
  for (int a = -A; a <= A; ++a) {
    for (int b = -B; b <= B; ++b) {
      std::size_t n_on = 0;
      double s_abs = 0.0, s_sq = 0.0, s_lm = 0.0, s_mm = 0.0, s_ll = 0.0;
      for (const CellPoint& q : pts) {
        const int i = q.i + a, j = q.j + b;
        if (i < 0 || j < 0 || i > la.count - 2 || j > lo.count - 2) continue;
        const double* c = val + static_cast<std::size_t>(i) * n_lon + j;
        const double m = q.w00 * c[0] + q.w01 * c[1] + q.w10 * c[n_lon] + q.w11 * c[n_lon + 1];
        const double d = q.measured_nT - m;
        ++n_on;
        s_abs += std::abs(d);
        s_sq += d * d;
        s_lm += q.measured_nT * m;
        s_mm += m * m;
        s_ll += q.measured_nT * q.measured_nT;
      }
      if (n_on < needed || n_on == 0) continue;
      const double n = static_cast<double>(n_on);
      double score = 0.0;
      switch (options.metric) {
        case CorrelationMetric::kMad:
          score = s_abs / n;
          break;
        case CorrelationMetric::kMsd:
          score = s_sq / n;
          break;
        case CorrelationMetric::kProd:
          score = s_lm / n;
          break;
        case CorrelationMetric::kNprod:
          score = s_lm / (std::sqrt(s_ll) * std::sqrt(s_mm));
          break;
      }
      // Ties go to the smaller shift (the scan order would otherwise favour a corner).
      const bool better = maximise ? score > best : score < best;
      const bool tie = score == best && a * a + b * b < best_a * best_a + best_b * best_b;
      if (better || tie) {
        best = score;
        best_a = a;
        best_b = b;
        best_on = n_on;
        found = true;
      }
    }
  }
  r.iterations = (2 * A + 1) * (2 * B + 1);
  if (!found) {
    r.points_used = 0;
    r.reason = "no shift within the window has " + FormatNumber(options.min_on_map_fraction) +
               " of the points on the map: path left as the INS gave it";
    return r;
  }
  r.score = best;
  r.points_used = static_cast<int>(best_on);
  r.points_off_map = static_cast<int>(pts.size() - best_on);
  for (std::size_t p = 0; p < path.size(); ++p) {
    r.lat_deg[p] = path.lat_deg[p] + best_a * la.step_deg;
    r.lon_deg[p] = path.lon_deg[p] + best_b * lo.step_deg;
  }
  r.notes = "shift " + FormatNumber(best_a * la.step_deg) + ", " + FormatNumber(best_b * lo.step_deg) +
            " deg (lat, lon) in a window of +-" + FormatNumber(options.search_window_deg) + " deg";
  if (A == 0 || B == 0) {
    r.reason = "the window is narrower than one grid step in lat or lon: that axis was not searched";
  } else if (std::abs(best_a) == A || std::abs(best_b) == B) {
    r.reason = "best shift on the edge of the search window (the window may be too small)";
  } else {
    r.converged = true;
  }
  return r;
}

}  // namespace magnav::mapmatch
