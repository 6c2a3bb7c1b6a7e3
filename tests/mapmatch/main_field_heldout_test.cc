// Main-field (WMM) maps off the tuning paths (issue 23 item 5): on the
// held-out paths of `scripts/heldout_mappaths --wmm 0p5deg` (seeds 101..110,
// committed before any was matched), 0.5 nT, with the main-field configuration
// of scripts/accuracy_mainfield, MMA — the best method there — ends nearer the
// truth than the INS on every path and cuts the mean final error by the
// documented figure; MAD ±2.5° makes it worse and says "converged" on at most
// the documented number of paths ("no better than the prior", ReviewResult);
// ICP loses "converged" on 2 of the 5 paths where it ends further ("... at the
// path's end"). With the paths' own INS model as the prior (--ins-drift-sd
// 0.144, scripts/accuracy_mainfield) no result says "converged": the map's
// information along the F iso-line at the path's end is below the prior's
// ("partly observable", ReviewObservability), on the paths where MMA and ICP
// end nearer the truth as on those where they end further.
// docs/ACCURACY.md, "Main-field (WMM) maps", is the full table
// (scripts/accuracy_mainfield --heldout).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/mapmatch/match.h"
#include "reference_truth.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

// Documented (docs/ACCURACY.md, held-out per-path table, 0.5° grid, 0.5 nT):
// mean over paths 101..110 of the final error, deg.
constexpr double kInsMeanFinal = 1.1652;  // the INS
constexpr double kMmaMeanFinal = 0.9031;  // MMA
constexpr int kMadConverged = 1;          // MAD ±2.5° paths "converged" (of 10)
// The map information along the least observed direction at the path's end,
// as a fraction of the prior's, for MMA: at most this on every path (measured
// at most 0.0244, docs/ACCURACY.md "Partly observable"; 2x that; the
// threshold of "partly observable" is 1).
constexpr double kMmaMaxRatio = 0.05;

double FinalErrorDeg(const CsvTable& t, const MatchResult& r) {
  const std::size_t last = t.num_rows() - 1;
  return std::hypot(r.lat_deg[last] - t.number(last, t.column("true_lat")),
                    r.lon_deg[last] - t.number(last, t.column("true_lon")));
}

TEST(MainFieldHeldOut, MmaBeatsTheInsOnEveryPathAndMadSaysNotConverged) {
  const std::string dir = testing::TempDir();
  const std::string script = testing::TestDataDir() + "/../../scripts/heldout_mappaths";
  const auto [code, out] =
      testing::RunCommand({script, "--wmm", "0p5deg", dir, "10", "0.5", "101"}, {}, std::chrono::seconds(60));
  ASSERT_EQ(code, 0) << out;
  const GeoGrid g = ReadGeoGridCsv(testing::ReferencePath("map_wmm_0p5deg.csv"), {"F_nT"});
  MatchOptions o;
  o.max_correction_deg = 4.7;  // the prior on the INS error (scripts/accuracy_mainfield)
  o.correlation.search_window_deg = 2.5;
  o.observability.prior.drift_sd_deg = 0.144;  // the INS model: U(+-0.5) x 0.5 deg per step and axis, from 0
  double ins_sum = 0.0, mma_sum = 0.0;
  int mad_converged = 0, mad_worse = 0;
  double mma_max_ratio = 0.0;
  int icp_converged_right = 0, icp_converged_wrong = 0, icp_right_count = 0;
  for (int p = 101; p <= 110; ++p) {
    const std::string file = dir + "/wmm_0p5deg_" + std::to_string(p) + "_noise0p5.csv";
    const CsvTable t = CsvTable::Read(file);
    const MatchPath path = ReadMatchPath(file, "meas_nT");
    MatchResult ins;
    ins.lat_deg = path.lat_deg;
    ins.lon_deg = path.lon_deg;
    const double e_ins = FinalErrorDeg(t, ins);
    const MatchResult mma = Match(Method::kMma, g, 0, path, o);
    const double e_mma = FinalErrorDeg(t, mma);
    EXPECT_LT(e_mma, e_ins) << "path " << p;
    EXPECT_FALSE(mma.converged) << "path " << p;
    EXPECT_EQ(mma.reason.find("partly observable: along-iso-line error unconstrained"), 0u)
        << "path " << p << ": " << mma.reason;
    EXPECT_LE(mma.observability_ratio, kMmaMaxRatio) << "path " << p << ": " << mma.observability;
    mma_max_ratio = std::max(mma_max_ratio, mma.observability_ratio);
    // ICP, its main-field configuration (--subdivision 5): the end check
    // (ReviewResult, "no better than the prior at the path's end").
    MatchOptions oi = o;
    oi.icp.closest_point_subdivision = 5;
    const MatchResult icp = Match(Method::kIcp, g, 0, path, oi);
    const bool icp_right = FinalErrorDeg(t, icp) < e_ins;
    if (icp.converged) ++(icp_right ? icp_converged_right : icp_converged_wrong);
    if (icp_right) ++icp_right_count;
    if (p == 104 || p == 108) {
      EXPECT_NE(icp.reason.find("no better than the prior at the path's end"), std::string::npos)
          << "path " << p << ": " << icp.BriefReport();
    }
    const MatchResult mad = Match(Method::kMad, g, 0, path, o);
    if (mad.converged) ++mad_converged;
    if (FinalErrorDeg(t, mad) >= e_ins) ++mad_worse;
    ins_sum += e_ins;
    mma_sum += e_mma;
  }
  std::printf("WMM 0.5 deg held out, 0.5 nT: INS mean final %.4f deg, MMA %.4f deg (%+.0f %%); "
              "MAD converged on %d/10, worse than the INS on %d/10\n",
              ins_sum / 10, mma_sum / 10, -100.0 * (1.0 - mma_sum / ins_sum), mad_converged, mad_worse);
  EXPECT_NEAR(ins_sum / 10, kInsMeanFinal, 1e-3);  // the same paths as documented
  testing::ExpectErrorFigure(mma_sum / 10, kMmaMeanFinal, "MMA mean final error, WMM 0.5 deg held out");
  EXPECT_LE(mad_converged, kMadConverged);
  // ICP ends nearer the truth than the INS on 5 of the 10 paths; without the
  // observability review all 5 said "converged", and 3 of the 5 where it ends
  // further (5 before the end check); now none does.
  std::printf("MMA: map information along the least observed direction at the end at most %.3g of the prior's\n",
              mma_max_ratio);
  std::printf("ICP: right on %d/10, converged right %d, converged wrong %d\n", icp_right_count, icp_converged_right,
              icp_converged_wrong);
  EXPECT_EQ(icp_right_count, 5);
  EXPECT_EQ(icp_converged_right, 0);
  EXPECT_EQ(icp_converged_wrong, 0);
}

}  // namespace
}  // namespace magnav::mapmatch
