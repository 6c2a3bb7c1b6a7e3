#include "magnav/mapmatch/correlation.h"

#include <algorithm>
#include <array>
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

bool Maximised(CorrelationMetric metric) {
  return metric == CorrelationMetric::kProd || metric == CorrelationMetric::kNprod;
}

// The best whole-cell shift so far (over every rotation tried).
struct Best {
  double score = 0.0;
  int a = 0, b = 0;  // shift in lat, lon steps
  std::size_t on = 0;
  bool found = false;
};

// Scores every shift (a, b) in [-A, A] x [-B, B] of the points; updates *best
// with a strictly better score (ties keep the earlier: the smaller rotation,
// then the smaller shift). Returns whether it did.
// `clip` (nT; infinity = none): MAD and MSD count a residual beyond it as
// `clip` (a truncated loss: one spike weighs the same at every shift).
// `off_map_as_clip`: MAD and MSD count every point off the map at a shift as
// a residual of `clip` and average over all the points.
// `surface` (optional): every shift's score, row-major (a, then b), NaN where not scored.
bool SearchShifts(const GeoGrid& grid, std::size_t layer, const std::vector<CellPoint>& pts, int A, int B,
                  std::size_t needed, CorrelationMetric metric, double clip, bool off_map_as_clip, Best* best,
                  std::vector<double>* surface = nullptr) {
  if (surface) surface->assign(static_cast<std::size_t>(2 * A + 1) * (2 * B + 1), std::nan(""));
  const GridAxis& la = grid.lat();
  const GridAxis& lo = grid.lon();
  const double* val = grid.values(layer).data();
  const int n_lon = lo.count;
  const bool maximise = Maximised(metric);
  bool improved = false;
  bool seen_here = false;
  Best here;
  for (int a = -A; a <= A; ++a) {
    for (int b = -B; b <= B; ++b) {
      std::size_t n_on = 0;
      double s_abs = 0.0, s_sq = 0.0, s_lm = 0.0, s_mm = 0.0, s_ll = 0.0;
      for (const CellPoint& q : pts) {
        const int i = q.i + a, j = q.j + b;
        if (i < 0 || j < 0 || i > la.count - 2 || j > lo.count - 2) continue;
        const double* c = val + static_cast<std::size_t>(i) * n_lon + j;
        const double m = q.w00 * c[0] + q.w01 * c[1] + q.w10 * c[n_lon] + q.w11 * c[n_lon + 1];
        const double d = std::min(std::abs(q.measured_nT - m), clip);
        ++n_on;
        s_abs += d;
        s_sq += d * d;
        s_lm += q.measured_nT * m;
        s_mm += m * m;
        s_ll += q.measured_nT * q.measured_nT;
      }
      if (n_on < needed || n_on == 0) continue;
      double n = static_cast<double>(n_on);
      if (off_map_as_clip) {
        const double n_off = static_cast<double>(pts.size() - n_on);
        s_abs += n_off * clip;
        s_sq += n_off * clip * clip;
        n = static_cast<double>(pts.size());
      }
      double score = 0.0;
      switch (metric) {
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
      if (surface) (*surface)[static_cast<std::size_t>(a + A) * (2 * B + 1) + (b + B)] = score;
      // Within one rotation, ties go to the smaller shift (the scan order would
      // otherwise favour a corner).
      const bool better_here = !seen_here || (maximise ? score > here.score : score < here.score) ||
                               (score == here.score && a * a + b * b < here.a * here.a + here.b * here.b);
      if (better_here) {
        here = Best{score, a, b, n_on, true};
        seen_here = true;
      }
    }
  }
  if (seen_here && (!best->found || (maximise ? here.score > best->score : here.score < best->score))) {
    *best = here;
    improved = true;
  }
  return improved;
}

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
  if (!internal::ValidOnMapFraction(min_on_map_fraction, error)) return false;
  if (!internal::ValidOutlierSigmas(outlier_sigmas, error)) return false;
  if (!(std::isfinite(rotation_window_deg) && rotation_window_deg >= 0.0 && rotation_window_deg <= 180.0)) {
    return Fail(error, "rotation_window_deg must be in [0, 180] (0 = no rotation search)");
  }
  if (!PositiveFinite(rotation_step_deg)) return Fail(error, "rotation_step_deg must be finite and > 0");
  return true;
}

MatchResult MatchCorrelation(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                             const CorrelationOptions& options, CorrelationPeaks* peaks) {
  internal::CheckInputs(grid, layer, path, options, CorrelationMetricName(options.metric));
  const std::string unit = options.metric == CorrelationMetric::kMad     ? "nT"
                           : options.metric == CorrelationMetric::kNprod ? "1"
                                                                         : "nT^2";
  MatchResult r = internal::StartResult(CorrelationMetricName(options.metric),
                                        std::string(CorrelationMetricName(options.metric)) + ", " + unit, path);
  // Robust residuals (match_common.h rules 1-3): readings the map cannot
  // explain are left out; residuals are clipped at k·σ_l in the search;
  // points beyond k robust sigmas at the answer are left out and the search repeated.
  const std::vector<std::size_t> finite = internal::FiniteMeasurements(path, &r);
  const std::vector<std::size_t> used = internal::WithinMapRange(grid, layer, path, finite, options.outlier_sigmas, &r);
  if (!internal::EnoughPoints(used, 1, &r)) return r;
  const internal::RobustSpread readings = internal::ReadingSpread(path, used);
  const double clip = options.outlier_sigmas > 0.0 ? options.outlier_sigmas * readings.sigma
                                                   : std::numeric_limits<double>::infinity();
  const bool off_map_as_clip = options.off_map_as_unexplained && std::isfinite(clip) &&
                               (options.metric == CorrelationMetric::kMad || options.metric == CorrelationMetric::kMsd);
  const GridAxis& la = grid.lat();
  const GridAxis& lo = grid.lon();
  const int A = static_cast<int>(std::floor(options.search_window_deg / la.step_deg + 1e-9));
  const int B = static_cast<int>(std::floor(options.search_window_deg / lo.step_deg + 1e-9));
  const int n_rot = options.rotation_window_deg > 0.0
                        ? static_cast<int>(std::floor(options.rotation_window_deg / options.rotation_step_deg + 1e-9))
                        : 0;
  // Rotations about the centroid of the usable INS points (deg plane).
  double c_lat = 0.0, c_lon = 0.0;
  for (std::size_t p : used) {
    c_lat += path.lat_deg[p] / static_cast<double>(used.size());
    c_lon += path.lon_deg[p] / static_cast<double>(used.size());
  }
  const auto rotated = [&](std::size_t p, double theta_rad) {
    const double a = path.lat_deg[p] - c_lat, b = path.lon_deg[p] - c_lon;
    return std::array<double, 2>{c_lat + std::cos(theta_rad) * a - std::sin(theta_rad) * b,
                                 c_lon + std::sin(theta_rad) * a + std::cos(theta_rad) * b};
  };
  // One search over the points `idx` (indices into the path): the best shift and rotation.
  struct Search {
    Best best;
    int rot = 0;
    std::vector<double> surface;  // with `peaks` and no rotation search
  };
  const auto cell_point = [&](std::size_t p, double theta) {
    const auto x = rotated(p, theta);
    const double fi = (x[0] - la.first_deg) / la.step_deg, fj = (x[1] - lo.first_deg) / lo.step_deg;
    const double bi = std::floor(fi), bj = std::floor(fj);
    const double u = fi - bi, v = fj - bj;
    // PROD and NPROD weigh each reading by its value: a reading is held within the clip of the readings' median.
    const double l = Maximised(options.metric)
                         ? std::clamp(path.measured_nT[p], readings.median - clip, readings.median + clip)
                         : path.measured_nT[p];
    return CellPoint{static_cast<int>(bi), static_cast<int>(bj), (1 - u) * (1 - v), (1 - u) * v, u * (1 - v), u * v, l};
  };
  const auto search = [&](const std::vector<std::size_t>& idx) {
    const std::size_t needed =
        static_cast<std::size_t>(std::ceil(options.min_on_map_fraction * static_cast<double>(idx.size()) - 1e-9));
    Search out;
    out.best.score = Maximised(options.metric) ? -std::numeric_limits<double>::infinity()
                                               : std::numeric_limits<double>::infinity();
    std::vector<CellPoint> pts(idx.size());
    for (int k = 0; k <= 2 * n_rot; ++k) {
      const int rot = k % 2 == 0 ? k / 2 : -(k + 1) / 2;  // 0, -1, 1, -2, 2, ...: ties keep the smaller angle
      const double theta = rot * options.rotation_step_deg * M_PI / 180.0;
      for (std::size_t c = 0; c < idx.size(); ++c) pts[c] = cell_point(idx[c], theta);
      if (SearchShifts(grid, layer, pts, A, B, needed, options.metric, clip, off_map_as_clip, &out.best,
                       peaks && n_rot == 0 ? &out.surface : nullptr)) {
        out.rot = rot;
      }
    }
    return out;
  };
  // Robust residuals (match_common.h): search, judge every usable point's
  // residual at the best shift, search again without the outliers, until the
  // set of outliers repeats (at most kPasses searches).
  constexpr int kPasses = 3;
  std::vector<std::size_t> inliers = used;
  std::vector<char> outlier(path.size(), 0);
  Search found = search(inliers);
  for (int pass = 1; pass < kPasses && found.best.found && options.outlier_sigmas > 0.0; ++pass) {
    const double theta = found.rot * options.rotation_step_deg * M_PI / 180.0;
    std::vector<std::pair<std::size_t, double>> resid;  // (point, measured − map) at the best shift, on the map
    for (std::size_t p : used) {
      const CellPoint q = cell_point(p, theta);
      const int i = q.i + found.best.a, j = q.j + found.best.b;
      if (i < 0 || j < 0 || i > la.count - 2 || j > lo.count - 2) continue;
      const double* c = grid.values(layer).data() + static_cast<std::size_t>(i) * lo.count + j;
      resid.emplace_back(p, q.measured_nT - (q.w00 * c[0] + q.w01 * c[1] + q.w10 * c[lo.count] + q.w11 * c[lo.count + 1]));
    }
    std::vector<double> values;
    for (const auto& pr : resid) values.push_back(pr.second);
    const internal::RobustSpread spread = internal::RobustSpreadOf(values, internal::kOutlierSigmaFloor_nT);
    std::vector<char> next(path.size(), 0);
    for (const auto& [p, d] : resid) next[p] = internal::IsOutlier(d, spread, options.outlier_sigmas);
    if (next == outlier) break;
    outlier = next;
    inliers.clear();
    for (std::size_t p : used) {
      if (!outlier[p]) inliers.push_back(p);
    }
    found = search(inliers);
  }
  const Best& best = found.best;
  const int best_rot = found.rot;
  r.points_outlier += static_cast<int>(used.size() - inliers.size());
  r.iterations = (2 * A + 1) * (2 * B + 1) * (2 * n_rot + 1);
  if (!best.found) {
    r.points_used = 0;
    r.reason = "no shift within the window has " + FormatNumber(options.min_on_map_fraction) +
               " of the points on the map: path left as the INS gave it";
    return r;
  }
  if (peaks && n_rot == 0) {
    // Local optima of the final surface, best first, greedily kept when far enough from every better one.
    const bool maximise = Maximised(options.metric);
    const auto at = [&](int a, int b) { return found.surface[static_cast<std::size_t>(a + A) * (2 * B + 1) + (b + B)]; };
    std::vector<CorrelationPeak> local;
    for (int a = -A; a <= A; ++a) {
      for (int b = -B; b <= B; ++b) {
        const double s = at(a, b);
        if (std::isnan(s)) continue;
        bool optimum = true;
        for (int da = -1; da <= 1 && optimum; ++da) {
          for (int db = -1; db <= 1 && optimum; ++db) {
            if ((da == 0 && db == 0) || std::abs(a + da) > A || std::abs(b + db) > B) continue;
            const double t = at(a + da, b + db);
            if (!std::isnan(t) && (maximise ? t > s : t < s)) optimum = false;
          }
        }
        if (optimum) local.push_back({a * la.step_deg, b * lo.step_deg, s});
      }
    }
    std::stable_sort(local.begin(), local.end(), [&](const CorrelationPeak& x, const CorrelationPeak& y) {
      return maximise ? x.score > y.score : x.score < y.score;
    });
    peaks->found.clear();
    for (const CorrelationPeak& c : local) {
      if (peaks->found.size() >= peaks->max_peaks) break;
      bool far = true;
      for (const CorrelationPeak& f : peaks->found) {
        far = far && std::max(std::abs(c.shift_lat_deg - f.shift_lat_deg), std::abs(c.shift_lon_deg - f.shift_lon_deg)) >=
                         peaks->min_separation_deg;
      }
      if (far) peaks->found.push_back(c);
    }
  }
  r.score = best.score;
  r.points_used = static_cast<int>(best.on);
  r.points_off_map = static_cast<int>(inliers.size() - best.on);
  const double theta = best_rot * options.rotation_step_deg * M_PI / 180.0;
  for (std::size_t p = 0; p < path.size(); ++p) {
    const auto x = rotated(p, theta);
    r.lat_deg[p] = x[0] + best.a * la.step_deg;
    r.lon_deg[p] = x[1] + best.b * lo.step_deg;
  }
  r.notes = "shift " + FormatNumber(best.a * la.step_deg) + ", " + FormatNumber(best.b * lo.step_deg) +
            " deg (lat, lon) in a window of +-" + FormatNumber(options.search_window_deg) + " deg";
  if (n_rot > 0) r.notes += ", rotation " + FormatNumber(best_rot * options.rotation_step_deg) + " deg";
  if (A == 0 || B == 0) {
    r.reason = "the window is narrower than one grid step in lat or lon: that axis was not searched";
  } else if (std::abs(best.a) == A || std::abs(best.b) == B || (n_rot > 0 && std::abs(best_rot) == n_rot)) {
    r.reason = "best shift or rotation on the edge of the search window (the window may be too small)";
  } else {
    r.converged = true;
  }
  return r;
}

}  // namespace magnav::mapmatch
