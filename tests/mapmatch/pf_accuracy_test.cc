// The particle-filter accuracy table of docs/ACCURACY.md ("Map matching II"),
// re-measured from its golden figures (tests/data/golden/pf_table.csv): every row (pf / afpf on a crustal reference path, default
// settings) is run through the library with the first kSeeds of the table's 20
// seeds; the mean second-half error must stay within kFigureMargin of the
// table's 20-seed mean, the final error within kFigureMargin of the table's
// mean + 2 standard deviations (the final point is one sample). Then the
// issue's targets that are met are asserted outright, and the PF's
// covariance honesty (mean NEES).
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/mapmatch/particle_filter.h"
#include "reference_truth.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

constexpr int kSeeds = 2;

struct Row {
  std::string method, path;
  double half_deg = 0.0, half_sd = 0.0, ins_half_deg = 0.0;
  double final_deg = 0.0, final_sd = 0.0, ins_final_deg = 0.0;
};

// The rows of the PF table (tests/data/golden/pf_table.csv; the same rows as
// docs/ACCURACY.md "Map matching II", kept equal by scripts/golden_tables check).
std::vector<Row> DocumentedRows() {
  const CsvTable t = CsvTable::Read(testing::TestDataDir() + "/golden/pf_table.csv");
  const auto col = [&](const char* name) { return t.column(name); };
  std::vector<Row> rows;
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    Row r;
    r.method = t.text(i, col("method"));
    r.path = std::string(t.text(i, col("path"))) + ".csv";
    r.half_deg = t.number(i, col("half_mean_deg"));
    r.half_sd = t.number(i, col("half_sd_deg"));
    r.ins_half_deg = t.number(i, col("ins_half_deg"));
    r.final_deg = t.number(i, col("final_mean_deg"));
    r.final_sd = t.number(i, col("final_sd_deg"));
    r.ins_final_deg = t.number(i, col("ins_final_deg"));
    rows.push_back(r);
  }
  return rows;
}

struct Measured {
  double half_deg = 0.0, final_deg = 0.0, ins_half_deg = 0.0, ins_final_deg = 0.0;
  double nees = 0.0;  // mean 2-D NEES over the second halves (the reported covariance)
};

Measured RunRow(const GeoGrid& g, const Row& row, int seeds) {
  const std::string file = testing::ReferencePath(row.path);
  const CsvTable t = CsvTable::Read(file);
  const MatchPath p = ReadMatchPath(file, "meas_nT");
  const std::size_t cl = t.column("true_lat"), cn = t.column("true_lon");
  const std::size_t n = p.size(), h = n / 2;
  Measured m;
  for (int seed = 1; seed <= seeds; ++seed) {
    ParticleFilterOptions o;  // the defaults
    o.seed = static_cast<std::uint64_t>(seed);
    std::vector<StepDiagnostics> steps;
    const MatchResult r = MatchParticleFilter(
        row.method == "pf" ? ParticleFilterKind::kPf : ParticleFilterKind::kAfpf, g, 0, p, o, &steps);
    for (std::size_t k = h; k < n; ++k) {
      const double e0 = r.lat_deg[k] - t.number(k, cl), e1 = r.lon_deg[k] - t.number(k, cn);
      m.half_deg += std::hypot(e0, e1) / static_cast<double>((n - h) * seeds);
      const StepDiagnostics& d = steps[k];
      const double det = d.cov_lat_lat * d.cov_lon_lon - d.cov_lat_lon * d.cov_lat_lon;
      m.nees += (d.cov_lon_lon * e0 * e0 - 2.0 * d.cov_lat_lon * e0 * e1 + d.cov_lat_lat * e1 * e1) / det /
                static_cast<double>((n - h) * seeds);
    }
    m.final_deg += std::hypot(r.lat_deg[n - 1] - t.number(n - 1, cl), r.lon_deg[n - 1] - t.number(n - 1, cn)) / seeds;
  }
  for (std::size_t k = h; k < n; ++k) {
    m.ins_half_deg += std::hypot(p.lat_deg[k] - t.number(k, cl), p.lon_deg[k] - t.number(k, cn)) /
                      static_cast<double>(n - h);
  }
  m.ins_final_deg = std::hypot(p.lat_deg[n - 1] - t.number(n - 1, cl), p.lon_deg[n - 1] - t.number(n - 1, cn));
  return m;
}

const GeoGrid& Crustal() {
  static const GeoGrid g = ReadGeoGridCsv(testing::ReferencePath("map_crustal_anomaly.csv"), {"anomaly_nT"});
  return g;
}

TEST(ParticleFilterAccuracy, EveryDocumentedRowHoldsAndTheMetTargetsHold) {
  const std::vector<Row> rows = DocumentedRows();
  ASSERT_EQ(rows.size(), 2u * 2 * 2);  // pf, afpf x 2 offsets x 2 noise levels
  for (const Row& row : rows) {
    const std::string what = row.method + " " + row.path;
    const Measured m = RunRow(Crustal(), row, kSeeds);
    testing::ExpectErrorFigure(m.half_deg, row.half_deg, what + " second-half mean error");
    testing::ExpectErrorFigure(m.final_deg, row.final_deg + 2.0 * row.final_sd, what + " final error");
    EXPECT_NEAR(m.ins_half_deg, row.ins_half_deg, 1e-3 * row.ins_half_deg) << what;
    EXPECT_NEAR(m.ins_final_deg, row.ins_final_deg, 1e-3 * row.ins_final_deg) << what;
    // Issue 12's targets: both filters cut the second-half mean error to ≤ 25 %
    // of the INS's on every path (measured: PF 14–22 % on the 0.01° paths,
    // AFPF 19 %; a 2× regression breaks it).
    EXPECT_LE(m.half_deg, 0.25 * m.ins_half_deg) << what;
    // The PF's covariance is honest: mean NEES over the second half in
    // [1, 3.5] (2 if honest; measured 2.5–2.8 over 20 seeds), which the
    // covariance halved (NEES ≥ 5) leaves. The AFPF's is not (2.7–4.4 on
    // these paths, docs/ACCURACY.md): not asserted.
    if (row.method == "pf") {
      RecordProperty("nees_" + row.path, std::to_string(m.nees));
      EXPECT_GE(m.nees, 1.0) << what;
      EXPECT_LE(m.nees, 3.5) << what;
    }
  }
}

}  // namespace
}  // namespace magnav::mapmatch
