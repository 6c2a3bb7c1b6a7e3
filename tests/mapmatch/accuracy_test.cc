// The map-matching accuracy table of docs/ACCURACY.md, re-measured: every row
// of the table (every method on every reference map-path file, the fixed
// settings of scripts/accuracy_mapmatch) is run through the library and its
// final-point and mean errors asserted against the golden figures
// (tests/data/golden/mapmatch_table.csv, the page's table; kFigureMargin), its
// converged flag must match; then the issue's targets are asserted outright.
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/mapmatch/match.h"
#include "reference_truth.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

struct Row {
  std::string path, column, method;
  double window_deg = 0.0;
  double final_deg = 0.0, ins_final_deg = 0.0, mean_deg = 0.0, ins_mean_deg = 0.0;
  bool converged = false;
};

// The rows of the map-matching table (tests/data/golden/mapmatch_table.csv; the
// same rows as docs/ACCURACY.md, kept equal by scripts/golden_tables check).
std::vector<Row> DocumentedRows() {
  const CsvTable t = CsvTable::Read(testing::TestDataDir() + "/golden/mapmatch_table.csv");
  const auto col = [&](const char* name) { return t.column(name); };
  std::vector<Row> rows;
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    Row r;
    r.path = std::string(t.text(i, col("path"))) + ".csv";
    r.column = t.text(i, col("column"));
    r.method = t.text(i, col("method"));
    r.window_deg = t.number(i, col("window_deg"));
    r.final_deg = t.number(i, col("final_deg"));
    r.ins_final_deg = t.number(i, col("ins_final_deg"));
    r.mean_deg = t.number(i, col("mean_deg"));
    r.ins_mean_deg = t.number(i, col("ins_mean_deg"));
    r.converged = t.text(i, col("converged")) == "yes";
    rows.push_back(r);
  }
  return rows;
}

std::string MapOf(const std::string& path) {
  if (path.find("crustal") != std::string::npos) return "map_crustal_anomaly.csv";
  return path.find("0p05deg") != std::string::npos ? "map_wmm_0p05deg.csv" : "map_wmm_0p5deg.csv";
}

struct Errors {
  double final_deg, mean_deg, ins_final_deg, ins_mean_deg;
};

Errors Measure(const CsvTable& t, const MatchResult& r) {
  const std::size_t cl = t.column("true_lat"), cn = t.column("true_lon"), il = t.column("ins_lat"),
                    in = t.column("ins_lon");
  Errors e{0, 0, 0, 0};
  for (std::size_t k = 0; k < t.num_rows(); ++k) {
    const double err = std::hypot(r.lat_deg[k] - t.number(k, cl), r.lon_deg[k] - t.number(k, cn));
    const double ins = std::hypot(t.number(k, il) - t.number(k, cl), t.number(k, in) - t.number(k, cn));
    e.mean_deg += err / static_cast<double>(t.num_rows());
    e.ins_mean_deg += ins / static_cast<double>(t.num_rows());
    e.final_deg = err;
    e.ins_final_deg = ins;
  }
  return e;
}

class MapCache {
 public:
  const GeoGrid& Get(const std::string& map, const std::string& column) {
    auto& slot = maps_[map + "/" + column];
    if (!slot) slot = std::make_unique<GeoGrid>(ReadGeoGridCsv(testing::ReferencePath(map), {column}));
    return *slot;
  }

 private:
  std::map<std::string, std::unique_ptr<GeoGrid>> maps_;
};

MatchResult MatchRow(MapCache& maps, const Row& row) {
  const GeoGrid& g = maps.Get(MapOf(row.path), row.column);
  const std::string meas = row.column == "X_north_nT" ? "meas_X_nT" : "meas_nT";
  const MatchPath p = ReadMatchPath(testing::ReferencePath(row.path), meas);
  MatchOptions o;  // the defaults: no tuning per file
  o.correlation.search_window_deg = row.window_deg;
  o.fast_msd.search_window_deg = row.window_deg;
  return Match(*ParseMethod(row.method), g, 0, p, o);
}

TEST(MapMatchAccuracy, EveryDocumentedRowHolds) {
  const std::vector<Row> rows = DocumentedRows();
  // 2 WMM grids x 4 noise levels x 2 components x 9 methods + crustal 2 offsets x 4 noise x 10.
  ASSERT_EQ(rows.size(), 2u * 4 * 2 * 9 + 2u * 4 * 10);
  MapCache maps;
  for (const Row& row : rows) {
    const std::string what = row.path + " " + row.column + " " + row.method;
    const MatchResult r = MatchRow(maps, row);
    const Errors e = Measure(CsvTable::Read(testing::ReferencePath(row.path)), r);
    testing::ExpectErrorFigure(e.final_deg, row.final_deg, what + " final error");
    testing::ExpectErrorFigure(e.mean_deg, row.mean_deg, what + " mean error");
    EXPECT_NEAR(e.ins_final_deg, row.ins_final_deg, 1e-3 * row.ins_final_deg) << what;
    EXPECT_NEAR(e.ins_mean_deg, row.ins_mean_deg, 1e-3 * row.ins_mean_deg) << what;
    EXPECT_EQ(r.converged, row.converged) << what << ": " << r.BriefReport();
  }
}

Errors RunOne(MapCache& maps, const std::string& path, const std::string& column, const std::string& method,
              double window_deg) {
  Row row;
  row.path = path;
  row.column = column;
  row.method = method;
  row.window_deg = window_deg;
  return Measure(CsvTable::Read(testing::ReferencePath(path)), MatchRow(maps, row));
}

TEST(MapMatchAccuracy, IssueTargetsOnTheCrustalMap) {
  // Fast MSD with the coarse stage (±0.15°): mean error ≤ 0.001° at 0.5 nT and
  // ≤ 0.002° at 3 nT, from both start offsets.
  MapCache maps;
  for (const std::string off : {"0p01deg", "0p1deg"}) {
    const std::string base = "mappath_crustal_off" + off + "_noise";
    EXPECT_LE(RunOne(maps, base + "0p5nT.csv", "anomaly_nT", "fast-msd", 0.15).mean_deg, 0.001) << off;
    EXPECT_LE(RunOne(maps, base + "3nT.csv", "anomaly_nT", "fast-msd", 0.15).mean_deg, 0.002) << off;
  }
}

TEST(MapMatchAccuracy, JacobiSolverMeetsTheSameTargets) {
  // docs/ACCURACY.md "Fast MSD: direct solver (default) and the paper's Jacobi
  // iteration" (the Jacobi columns; the table above is the default's) and the
  // issue's targets.
  MapCache maps;
  const GeoGrid& g = maps.Get("map_crustal_anomaly.csv", "anomaly_nT");
  struct Case {
    std::string path;
    double documented_deg, target_deg;
  };
  for (const Case& c : {Case{"mappath_crustal_off0p01deg_noise0p5nT.csv", 0.00072, 0.001},
                        Case{"mappath_crustal_off0p01deg_noise3nT.csv", 0.00153, 0.002},
                        Case{"mappath_crustal_off0p1deg_noise0p5nT.csv", 0.00072, 0.001},
                        Case{"mappath_crustal_off0p1deg_noise3nT.csv", 0.00140, 0.002}}) {
    FastMsdOptions o;
    o.solver = FastMsdSolver::kJacobi;
    o.search_window_deg = 0.15;
    const MatchResult r = MatchFastMsd(g, 0, ReadMatchPath(testing::ReferencePath(c.path), "meas_nT"), o);
    const Errors e = Measure(CsvTable::Read(testing::ReferencePath(c.path)), r);
    testing::ExpectErrorFigure(e.mean_deg, c.documented_deg, c.path + " jacobi");
    EXPECT_LE(e.mean_deg, c.target_deg) << c.path;
  }
}

TEST(MapMatchAccuracy, ShapeMatchersOnTheWmmFinalPoint) {
  // WMM 0.5°, F, noise-free: the best of ICP, ICCP and MMA cuts the INS's
  // final-point error by ≥ 60 % (the default planar ICP) and none of them
  // makes it worse; the thesis' 3-D ICP (figure 0.802°) does not reach 60 %.
  MapCache maps;
  double best = 1e9, ins = 0.0;
  for (const std::string method : {"icp", "iccp", "mma"}) {
    const Errors e = RunOne(maps, "mappath_wmm_0p5deg_noise0nT.csv", "F_nT", method, 0.0);
    EXPECT_LT(e.final_deg, e.ins_final_deg) << method;
    best = std::min(best, e.final_deg);
    ins = e.ins_final_deg;
  }
  EXPECT_LE(best, 0.4 * ins);
  const GeoGrid& g = maps.Get("map_wmm_0p5deg.csv", "F_nT");
  const std::string path = "mappath_wmm_0p5deg_noise0nT.csv";
  IcpOptions o;
  o.planar_motion = false;
  const MatchResult r3 = MatchIcp(g, 0, ReadMatchPath(testing::ReferencePath(path), "meas_nT"), o);
  const Errors e3 = Measure(CsvTable::Read(testing::ReferencePath(path)), r3);
  testing::ExpectErrorFigure(e3.final_deg, 0.802, "3-D ICP final error");
  EXPECT_LT(e3.final_deg, e3.ins_final_deg);
}

}  // namespace
}  // namespace magnav::mapmatch
