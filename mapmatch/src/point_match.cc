#include "magnav/mapmatch/point_match.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "magnav/core/error.h"
#include "magnav/core/option_check.h"
#include "match_common.h"

namespace magnav::mapmatch {

PointIndex::PointIndex(const GeoGrid& grid, std::vector<std::size_t> layers) : grid_(&grid), layers_(std::move(layers)) {
  if (layers_.empty()) throw InputError("point index: no layer");
  for (std::size_t l : layers_) {
    if (l >= grid.layer_names().size()) throw InputError("point index: layer " + std::to_string(l) + " not in the map");
  }
  const std::vector<double>& v = grid.values(layers_.front());
  sorted_.reserve(v.size());
  for (std::size_t n = 0; n < v.size(); ++n) sorted_.emplace_back(v[n], n);
  std::sort(sorted_.begin(), sorted_.end());
}

std::vector<PointHit> PointIndex::Find(const std::vector<double>& measured_nT, double tolerance_nT) const {
  if (measured_nT.size() != layers_.size()) {
    throw InputError("point index: " + std::to_string(measured_nT.size()) + " measurements for " +
                     std::to_string(layers_.size()) + " layers");
  }
  if (!(tolerance_nT >= 0.0) || !std::isfinite(tolerance_nT)) throw InputError("point index: tolerance must be >= 0");
  for (double m : measured_nT) {
    if (!std::isfinite(m)) throw InputError("point index: measurement is not finite");
  }
  const double lo = measured_nT[0] - tolerance_nT, hi = measured_nT[0] + tolerance_nT;
  auto first = std::lower_bound(sorted_.begin(), sorted_.end(), std::make_pair(lo, std::size_t{0}));
  std::vector<PointHit> hits;
  const int n_lon = grid_->lon().count;
  for (auto it = first; it != sorted_.end() && it->first <= hi; ++it) {
    const std::size_t node = it->second;
    double worst = std::abs(it->first - measured_nT[0]);
    bool ok = true;
    for (std::size_t l = 1; l < layers_.size() && ok; ++l) {
      const double d = std::abs(grid_->values(layers_[l])[node] - measured_nT[l]);
      ok = d <= tolerance_nT;
      worst = std::max(worst, d);
    }
    if (!ok) continue;
    PointHit h;
    h.i_lat = static_cast<int>(node / n_lon);
    h.j_lon = static_cast<int>(node % n_lon);
    h.lat_deg = grid_->lat().at(h.i_lat);
    h.lon_deg = grid_->lon().at(h.j_lon);
    h.max_abs_difference_nT = worst;
    hits.push_back(h);
  }
  std::sort(hits.begin(), hits.end(), [](const PointHit& a, const PointHit& b) {
    return a.i_lat != b.i_lat ? a.i_lat < b.i_lat : a.j_lon < b.j_lon;
  });
  return hits;
}

bool PointMatchOptions::IsValid(std::string* error) const {
  if (!(tolerance_nT >= 0.0) || !std::isfinite(tolerance_nT)) return Fail(error, "tolerance_nT must be finite and >= 0");
  return true;
}

MatchResult MatchPoints(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                        const PointMatchOptions& options) {
  internal::CheckInputs(grid, layer, path, options, "point");
  const PointIndex index(grid, {layer});
  MatchResult r = internal::StartResult("point", "mean distance moved, deg", path);
  r.iterations = 1;
  int no_hit = 0;
  double moved = 0.0;
  for (std::size_t p = 0; p < path.size(); ++p) {
    if (!std::isfinite(path.measured_nT[p])) {
      ++r.points_bad_measurement;
      continue;
    }
    const std::vector<PointHit> hits = index.Find({path.measured_nT[p]}, options.tolerance_nT);
    double best = std::numeric_limits<double>::infinity();
    for (const PointHit& h : hits) {
      const double d = std::hypot(h.lat_deg - path.lat_deg[p], h.lon_deg - path.lon_deg[p]);
      if (d < best) {
        best = d;
        r.lat_deg[p] = h.lat_deg;
        r.lon_deg[p] = h.lon_deg;
      }
    }
    if (hits.empty()) {
      ++no_hit;
      continue;
    }
    ++r.points_used;
    moved += best;
  }
  internal::CountOffMap(grid, &r);  // INS positions kept off the map
  r.score = r.points_used > 0 ? moved / r.points_used : std::numeric_limits<double>::quiet_NaN();
  r.converged = r.points_used > 0;
  if (!r.converged) r.reason = "no point has a map node within the tolerance";
  else if (no_hit > 0) r.reason = std::to_string(no_hit) + " points without a node within the tolerance kept their INS position";
  return r;
}

}  // namespace magnav::mapmatch
