// Shared by the particle-filter status tests: the crustal reference map and a
// map path with its truth columns (true_lat, true_lon; deg).
#pragma once

#include <string>
#include <vector>

#include "magnav/core/csv.h"
#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"
#include "test_data.h"

namespace magnav::mapmatch::testing_paths {

// tests/data/reference/map_crustal_anomaly.csv, read once.
inline const GeoGrid& CrustalMap() {
  static const GeoGrid g = ReadGeoGridCsv(magnav::testing::ReferencePath("map_crustal_anomaly.csv"), {"anomaly_nT"});
  return g;
}

struct PathRun {
  MatchPath path;
  std::vector<double> true_lat, true_lon;
};

// The path file at `file` (measured column meas_nT) and its truth.
inline PathRun LoadPathRun(const std::string& file) {
  PathRun r;
  r.path = ReadMatchPath(file, "meas_nT");
  const CsvTable t = CsvTable::Read(file);
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    r.true_lat.push_back(t.number(i, t.column("true_lat")));
    r.true_lon.push_back(t.number(i, t.column("true_lon")));
  }
  return r;
}

}  // namespace magnav::mapmatch::testing_paths
