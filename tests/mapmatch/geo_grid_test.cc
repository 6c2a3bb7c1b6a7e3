// GeoGrid: bilinear value and gradient (against an exactly bilinear function
// and finite differences), the outside result, the CSV and NGDC readers (any
// row order) and their errors for irregular grids, holes, NaN and missing
// columns; the point index against a brute-force scan.
#include <cmath>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/point_match.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

GridAxis Axis(double first, double step, int count) { return GridAxis{first, step, count}; }

// Smooth, non-bilinear test field (nT).
double Smooth(double lat, double lon) { return 40000.0 + 300.0 * std::sin(0.7 * lat) * std::cos(1.3 * lon) + 20.0 * lat * lon; }

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
}

std::string ExpectInputError(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

TEST(GeoGrid, BilinearIsExactOnABilinearFunction) {
  const auto f = [](double lat, double lon) { return 3.0 + 2.0 * lat - 5.0 * lon + 0.75 * lat * lon; };
  const GeoGrid g = GeoGrid::FromFunction(Axis(10.0, 0.5, 5), Axis(60.0, 0.25, 7), "v", f);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ulat(10.0, 12.0), ulon(60.0, 61.5);
  for (int k = 0; k < 200; ++k) {
    const double lat = ulat(rng), lon = ulon(rng);
    const auto s = g.Sample(0, lat, lon);
    ASSERT_TRUE(s.has_value());
    EXPECT_NEAR(s->value_nT, f(lat, lon), 1e-9);
    EXPECT_NEAR(s->dvalue_dlat_nT_per_deg, 2.0 + 0.75 * lon, 1e-9);
    EXPECT_NEAR(s->dvalue_dlon_nT_per_deg, -5.0 + 0.75 * lat, 1e-9);
  }
}

TEST(GeoGrid, GradientMatchesFiniteDifferencesInsideACell) {
  const GeoGrid g = GeoGrid::FromFunction(Axis(-1.0, 0.1, 21), Axis(2.0, 0.2, 11), "v", Smooth);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> frac(0.05, 0.95);
  std::uniform_int_distribution<int> ci(0, 19), cj(0, 9);
  const double h = 1e-6;
  for (int k = 0; k < 100; ++k) {
    const double lat = -1.0 + 0.1 * (ci(rng) + frac(rng)), lon = 2.0 + 0.2 * (cj(rng) + frac(rng));
    const MapSample s = *g.Sample(0, lat, lon);
    const double fd_lat = (g.Sample(0, lat + h, lon)->value_nT - g.Sample(0, lat - h, lon)->value_nT) / (2 * h);
    const double fd_lon = (g.Sample(0, lat, lon + h)->value_nT - g.Sample(0, lat, lon - h)->value_nT) / (2 * h);
    EXPECT_NEAR(s.dvalue_dlat_nT_per_deg, fd_lat, 1e-4 * std::abs(fd_lat) + 1e-3);
    EXPECT_NEAR(s.dvalue_dlon_nT_per_deg, fd_lon, 1e-4 * std::abs(fd_lon) + 1e-3);
  }
  // Nodes are reproduced exactly, including the last row and column.
  EXPECT_DOUBLE_EQ(g.Sample(0, 1.0, 4.0)->value_nT, Smooth(1.0, 4.0));
  EXPECT_DOUBLE_EQ(g.Sample(0, -1.0, 2.0)->value_nT, Smooth(-1.0, 2.0));
}

TEST(GeoGrid, OutsideIsNulloptAndEdgesAreInside) {
  const GeoGrid g = GeoGrid::FromFunction(Axis(10.0, 0.5, 3), Axis(60.0, 0.5, 3), "v", Smooth);
  EXPECT_TRUE(g.Sample(0, 10.0, 60.0).has_value());
  EXPECT_TRUE(g.Sample(0, 11.0, 61.0).has_value());
  EXPECT_FALSE(g.Sample(0, 11.0001, 60.5).has_value());
  EXPECT_FALSE(g.Sample(0, 10.5, 59.9999).has_value());
  EXPECT_FALSE(g.Sample(0, std::nan(""), 60.5).has_value());
  EXPECT_FALSE(g.Contains(9.0, 60.5));
}

TEST(GeoGrid, ReadsTheReferenceMapByColumnName) {
  const GeoGrid g = ReadGeoGridCsv(testing::ReferencePath("map_wmm_0p5deg.csv"), {"F_nT", "X_north_nT"});
  EXPECT_EQ(g.lat().count, 21);
  EXPECT_EQ(g.lon().count, 21);
  EXPECT_DOUBLE_EQ(g.lat().first_deg, 10.0);
  EXPECT_DOUBLE_EQ(g.lon().step_deg, 0.5);
  // Range stated in the reference README (F 38813.5...43621.9 nT, X 36688.6...39794.8 nT).
  EXPECT_NEAR(g.min_value(g.layer("F_nT")), 38813.5, 0.05);
  EXPECT_NEAR(g.max_value(g.layer("F_nT")), 43621.9, 0.05);
  EXPECT_NEAR(g.min_value(g.layer("X_north_nT")), 36688.6, 0.05);
  EXPECT_NEAR(g.max_value(g.layer("X_north_nT")), 39794.8, 0.05);
  EXPECT_EQ(ExpectInputError([&] { g.layer("Z_nT"); }).find("no layer 'Z_nT'") != std::string::npos, true);
}

// A 3 x 2 grid written in a shuffled order; lat, lon, v columns.
const char* kShuffled =
    "# comment\n"
    "v,lon,lat\n"
    "6,61,12\n1,60,10\n4,61,11\n2,61,10\n3,60,11\n5,60,12\n";

TEST(GeoGrid, ReadsAnyRowOrderAndNgdcText) {
  const std::string dir = testing::TempDir();
  WriteText(dir + "/m.csv", kShuffled);
  const GeoGrid g = ReadGeoGridCsv(dir + "/m.csv", {"v"});
  EXPECT_EQ(g.lat().count, 3);
  EXPECT_EQ(g.lon().count, 2);
  EXPECT_DOUBLE_EQ(g.node(0, 0, 0), 1.0);
  EXPECT_DOUBLE_EQ(g.node(0, 0, 1), 2.0);
  EXPECT_DOUBLE_EQ(g.node(0, 2, 1), 6.0);
  WriteText(dir + "/m.xyz", "# lon lat value\n61 12 6\n60   10\t1\n\n61 11 4\n61 10 2\n60 11 3\n60 12 5\n");
  const GeoGrid x = ReadGeoGridXyz(dir + "/m.xyz", "F_nT");
  EXPECT_EQ(x.layer_names().front(), "F_nT");
  EXPECT_EQ(x.values(0), g.values(0));
}

TEST(GeoGrid, BadMapsAreClearErrors) {
  const std::string dir = testing::TempDir();
  const auto read = [&](const std::string& text) {
    WriteText(dir + "/bad.csv", text);
    return ExpectInputError([&] { ReadGeoGridCsv(dir + "/bad.csv", {"v"}); });
  };
  // Irregular spacing (10, 11, 12.5).
  std::string e = read("lat,lon,v\n10,60,1\n10,61,1\n11,60,1\n11,61,1\n12.5,60,1\n12.5,61,1\n");
  EXPECT_NE(e.find("irregular latitude spacing"), std::string::npos) << e;
  // A hole: one node missing.
  e = read("lat,lon,v\n10,60,1\n10,61,1\n11,60,1\n11,61,1\n12,60,1\n");
  EXPECT_NE(e.find("hole in the map: no node at lat 12, lon 61"), std::string::npos) << e;
  // NaN value: file, line, column and position.
  e = read("lat,lon,v\n10,60,1\n10,61,NaN\n11,60,1\n11,61,1\n");
  EXPECT_NE(e.find("bad.csv:3: column 'v': no value (NaN or inf) at lat 10, lon 61"), std::string::npos) << e;
  // A node twice.
  e = read("lat,lon,v\n10,60,1\n10,61,1\n11,60,1\n11,61,1\n10,61,2\n");
  EXPECT_NE(e.find("bad.csv:6: node lat 10, lon 61 given twice (first on line 3)"), std::string::npos) << e;
  // Coordinates whose span overflows (fuzz/, tests/data/fuzz/map/): the step
  // was inf and a node's grid index NaN, written far outside the grid. The
  // latitude limit (core/limits.h) now stops them at the first row.
  e = read("lat,lon,v\n-1e308,0,1\n1e308,0,1\n-1e308,1,1\n1e308,1,1\n-1e308,2,1\n1e308,2,1\n");
  EXPECT_NE(e.find("bad.csv:2: column 'lat': -1e+308 deg is out of range"), std::string::npos) << e;
  // Nodes on a diagonal span an n x n grid: a hole, found without allocating it
  // (20 000 nodes asked for 3.2 GB).
  std::string diagonal = "lat,lon,v\n";
  for (int k = 0; k < 20000; ++k) diagonal += FormatNumber(0.001 * k) + "," + FormatNumber(0.001 * k) + ",1\n";
  e = read(diagonal);
  EXPECT_NE(e.find("hole in the map: no node at lat 0, lon 0.001"), std::string::npos) << e;
  EXPECT_NE(e.find("(20000 nodes for a 20000 x 20000 grid)"), std::string::npos) << e;
  // Missing layer column.
  WriteText(dir + "/bad.csv", "lat,lon,w\n10,60,1\n10,61,1\n11,60,1\n11,61,1\n");
  e = ExpectInputError([&] { ReadGeoGridCsv(dir + "/bad.csv", {"v"}); });
  EXPECT_NE(e.find("missing column 'v'"), std::string::npos) << e;
  // Text in a number (the CSV reader's file:line:column message).
  e = read("lat,lon,v\n10,60,1\n10,61,1\n11,60,abc\n11,61,1\n");
  EXPECT_NE(e.find("bad.csv:4"), std::string::npos) << e;
  // NGDC text: a short line and a NaN.
  WriteText(dir + "/bad.xyz", "60 10 1\n61 10\n");
  e = ExpectInputError([&] { ReadGeoGridXyz(dir + "/bad.xyz", "v"); });
  EXPECT_NE(e.find("bad.xyz:2: expected 'lon lat value', field 'value' missing"), std::string::npos) << e;
  WriteText(dir + "/bad.xyz", "60 10 1\n61 10 nan\n60 11 1\n61 11 1\n");
  e = ExpectInputError([&] { ReadGeoGridXyz(dir + "/bad.xyz", "v"); });
  EXPECT_NE(e.find("bad.xyz:2: column 'v': no value (NaN or inf) at lat 10, lon 61"), std::string::npos) << e;
}

TEST(PointIndex, FindsExactlyWhatAScanFinds) {
  const GeoGrid one = GeoGrid::FromFunction(Axis(0.0, 0.1, 40), Axis(0.0, 0.1, 50), "a", Smooth);
  std::vector<double> b(one.num_nodes());
  for (std::size_t n = 0; n < b.size(); ++n) b[n] = 100.0 * std::cos(0.37 * static_cast<double>(n));
  const GeoGrid g(one.lat(), one.lon(), {"a", "b"}, {one.values(0), b});
  const PointIndex single(g, {0}), both(g, {0, 1});
  std::mt19937 rng(11);
  std::uniform_int_distribution<std::size_t> node(0, g.num_nodes() - 1);
  for (int k = 0; k < 30; ++k) {
    const std::size_t n = node(rng);
    const std::vector<double> m = {g.values(0)[n] + 1.0, g.values(1)[n] - 2.0};
    const double tol = 5.0;
    std::vector<std::size_t> scan1, scan2;
    for (std::size_t q = 0; q < g.num_nodes(); ++q) {
      if (std::abs(g.values(0)[q] - m[0]) <= tol) {
        scan1.push_back(q);
        if (std::abs(g.values(1)[q] - m[1]) <= tol) scan2.push_back(q);
      }
    }
    const auto to_nodes = [&](const std::vector<PointHit>& hits) {
      std::vector<std::size_t> out;
      for (const PointHit& h : hits) out.push_back(static_cast<std::size_t>(h.i_lat) * g.lon().count + h.j_lon);
      return out;
    };
    EXPECT_EQ(to_nodes(single.Find({m[0]}, tol)), scan1);
    const auto hits2 = both.Find(m, tol);
    EXPECT_EQ(to_nodes(hits2), scan2);
    ASSERT_FALSE(hits2.empty());  // the node n itself
    for (const PointHit& h : hits2) EXPECT_LE(h.max_abs_difference_nT, tol);
  }
  EXPECT_THROW(both.Find({1.0}, 1.0), InputError);
  EXPECT_THROW(single.Find({std::nan("")}, 1.0), InputError);
}

}  // namespace
}  // namespace magnav::mapmatch
