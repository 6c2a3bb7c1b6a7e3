// The inverter's default gates off the tuning set (issue 25 item 6): on the
// fluxgate AUV passes of tests/data/generated/inverter_passes.csv (closest
// approach 7–9 m; tuning and held-out rows fixed before the defaults were
// chosen), TED+EGT with the default gates gives ≥ 20 fixes per pass with max
// error ≤ 1.7 m (the paper's fluxgate figure). docs/ACCURACY.md, "Default
// gates off the tuning set", is this test's table; scripts/heldout_inverter
// reproduces it with `magnav simulate` and `magnav invert`.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/simulate.h"
#include "magnav/inversion/inverter.h"
#include "reference_truth.h"
#include "test_data.h"
#include "track_runs.h"

namespace magnav::inversion {
namespace {

using magnav::testing::ErrorStats;
using magnav::testing::TruthTrack;

struct PassRow {
  std::string set, name;
  PassScenario scenario;
  double closest_3d_m = 0.0;
};

// The rows as scripts/heldout_inverter simulates them: the vessel 5 m above
// the sensor at the origin, at its closest approach at t = 75 s.
std::vector<PassRow> Rows() {
  const CsvTable c = CsvTable::Read(magnav::testing::TestDataDir() + "/generated/inverter_passes.csv");
  std::vector<PassRow> rows;
  for (std::size_t r = 0; r < c.num_rows(); ++r) {
    const auto num = [&](const char* col) { return c.number(r, c.column(col)); };
    PassRow row;
    row.set = c.text(r, c.column("set"));
    row.name = c.text(r, c.column("name"));
    row.closest_3d_m = num("closest_3d_m");
    PassScenario& sc = row.scenario;
    sc.moment_body = Vec3(num("mx"), num("my"), num("mz"));
    sc.start_heading_rad = num("heading_rad");
    sc.speed_mps = num("speed_mps");
    const double h = sc.start_heading_rad;
    const Vec3 v(std::cos(h), std::sin(h), 0.0), left(std::sin(h), -std::cos(h), 0.0);
    const double horizontal = std::sqrt(row.closest_3d_m * row.closest_3d_m - 25.0);
    const Vec3 closest = num("side") * horizontal * left + Vec3(0.0, 0.0, -5.0);
    sc.start_position = closest - 75.0 * sc.speed_mps * v;
    sc.segments = {{80.0, 0.0}, {60.0, num("turn_rps")}, {60.0, 0.0}};
    sc.sigma_B = magnav::testing::kFluxgateSigmaB;
    sc.sigma_T = magnav::testing::kFluxgateSigmaT;
    sc.seed = static_cast<std::uint64_t>(num("seed"));
    rows.push_back(row);
  }
  return rows;
}

// Measured with the defaults (docs/ACCURACY.md): fixes, max error (m).
struct Documented {
  const char* name;
  int count;
  double max_m;
};
constexpr Documented kDocumented[] = {
    {"t1", 114, 0.506}, {"t2", 99, 0.714}, {"t3", 141, 0.641}, {"t4", 42, 0.595},
    {"h1", 157, 0.648},  {"h2", 87, 0.670}, {"h3", 142, 0.647}, {"h4", 55, 0.721},
    {"h5", 104, 0.782},  {"h6", 107, 0.765}, {"h7", 77, 0.545}, {"h8", 149, 0.712},
};

TEST(DefaultGates, FluxgateAuvPassesAtSevenToNineMetres) {
  const std::vector<PassRow> rows = Rows();
  ASSERT_EQ(rows.size(), std::size(kDocumented));
  int heldout = 0;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const PassRow& row = rows[k];
    const Documented& doc = kDocumented[k];
    ASSERT_EQ(row.name, doc.name);
    const SimulatedPass pass = SimulatePass(row.scenario);
    const TruthTrack truth = magnav::testing::TruthOf(pass);
    double closest = 1e9;
    for (std::size_t i = 0; i < pass.samples.size(); ++i) {
      closest = std::min(closest, (truth.p[i] - pass.samples[i].p_SinW).norm());
    }
    InverterOptions defaults;
    defaults.B0_W = row.scenario.B0;
    const ErrorStats st = testing::RunInverter(pass.samples, truth, defaults);
    // The gates before 2026-11-25 (SNR ≥ 100, σ_3d ≤ 1.5 % of the range, no absolute gate).
    InverterOptions former = defaults;
    former.gates.min_snr = 100.0;
    former.gates.max_relative_sigma = 0.015;
    former.gates.max_position_sigma_3d_m = 0.0;
    const ErrorStats before = testing::RunInverter(pass.samples, truth, former);
    std::printf("| %s | %s | %.2f | %d / %.3f | %d / %.3f / %.3f |\n", row.name.c_str(), row.set.c_str(), closest,
                before.count, before.max, st.count, st.rms(), st.max);
    EXPECT_NEAR(closest, row.closest_3d_m, 0.05) << row.name;
    // The issue's target, on every row (held out and tuning).
    EXPECT_GE(st.count, 20) << row.name;
    EXPECT_LE(st.max, 1.7) << row.name;
    // The documented figures: at least count / 1.5 fixes, max within 1.5×.
    magnav::testing::ExpectCountFigure(st.count, doc.count, row.name + " fixes");
    magnav::testing::ExpectErrorFigure(st.max, doc.max_m, row.name + " max error");
    if (row.set == "heldout") ++heldout;
  }
  EXPECT_EQ(heldout, 8);
}

// The issue's case (row t1: the reference AUV moment and heading at 8.6 m):
// the former gates accepted no fix there.
TEST(DefaultGates, TheIssuesPassHadNoFixWithTheFormerGates) {
  const PassRow row = Rows().at(0);
  ASSERT_EQ(row.name, "t1");
  const SimulatedPass pass = SimulatePass(row.scenario);
  const TruthTrack truth = magnav::testing::TruthOf(pass);
  InverterOptions former;
  former.B0_W = row.scenario.B0;
  former.gates.min_snr = 100.0;
  former.gates.max_relative_sigma = 0.015;
  former.gates.max_position_sigma_3d_m = 0.0;
  EXPECT_EQ(testing::RunInverter(pass.samples, truth, former).count, 0);
}

}  // namespace
}  // namespace magnav::inversion
