// Single-point matching (METHODS.md §4): every map node whose value(s) lie
// within a tolerance of a measurement, found through a sorted value index
// (O(log N + hits)), not a scan of the grid. The answer can be ambiguous: all
// hits are returned.
//
// Units: values and tolerance in nT; positions in degrees (WGS84).
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"

namespace magnav::mapmatch {

struct PointHit {
  int i_lat = 0, j_lon = 0;  // node indices
  double lat_deg = 0.0, lon_deg = 0.0;
  double max_abs_difference_nT = 0.0;  // largest |map − measurement| over the layers
};

// Index of one or more layers of a grid (the grid must outlive it). The
// first layer is sorted; the other layers filter its candidates.
class PointIndex {
 public:
  PointIndex(const GeoGrid& grid, std::vector<std::size_t> layers);

  // Every node with |value_l − measured[l]| ≤ tolerance_nT for every layer
  // l, in node order. Throws InputError if the counts differ, a measurement
  // is not finite or the tolerance is negative.
  std::vector<PointHit> Find(const std::vector<double>& measured_nT, double tolerance_nT) const;

 private:
  const GeoGrid* grid_;
  std::vector<std::size_t> layers_;
  std::vector<std::pair<double, std::size_t>> sorted_;  // (first layer value, node)
};

struct PointMatchOptions {
  // Half-width of the value window, nT (the thesis' sensor noise bound, < 5 nT).
  double tolerance_nT = 5.0;

  bool IsValid(std::string* error) const;
};

// Path matching from single points: each point goes to the hit nearest (in
// degrees) to its INS position; a point without a hit (or with a bad
// measurement) keeps its INS position and is counted (not in points_used; the
// number without a hit is in the reason). Score: mean distance moved, deg.
// Never iterates (iterations = 1).
MatchResult MatchPoints(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                        const PointMatchOptions& options = {});

}  // namespace magnav::mapmatch
