// Shared by the particle-filter status tests: the crustal reference map and a
// map path with its truth columns (true_lat, true_lon; deg).
#pragma once

#include <chrono>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/mapmatch/fix_schedule.h"
#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::mapmatch::testing_paths {

// One 2 m step of the dense test paths (pf_drift_step_test, pf_offset_slide_test):
// the heading walks 0.02 rad per step, the vehicle moves 2 m along it (lat, lon
// deg), and the INS error (dlat, dlon deg) walks `drift` deg per step. Draws
// three normals from `rng` in that order.
inline void DenseWalkStep(std::mt19937_64& rng, std::normal_distribution<double>& unit, double drift, double* lat,
                          double* lon, double* heading, double* dlat, double* dlon) {
  *heading += 0.02 * unit(rng);
  *lat += 2.0 * std::cos(*heading) / MetresPerDegreeLat(*lat);
  *lon += 2.0 * std::sin(*heading) / MetresPerDegreeLon(*lat);
  *dlat += drift * unit(rng);
  *dlon += drift * unit(rng);
}

// tests/data/reference/map_crustal_anomaly.csv, read once.
inline const GeoGrid& CrustalMap() {
  static const GeoGrid g = ReadGeoGridCsv(magnav::testing::ReferencePath("map_crustal_anomaly.csv"), {"anomaly_nT"});
  return g;
}

struct PathRun {
  MatchPath path;
  std::vector<double> true_lat, true_lon;
};

// A path read every 2 m (pf_offset_slide_test, the matcher's parity test), generated like
// scripts/dense_mappaths: start near the map's centre, random heading, INS = truth + 0.01° in a
// random direction + a random walk of 0.0003° · √(2 m / 100 m) per axis and step, 3 nT noise; at
// most `steps` points, ending before the path would leave the map.
inline PathRun DensePath(std::uint64_t seed, int steps) {
  const GeoGrid& g = CrustalMap();
  const std::size_t layer = g.layer("anomaly_nT");
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  PathRun r;
  double lat = 45.0 + 0.06 * (u(rng) - 0.5), lon = 10.0 + 0.08 * (u(rng) - 0.5), heading = 2.0 * M_PI * u(rng);
  const double off = 2.0 * M_PI * u(rng), drift = 0.0003 * std::sqrt(2.0 / 100.0);
  double dlat = 0.01 * std::cos(off), dlon = 0.01 * std::sin(off);
  for (int k = 0; k < steps; ++k) {
    if (k > 0) testing_paths::DenseWalkStep(rng, unit, drift, &lat, &lon, &heading, &dlat, &dlon);
    const auto v = g.Sample(layer, lat, lon);
    if (!v) break;
    r.path.k.push_back(k);
    r.path.lat_deg.push_back(lat + dlat);
    r.path.lon_deg.push_back(lon + dlon);
    r.path.measured_nT.push_back(v->value_nT + 3.0 * unit(rng));
    r.true_lat.push_back(lat);
    r.true_lon.push_back(lon);
  }
  return r;
}

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

// Generated path `number` (scripts/heldout_mappaths: seed = path number, `offset_deg` INS offset, 0.01° unless
// given) at `noise` nT, written to the test's temporary directory (file tag `tag`) and read back.
inline PathRun GeneratedPathRun(int number, const std::string& noise, const std::string& tag,
                                const std::string& offset_deg = "0.01") {
  const std::string dir = ::testing::TempDir();
  const auto [code, out] = magnav::testing::RunCommand(
      {magnav::testing::TestDataDir() + "/../../scripts/heldout_mappaths", dir, "1", offset_deg, noise, std::to_string(number)},
      {}, std::chrono::seconds(60));
  EXPECT_EQ(code, 0) << out;
  return LoadPathRun(dir + "/heldout_" + std::to_string(number) + "_noise" + tag + ".csv");
}

}  // namespace magnav::mapmatch::testing_paths
