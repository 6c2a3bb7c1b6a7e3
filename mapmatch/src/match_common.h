// Internal: the door every matcher goes through (inputs, options) and the
// bookkeeping of its result (used / off-map / bad-measurement counts).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "magnav/core/error.h"
#include "magnav/core/option_check.h"
#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"

namespace magnav::mapmatch::internal {

template <typename Options>
void CheckInputs(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const Options& options,
                 const std::string& method) {
  path.Check();
  if (layer >= grid.layer_names().size()) throw InputError(method + ": layer index not in the map");
  std::string why;
  if (!options.IsValid(&why)) throw InputError(method + " options: " + why);
}

// The result with the INS path as its matched path (what is returned when
// the method cannot run) and the method's score name.
inline MatchResult StartResult(const std::string& method, const std::string& score_name, const MatchPath& path) {
  MatchResult r;
  r.method = method;
  r.score_name = score_name;
  r.lat_deg = path.lat_deg;
  r.lon_deg = path.lon_deg;
  return r;
}

// Indices of the points with a finite measurement; counts the others.
inline std::vector<std::size_t> FiniteMeasurements(const MatchPath& path, MatchResult* r) {
  std::vector<std::size_t> used;
  for (std::size_t p = 0; p < path.size(); ++p) {
    if (std::isfinite(path.measured_nT[p])) {
      used.push_back(p);
    } else {
      ++r->points_bad_measurement;
    }
  }
  r->points_used = static_cast<int>(used.size());
  return used;
}

// False (with the reason set, path left as the INS gave it) below `needed` points.
inline bool EnoughPoints(const std::vector<std::size_t>& used, std::size_t needed, MatchResult* r) {
  if (used.size() >= needed) return true;
  r->points_used = 0;
  r->reason = "only " + std::to_string(used.size()) + " usable points (needs " + std::to_string(needed) +
              "): path left as the INS gave it";
  return false;
}

// The options' "fraction of the points on the map" check.
inline bool ValidOnMapFraction(double fraction, std::string* error) {
  if (fraction > 0.0 && fraction <= 1.0) return true;
  return Fail(error, "min_on_map_fraction must be in (0, 1]");
}

// Robust residuals (the matchers' outlier rules; k = the options'
// outlier_sigmas, 5 by default, 0 = off):
// 1. the map's range: a reading beyond the layer's values by more than a
//    quarter of their range (crustal reference map: below −314 or above
//    404 nT) is explained by no position on the map: left out, counted as an
//    outlier (OutsideMapRange);
// 2. the readings' spread: σ_l = 1.4826·MAD of the path's readings (the
//    normal-consistent median absolute deviation, at least 1 nT), the scale
//    of the residual any wrong position gives; a field residual beyond k·σ_l
//    is not a position error: correlation clips it at k·σ_l (a truncated
//    loss, constant beyond), fast MSD drops its data term (IsOutlier);
// 3. a method's own residuals at its answer (correlation: field residuals,
//    ICP family: closest distances): beyond k robust sigmas of their median,
//    left out and the fit repeated.
// A Gaussian residual is beyond 5σ once in 1.7 million: on clean data the
// rules drop almost nothing; one +1000 nT spike is beyond all three.
inline constexpr double kDefaultOutlierSigmas = 5.0;
// σ floor for field residuals: below 1 nT the bilinear map alone differs
// from the field (0.06 nT rms, 0.27 nT max on the crustal reference path) and
// a noise-free path would have every tiny misfit called an outlier.
inline constexpr double kOutlierSigmaFloor_nT = 1.0;
// Rule 1's margin, as a fraction of the layer's range of values.
inline constexpr double kMapRangeMargin = 0.25;

struct RobustSpread {
  double median = 0.0;
  double sigma = 0.0;
};

inline RobustSpread RobustSpreadOf(std::vector<double> v, double floor) {
  if (v.empty()) return {0.0, floor};
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  const double median = *mid;
  for (double& x : v) x = std::abs(x - median);
  std::nth_element(v.begin(), mid, v.end());
  return {median, std::max(1.4826 * *mid, floor)};
}

// Whether residual r is an outlier of `spread` at k sigmas (never when k = 0).
inline bool IsOutlier(double r, const RobustSpread& spread, double k) {
  return k > 0.0 && std::abs(r - spread.median) > k * spread.sigma;
}

inline bool ValidOutlierSigmas(double k, std::string* error) {
  if (k == 0.0 || (std::isfinite(k) && k >= 2.0)) return true;
  return Fail(error, "outlier_sigmas must be 0 (off) or finite and >= 2");
}

// Rule 1: a value no position on the map explains.
inline bool OutsideMapRange(const GeoGrid& grid, std::size_t layer, double value_nT) {
  const double lo = grid.min_value(layer), hi = grid.max_value(layer), margin = kMapRangeMargin * (hi - lo);
  return value_nT < lo - margin || value_nT > hi + margin;
}

// Rule 1 on the usable points (when k > 0): returns those within the map's
// range; the others are counted as outliers (and taken out of points_used).
inline std::vector<std::size_t> WithinMapRange(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                                               const std::vector<std::size_t>& used, double k, MatchResult* r) {
  if (!(k > 0.0)) return used;
  std::vector<std::size_t> kept;
  for (std::size_t p : used) {
    if (OutsideMapRange(grid, layer, path.measured_nT[p])) {
      ++r->points_outlier;
    } else {
      kept.push_back(p);
    }
  }
  r->points_used = static_cast<int>(kept.size());
  return kept;
}

// Rule 2's scale: the robust spread of the readings of `used`.
inline RobustSpread ReadingSpread(const MatchPath& path, const std::vector<std::size_t>& used) {
  std::vector<double> v;
  v.reserve(used.size());
  for (std::size_t p : used) v.push_back(path.measured_nT[p]);
  return RobustSpreadOf(v, kOutlierSigmaFloor_nT);
}

// Counts matched points that lie outside the map.
inline void CountOffMap(const GeoGrid& grid, MatchResult* r) {
  for (std::size_t p = 0; p < r->lat_deg.size(); ++p) {
    if (!grid.Contains(r->lat_deg[p], r->lon_deg[p])) ++r->points_off_map;
  }
}

}  // namespace magnav::mapmatch::internal
