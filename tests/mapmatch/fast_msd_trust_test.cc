// Fast MSD's covariance and status (issue 25 items 3 and 4; docs/ACCURACY.md,
// "Trust: covariance calibration over independent runs" and "Fast MSD: a
// covariance and an ambiguity flag"):
//  - on the first 6 runs of the calibration scenario off0p1_noise3
//    (scripts/calibration_scenarios/scenarios.csv, seeds 3201-3206, fixed
//    before any tuning) the ANEES of the published covariance is inside
//    [0.5, 2] × dof, for the final point and over every point — and the same
//    fixes with every σ doubled or halved are not;
//  - on the 20 tuning paths at 0.5 nT the every-point ANEES is inside the
//    interval with the map's interpolation error in the covariance and
//    outside without it (the linearised basin's covariance);
//  - on held-out paths with stretches in a wrong basin (605-608, 626) the
//    every-point ANEES is inside the interval with the other basins in the
//    covariance and far outside without them;
//  - a map with two equally good places for the path (periodic) gives
//    "ambiguous", never "converged", with a covariance that covers the other
//    place; a map without gives "converged".
#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/mapmatch/match.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

double Nees(const MatchResult& r, std::size_t p, double lat, double lon) {
  const double e0 = r.lat_deg[p] - lat, e1 = r.lon_deg[p] - lon;
  const double a = r.cov_lat_lat[p], b = r.cov_lat_lon[p], c = r.cov_lon_lon[p];
  const double det = a * c - b * b;
  return det > 0.0 && a > 0.0 ? (c * e0 * e0 - 2.0 * b * e0 * e1 + a * e1 * e1) / det
                              : std::numeric_limits<double>::infinity();
}

// Documented (docs/ACCURACY.md): ANEES over seeds 3201-3206, 2 dof.
// With the basin mean shift (fast_msd.h, on by default since 2026-11-26 evening; 2.09 / 2.09 with the
// rounds' positions); with the other basins (2026-11-26 12:00); 3.03 / 2.78 before, 2.79 before the
// map-error term.
constexpr double kDocumentedFinal = 1.93;
constexpr double kDocumentedPoints = 1.95;

// An every-point ANEES (2 dof) within [0.5, 2] × dof with the term under test, outside it with
// every σ doubled or halved, and above it without the term.
void ExpectCalibratedAndNotWithout(double with_anees, double without_anees) {
  EXPECT_GE(with_anees, 0.5 * 2);
  EXPECT_LE(with_anees, 2.0 * 2);
  EXPECT_LT(with_anees / 4.0, 0.5 * 2);  // σ × 2
  EXPECT_GT(with_anees * 4.0, 2.0 * 2);  // σ / 2
  EXPECT_GT(without_anees, 2.0 * 2);
}

TEST(FastMsdTrust, CovarianceIsCalibratedOnTheCalibrationSeeds) {
  const std::string dir = testing::TempDir();
  const std::string script = testing::TestDataDir() + "/../../scripts/heldout_mappaths";
  const auto [code, out] = testing::RunCommand({script, dir, "6", "0.1", "3", "3201"}, {}, std::chrono::seconds(120));
  ASSERT_EQ(code, 0) << out;
  const GeoGrid grid =
      ReadGeoGridCsv(testing::TestDataDir() + "/reference/map_crustal_anomaly.csv", {"anomaly_nT"});
  MatchOptions o;
  o.fast_msd.search_window_deg = 0.15;
  double final_sum = 0.0, points_sum = 0.0;
  int runs = 0, points = 0;
  for (int seed = 3201; seed <= 3206; ++seed) {
    const std::string file = dir + "/heldout_" + std::to_string(seed) + "_noise3.csv";
    const MatchResult r = Match(Method::kFastMsd, grid, 0, ReadMatchPath(file, "meas_nT"), o);
    EXPECT_TRUE(r.converged) << seed << ": " << r.BriefReport();
    const CsvTable t = CsvTable::Read(file);
    ASSERT_EQ(r.cov_lat_lat.size(), t.num_rows());
    for (std::size_t i = 0; i < t.num_rows(); ++i) {
      const double x = Nees(r, i, t.number(i, t.column("true_lat")), t.number(i, t.column("true_lon")));
      points_sum += x;
      ++points;
      if (i + 1 == t.num_rows()) final_sum += x;
    }
    ++runs;
  }
  const double final_anees = final_sum / runs, points_anees = points_sum / points;
  std::printf("fast-msd, seeds 3201-3206: ANEES final point %.3f, every point %.3f (dof 2)\n", final_anees,
              points_anees);
  for (const double anees : {final_anees, points_anees}) {
    EXPECT_GE(anees, 0.5 * 2);
    EXPECT_LE(anees, 2.0 * 2);
    // σ × 2 (covariance × 4) and σ / 2 leave the interval.
    EXPECT_LT(anees / 4.0, 0.5 * 2);
    EXPECT_GT(anees * 4.0, 2.0 * 2);
  }
  EXPECT_NEAR(final_anees, kDocumentedFinal, 0.01);
  EXPECT_NEAR(points_anees, kDocumentedPoints, 0.01);
}

// The map's own error in the covariance (docs/ACCURACY.md, "Fast MSD: the
// map's own error in the covariance"): on the 20 tuning paths 501-520 at
// 0.5 nT (readings from the bicubic field, the matcher's map bilinear) the
// every-point ANEES leaves [0.5, 2] × dof without the map's interpolation
// error bound in the reading variance (5.32) and is inside with it (3.79, the
// documented figure; the σ-doubled and halved covariances leave it). The
// final point is not asserted: it fails either way (4.16 with, 4.22 without).
// It asserts the term's effect, not its cause: with readings from the
// bilinear map itself (no interpolation error) the term helps as much
// (5.87 -> 4.20, scripts/fastmsd_lownoise_diagnosis; the docs say why).
constexpr double kDocumentedHalfNtPoints = 3.79;
constexpr double kDocumentedHalfNtPointsWithout = 5.32;

TEST(FastMsdTrust, MapErrorTermCalibratesTheTuningPathsAtHalfANanotesla) {
  const std::string dir = testing::TempDir() + "/fastmsd_map_error";
  const std::string script = testing::TestDataDir() + "/../../scripts/heldout_mappaths";
  const auto [code, out] =
      testing::RunCommand({script, dir, "20", "0.1", "0.5", "501"}, {}, std::chrono::seconds(120));
  ASSERT_EQ(code, 0) << out;
  const GeoGrid grid =
      ReadGeoGridCsv(testing::TestDataDir() + "/reference/map_crustal_anomaly.csv", {"anomaly_nT"});
  double with_sum = 0.0, without_sum = 0.0;
  int points = 0;
  for (int seed = 501; seed <= 520; ++seed) {
    const std::string file = dir + "/heldout_" + std::to_string(seed) + "_noise0p5.csv";
    const MatchPath path = ReadMatchPath(file, "meas_nT");
    MatchOptions o;
    o.fast_msd.search_window_deg = 0.15;
    o.fast_msd.basin_half_width_deg = 0.0;  // the linearised basin's covariance, where the term enters
    const MatchResult with = Match(Method::kFastMsd, grid, 0, path, o);
    o.fast_msd.map_error_in_covariance = false;
    const MatchResult without = Match(Method::kFastMsd, grid, 0, path, o);
    const CsvTable t = CsvTable::Read(file);
    ASSERT_EQ(with.cov_lat_lat.size(), t.num_rows());
    for (std::size_t i = 0; i < t.num_rows(); ++i) {
      // The term changes the covariance only.
      ASSERT_EQ(with.lat_deg[i], without.lat_deg[i]);
      ASSERT_EQ(with.lon_deg[i], without.lon_deg[i]);
      const double lat = t.number(i, t.column("true_lat")), lon = t.number(i, t.column("true_lon"));
      with_sum += Nees(with, i, lat, lon);
      without_sum += Nees(without, i, lat, lon);
      ++points;
    }
  }
  const double with_anees = with_sum / points, without_anees = without_sum / points;
  std::printf("fast-msd, tuning paths 501-520 at 0.5 nT: ANEES every point %.3f with the map error, "
              "%.3f without\n",
              with_anees, without_anees);
  ExpectCalibratedAndNotWithout(with_anees, without_anees);
  EXPECT_NEAR(with_anees, kDocumentedHalfNtPoints, 0.01);
  EXPECT_NEAR(without_anees, kDocumentedHalfNtPointsWithout, 0.01);
}

// The other basins in the covariance (docs/ACCURACY.md, "Fast MSD: the other
// basins in the covariance"): the held-out paths 605-608 (scripts/
// heldout_mappaths, 0.1° offset) at 0.5 and 3 nT and 626 at 0.5 nT, whose
// stretches were refined into a wrong local minimum of the map (605, 606, 608,
// 626; 607 is a right path between them). With the linearised basin only
// (basin_half_width_deg 0, main's covariance before 2026-11-26 12:00) their
// every-point ANEES is far outside [0.5, 2] × dof (39.0: 605 at 0.5 nT alone
// 147); with the basins' forward-backward it is inside (1.60), and the same
// covariances with σ doubled or halved are not. The positions are the same
// either way. Not here: 626 at 3 nT, whose stretch lies up to 0.019° off, beyond
// the grid's ±0.012°: it is not covered (mean NEES 41.6 -> 28.5, documented as
// what is not met). Both arms with the rounds' positions (basin_mean_shift off:
// the shift moves the points); the default (the shift on) is measured too:
// inside [0.5, 2] × dof, documented 1.38.
constexpr double kDocumentedWrongBasinsWith = 1.60;
constexpr double kDocumentedWrongBasinsWithout = 39.0;
constexpr double kDocumentedWrongBasinsShifted = 1.38;

TEST(FastMsdTrust, OtherBasinsCoverTheWrongBasinStretches) {
  const std::string dir = testing::TempDir() + "/fastmsd_basins";
  const std::string script = testing::TestDataDir() + "/../../scripts/heldout_mappaths";
  for (const auto& [count, first] : {std::pair<std::string, std::string>{"4", "605"}, {"1", "626"}}) {
    const auto [code, out] =
        testing::RunCommand({script, dir, count, "0.1", "0.5,3", first}, {}, std::chrono::seconds(120));
    ASSERT_EQ(code, 0) << out;
  }
  const GeoGrid grid =
      ReadGeoGridCsv(testing::TestDataDir() + "/reference/map_crustal_anomaly.csv", {"anomaly_nT"});
  double with_sum = 0.0, without_sum = 0.0, shifted_sum = 0.0;
  int points = 0;
  for (const int seed : {605, 606, 607, 608, 626}) {
    for (const std::string noise : {"0p5", "3"}) {
      if (seed == 626 && noise == "3") continue;  // beyond the grid (above)
      const std::string file = dir + "/heldout_" + std::to_string(seed) + "_noise" + noise + ".csv";
      const MatchPath path = ReadMatchPath(file, "meas_nT");
      MatchOptions o;
      o.fast_msd.search_window_deg = 0.15;
      const MatchResult shifted = Match(Method::kFastMsd, grid, 0, path, o);
      o.fast_msd.basin_mean_shift = false;
      const MatchResult with = Match(Method::kFastMsd, grid, 0, path, o);
      o.fast_msd.basin_half_width_deg = 0.0;
      const MatchResult without = Match(Method::kFastMsd, grid, 0, path, o);
      const CsvTable t = CsvTable::Read(file);
      ASSERT_EQ(with.cov_lat_lat.size(), t.num_rows());
      double path_with = 0.0, path_without = 0.0;
      for (std::size_t i = 0; i < t.num_rows(); ++i) {
        ASSERT_EQ(with.lat_deg[i], without.lat_deg[i]);
        ASSERT_EQ(with.lon_deg[i], without.lon_deg[i]);
        const double lat = t.number(i, t.column("true_lat")), lon = t.number(i, t.column("true_lon"));
        path_with += Nees(with, i, lat, lon);
        path_without += Nees(without, i, lat, lon);
        shifted_sum += Nees(shifted, i, lat, lon);
        ++points;
      }
      std::printf("  path %d noise %s: mean NEES %.2f with the basins, %.2f without\n", seed, noise.c_str(),
                  path_with / t.num_rows(), path_without / t.num_rows());
      with_sum += path_with;
      without_sum += path_without;
    }
  }
  const double with_anees = with_sum / points, without_anees = without_sum / points;
  std::printf("fast-msd, held-out paths 605-608 at 0.5 and 3 nT, 626 at 0.5 nT: ANEES every point %.3f with the basins, "
              "%.3f without\n",
              with_anees, without_anees);
  ExpectCalibratedAndNotWithout(with_anees, without_anees);
  const double shifted_anees = shifted_sum / points;
  std::printf("  with the basin mean shift (the default): ANEES every point %.3f\n", shifted_anees);
  ExpectCalibratedAndNotWithout(shifted_anees, without_anees);
  EXPECT_NEAR(shifted_anees, kDocumentedWrongBasinsShifted, 0.02 * kDocumentedWrongBasinsShifted);
  EXPECT_NEAR(with_anees, kDocumentedWrongBasinsWith, 0.02 * kDocumentedWrongBasinsWith);
  EXPECT_NEAR(without_anees, kDocumentedWrongBasinsWithout, 0.02 * kDocumentedWrongBasinsWithout);
}

// A path on a map that repeats itself every 0.02° in latitude (and not in
// longitude): within a ±0.02° window the coarse stage finds two equally good
// shifts, the true one and one 0.02° north.
MatchPath PathOn(const GeoGrid& g, double dlat, double dlon, std::vector<double>* lat, std::vector<double>* lon) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.5);
  MatchPath p;
  double h = 0.4, a = 0.06, b = 0.06;
  for (int k = 0; k < 100; ++k) {
    lat->push_back(a);
    lon->push_back(b);
    p.k.push_back(k);
    p.lat_deg.push_back(a + dlat);
    p.lon_deg.push_back(b + dlon);
    p.measured_nT.push_back(g.Sample(0, a, b)->value_nT + noise(rng));
    h += 0.05 * std::sin(0.15 * k);
    a += 0.0008 * std::cos(h);
    b += 0.0008 * std::sin(h);
  }
  return p;
}

TEST(FastMsdTrust, AWrongPeakIsNeverConverged) {
  const double kTwoPi = 2.0 * M_PI;
  const GeoGrid periodic = GeoGrid::FromFunction({0.0, 0.001, 201}, {0.0, 0.001, 201}, "a", [&](double la, double lo) {
    return 80.0 * std::sin(kTwoPi * la / 0.02) * std::cos(kTwoPi * lo / 0.031) + 40.0 * std::cos(kTwoPi * lo / 0.013);
  });
  std::vector<double> lat, lon;
  const MatchPath p = PathOn(periodic, 0.004, -0.003, &lat, &lon);
  MatchOptions o;
  o.fast_msd.search_window_deg = 0.02;
  const MatchResult r = Match(Method::kFastMsd, periodic, 0, p, o);
  std::printf("periodic map: %s\n", r.BriefReport().c_str());
  EXPECT_FALSE(r.converged);
  EXPECT_NE(r.reason.find("ambiguous"), std::string::npos) << r.reason;
  // The covariance covers the other place — the truth, or its copy 0.02°
  // north, whichever was not published — inside its 99 % ellipse at the last point.
  const std::size_t last = p.size() - 1;
  const double other_lat = std::abs(r.lat_deg[last] - lat[last]) < 0.01 ? lat[last] + 0.02 : lat[last];
  EXPECT_LT(Nees(r, last, other_lat, lon[last]), 9.21);
  // Without the check the same answer says "converged" (what the flag changes).
  o.fast_msd.ambiguity_ratio = 0.0;
  EXPECT_TRUE(Match(Method::kFastMsd, periodic, 0, p, o).converged);

  // A map without a second place: converged, a covariance well below the period.
  const GeoGrid bumps = GeoGrid::FromFunction({0.0, 0.001, 201}, {0.0, 0.001, 201}, "a", [](double la, double lo) {
    return 80.0 * std::exp(-((la - 0.07) * (la - 0.07) + (lo - 0.08) * (lo - 0.08)) / (2 * 0.015 * 0.015)) -
           60.0 * std::exp(-((la - 0.1) * (la - 0.1) + (lo - 0.05) * (lo - 0.05)) / (2 * 0.012 * 0.012)) +
           30.0 * std::sin(90.0 * la) * std::cos(70.0 * lo);
  });
  std::vector<double> lat2, lon2;
  const MatchPath q = PathOn(bumps, 0.004, -0.003, &lat2, &lon2);
  o.fast_msd.ambiguity_ratio = 2.0;
  const MatchResult s = Match(Method::kFastMsd, bumps, 0, q, o);
  std::printf("bumps: %s\n", s.BriefReport().c_str());
  EXPECT_TRUE(s.converged) << s.reason;
}

}  // namespace
}  // namespace magnav::mapmatch
