// Internal: the door every matcher goes through (inputs, options) and the
// bookkeeping of its result (used / off-map / bad-measurement counts).
#pragma once

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

// Counts matched points that lie outside the map.
inline void CountOffMap(const GeoGrid& grid, MatchResult* r) {
  for (std::size_t p = 0; p < r->lat_deg.size(); ++p) {
    if (!grid.Contains(r->lat_deg[p], r->lon_deg[p])) ++r->points_off_map;
  }
}

}  // namespace magnav::mapmatch::internal
