// `magnav evaluate` on tiny multi-vessel files whose scores are worked out by
// hand: GOSPA per epoch and overall (c = 10 m, p = 2: a missed vessel or a
// false row costs c²/2 = 50 m²), its CSV, and single-sample fix files with
// rejected fixes scored against a multi-vessel truth; the mean NEES per
// regime (inside, outside, coasting) of a track file.
#include <cmath>
#include <fstream>
#include <string>
#include <tuple>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav {
namespace {

const std::string kMagnav = MAGNAV_BIN;

std::pair<int, std::string> Evaluate(const std::vector<std::string>& args) {
  std::vector<std::string> argv = {kMagnav, "evaluate"};
  argv.insert(argv.end(), args.begin(), args.end());
  return testing::RunCommand(argv);
}

// Two vessels standing still, 100 m apart, at three instants.
void WriteTruth(const std::string& path) {
  std::ofstream f(path);
  f << "t,vessel_id,x,y,z\n";
  for (const char* t : {"0", "0.1", "0.2"}) f << t << ",1,0,0,0\n" << t << ",2,100,0,0\n";
}

TEST(EvaluateCli, GospaOfATinyTrackFileEqualsTheHandWorkedValue) {
  const std::string dir = testing::TempDir();
  WriteTruth(dir + "/truth.csv");
  // t = 0: both tracked, 3 m and 4 m off: 9 + 16 = 25 m² → GOSPA 5 m.
  // t = 0.1: vessel 2 missed: 50 m² → √50 m. t = 0.2: both exact, one
  // false row 50 m from each: 50 m² → √50 m. Mean (5 + 2√50)/3 = 6.3807 m.
  std::ofstream(dir + "/track.csv") << "t,track_id,x,y,z\n"
                                    << "0,1,0,3,0\n0,2,100,4,0\n"
                                    << "0.1,1,0,0,0\n"
                                    << "0.2,1,0,0,0\n0.2,2,100,0,0\n0.2,3,50,0,0\n";
  const auto [rc, out] = Evaluate({"--estimate", dir + "/track.csv", "--truth", dir + "/truth.csv", "--gospa",
                                   dir + "/gospa.csv"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("GOSPA (c 10 m, p 2, alpha 2) over 3 epochs: mean 6.381 m, max 7.071 m; per epoch, mean "
                     "localisation 8.333 m^2, missed 16.67 m^2 (0.3333 vessels), false 16.67 m^2 (0.3333 estimates)"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("1 false"), std::string::npos) << out;  // the row at 50 m, beyond the 5 m gate
  const CsvTable g = CsvTable::Read(dir + "/gospa.csv");
  const std::vector<std::string> header = {"t", "gospa", "localisation", "missed", "false"};
  ASSERT_EQ(g.header(), header);
  ASSERT_EQ(g.num_rows(), 3u);
  const double expected[3][5] = {{0.0, 5.0, 25.0, 0.0, 0.0},
                                 {0.1, std::sqrt(50.0), 0.0, 50.0, 0.0},
                                 {0.2, std::sqrt(50.0), 0.0, 0.0, 50.0}};
  for (std::size_t k = 0; k < 3; ++k) {
    for (std::size_t c = 0; c < 5; ++c) EXPECT_NEAR(g.number(k, c), expected[k][c], 1e-12) << k << "," << c;
  }
  EXPECT_EQ(g.text(1, 0), "0.1");  // the truth's time as written, not 1e8 ns · 1e-9
  // --gospa-c 4: a miss or a false row costs 8 m²; the 4 m pair is at c, so a miss and a false
  // row (9 + 8 + 8 = 25 m² at t = 0).
  const auto [rc2, out2] =
      Evaluate({"--estimate", dir + "/track.csv", "--truth", dir + "/truth.csv", "--gospa-c", "4"});
  ASSERT_EQ(rc2, 0) << out2;
  EXPECT_NE(out2.find("mean 3.552 m"), std::string::npos) << out2;  // (5 + 2·√8)/3
  // --gospa with a one-vessel truth is refused.
  std::ofstream(dir + "/one.csv") << "t,x,y,z\n0,0,0,0\n";
  const auto [rc3, out3] =
      Evaluate({"--estimate", dir + "/track.csv", "--truth", dir + "/one.csv", "--gospa", dir + "/g2.csv"});
  EXPECT_EQ(rc3, 2) << out3;
}

TEST(EvaluateCli, FixFilesWithRejectedFixesAreScoredAgainstTheNearestVessel) {
  const std::string dir = testing::TempDir();
  WriteTruth(dir + "/truth.csv");
  // As magnav invert writes them: a rejected fix with an empty position.
  std::ofstream(dir + "/fixes.csv") << "t,sensor_id,dipole_x,dipole_y,dipole_z,valid,reason\n"
                                    << "0,0,,,,0,low_snr\n"
                                    << "0,1,1,0,0,1,\n"
                                    << "0.1,0,100,0,2,1,\n"
                                    << "0.1,1,100,0,-2,1,\n"
                                    << "0.2,1,30,0,0,1,\n";
  const auto [rc, out] = Evaluate({"--estimate", dir + "/fixes.csv", "--truth", dir + "/truth.csv"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("fixes 5: valid 4, rejected 1 (valid = 0: counted, not scored); each valid fix scored against "
                     "the nearest truth vessel at its time: 1 false"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("vessel 1: in-field instants 3, fixes 1 at 1 of them (coverage 0.3333), RMS 1 m, max 1 m"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("vessel 2: in-field instants 3, fixes 2 at 1 of them (coverage 0.3333), RMS 2 m, max 2 m"),
            std::string::npos)
      << out;
  // GOSPA needs one estimate per vessel: refused for fixes.
  const auto [rc2, out2] =
      Evaluate({"--estimate", dir + "/fixes.csv", "--truth", dir + "/truth.csv", "--gospa", dir + "/g.csv"});
  EXPECT_EQ(rc2, 2) << out2;
  EXPECT_NE(out2.find("--gospa needs a track file"), std::string::npos) << out2;
}

// `magnav evaluate`'s NEES per regime (issue 24 item 6), on a hand-made track
// file whose every NEES is known: coasting rows (state column) apart, the
// others inside or outside --reach (15 m) of the sensor by the true position;
// a file without the state column (an older track file) has no coasting rows.
TEST(EvaluateCli, MeanNeesPerRegimeOfATrackFile) {
  const std::string dir = testing::TempDir();
  // Truth 5, 30, 40 and 10 m from the sensor at the origin; errors of 1, 2, 3
  // and (1, 1) sigma: NEES 1, 4, 9, 2.
  std::ofstream(dir + "/truth.csv") << "t,x,y,z\n0,5,0,-5\n1,30,0,-5\n2,40,0,-5\n3,10,0,-5\n";
  const std::string cols = "t,track_id,x,y,z,vx,vy,heading,sigma_x,sigma_y,sigma_z";
  const std::string rows[] = {"0,1,5.1,0,-5,1,0,0,0.1,0.1,0.1", "1,1,30,0.2,-5,1,0,0,0.1,0.1,0.1",
                              "2,1,40,0,-4.7,1,0,0,0.1,0.1,0.1", "3,1,10.1,0.1,-5,1,0,0,0.1,0.1,0.1"};
  const std::string states[] = {"confirmed", "confirmed", "coasting", "confirmed"};
  {
    std::ofstream with(dir + "/with.csv"), without(dir + "/without.csv");
    with << cols << ",state\n";
    without << cols << "\n";
    for (int k = 0; k < 4; ++k) {
      with << rows[k] << "," << states[k] << "\n";
      without << rows[k] << "\n";
    }
  }
  const auto evaluate = [&](const std::string& est, const std::string& truth) {
    return Evaluate({"--estimate", est, "--truth", truth, "--sensors", "0,0,0"});
  };
  auto [rc, out] = evaluate(dir + "/with.csv", dir + "/truth.csv");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("regime inside: 1.5 over 2 rows"), std::string::npos) << out;
  EXPECT_NE(out.find("regime outside: 4 over 1 rows"), std::string::npos) << out;
  EXPECT_NE(out.find("regime coasting: 9 over 1 rows, RMS 0.3 m"), std::string::npos) << out;
  std::tie(rc, out) = evaluate(dir + "/without.csv", dir + "/truth.csv");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("no state column"), std::string::npos) << out;
  EXPECT_NE(out.find("regime outside: 6.5 over 2 rows"), std::string::npos) << out;
  EXPECT_EQ(out.find("regime coasting"), std::string::npos) << out;
  // The same rows against a multi-vessel truth (vessel_id): the same regimes.
  std::ofstream(dir + "/truth_multi.csv")
      << "t,vessel_id,x,y,z\n0,1,5,0,-5\n1,1,30,0,-5\n2,1,40,0,-5\n3,1,10,0,-5\n";
  std::tie(rc, out) = evaluate(dir + "/with.csv", dir + "/truth_multi.csv");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("regime inside: 1.5 over 2 rows"), std::string::npos) << out;
  EXPECT_NE(out.find("regime coasting: 9 over 1 rows"), std::string::npos) << out;
  // An unknown state is refused, naming the place.
  {
    std::ofstream bad(dir + "/bad.csv");
    bad << cols << ",state\n" << rows[0] << ",lost\n";
  }
  std::tie(rc, out) = evaluate(dir + "/bad.csv", dir + "/truth.csv");
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("column 'state': expected confirmed, coasting or start, got 'lost'"), std::string::npos) << out;
}

// With magnav track's cov_xy, cov_xz, cov_yz the NEES uses the full 3x3: sigma 0.1 m on every axis
// and cov_xy = 0.006 m^2, so the x-y block is [0.01 0.006; 0.006 0.01] (det 6.4e-5). e = (0.1, 0.1, 0):
// NEES 8e-5 / 6.4e-5 = 1.25 (diagonal sigmas: 2); e = (0.2, 0, 0): 4e-4 / 6.4e-5 = 6.25 (diagonal: 4);
// a row with its cov_* empty uses the diagonal, e = (0, 0, 0.1): 1; a row whose P is not positive
// definite (cov_xy 0.02 > 0.1 x 0.1) is left out. Mean (1.25 + 6.25 + 1) / 3 = 2.83.
TEST(EvaluateCli, FullCovarianceNeesOfATrackFile) {
  const std::string dir = testing::TempDir();
  std::ofstream(dir + "/truth.csv") << "t,x,y,z\n0,5,0,-5\n1,6,0,-5\n2,7,0,-5\n3,8,0,-5\n";
  std::ofstream(dir + "/cov.csv")
      << "t,track_id,x,y,z,vx,vy,heading,sigma_x,sigma_y,sigma_z,state,cov_xy,cov_xz,cov_yz\n"
      << "0,1,5.1,0.1,-5,1,0,0,0.1,0.1,0.1,confirmed,0.006,0,0\n"
      << "1,1,6.2,0,-5,1,0,0,0.1,0.1,0.1,confirmed,0.006,0,0\n"
      << "2,1,7,0,-4.9,1,0,0,0.1,0.1,0.1,confirmed,,,\n"
      << "3,1,8.1,0,-5,1,0,0,0.1,0.1,0.1,confirmed,0.02,0,0\n";
  const auto [rc, out] = Evaluate({"--estimate", dir + "/cov.csv", "--truth", dir + "/truth.csv", "--sensors", "0,0,0"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("mean NEES (full 3x3 covariance, 3 dof): 2.83 over 3 epochs"), std::string::npos) << out;
  EXPECT_NE(out.find("mean NEES per regime (full 3x3 covariance, 3 dof;"), std::string::npos) << out;
  EXPECT_NE(out.find("regime inside: 2.83 over 3 rows"), std::string::npos) << out;
}

TEST(EvaluateCli, HelpDefinesEveryFigure) {
  const auto [rc, out] = Evaluate({"--help"});
  ASSERT_EQ(rc, 0) << out;
  for (const char* w : {"coverage:", "purity", "overrun:", "GOSPA", "localisation =", "missed =", "false =",
                        "mean NEES", "mean NEES per regime", "in-field instants:", "beyond range", "ANEES:",
                        "inside 95 %:"}) {
    EXPECT_NE(out.find(w), std::string::npos) << w;
  }
}

// Sensor positions (issue 23 item 4; before: "missing column 't'"): two
// sensors worked by hand — errors 3-4-5 m and 0 m, sigmas (3, 4) and (1, 1),
// bounds (6, 8) and (1, 1) — and the localizer's output on the reference
// pass, whose RMSE is docs/ACCURACY.md's EKF figure.
TEST(EvaluateCli, SensorPositionsAgainstTheTrueSensors) {
  const std::string dir = testing::TempDir();
  std::ofstream(dir + "/truth.csv") << "sensor_id,x,y,z\n1,10,20,30\n2,-5,0,30\n3,0,0,30\n";
  std::ofstream(dir + "/est.csv") << "sensor_id,x,y,z,sigma_x,sigma_y,crlb_x,crlb_y\n"
                                  << "1,13,24,30,3,4,6,8\n2,-5,0,30,1,1,1,1\n";
  const auto [rc, out] = Evaluate({"--estimate", dir + "/est.csv", "--truth", dir + "/truth.csv"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("sensors 2 scored, 0 not in the truth, 1 true sensors without an estimate"), std::string::npos)
      << out;
  // RMSE sqrt((25 + 0) / 2) = 3.536 m; NEES (1 + 1 + 0 + 0) / 2 = 1; bound RMS sqrt((100 + 2) / 2) = 7.141 m.
  EXPECT_NE(out.find("RMSE 3.536 m, max 5 m"), std::string::npos) << out;
  EXPECT_NE(out.find("Cramer-Rao bound (RMS over sensors): 7.141 m"), std::string::npos) << out;
  EXPECT_NE(out.find("mean NEES (diagonal sigmas, 2 dof): 1 over 2 sensors; both axes within 2 sigma: 2 of 2"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("     1   5.0000   5.0000         1.00  10.0000         0.50"), std::string::npos) << out;
  // With magnav localize's cov_xy column the NEES uses the full 2x2: sensor 1 P = [9 6; 6 16], e = (3, 4):
  // (16·9 − 2·6·12 + 9·16) / (144 − 36) = 1.333; mean over the two sensors 0.667.
  std::ofstream(dir + "/est_xy.csv") << "sensor_id,x,y,z,sigma_x,sigma_y,crlb_x,crlb_y,cov_xy\n"
                                     << "1,13,24,30,3,4,6,8,6\n2,-5,0,30,1,1,1,1,0\n";
  const auto [xrc, xout] = Evaluate({"--estimate", dir + "/est_xy.csv", "--truth", dir + "/truth.csv"});
  ASSERT_EQ(xrc, 0) << xout;
  EXPECT_NE(xout.find("mean NEES (full 2x2 covariance, 2 dof): 0.667 over 2 sensors"), std::string::npos) << xout;

  const auto [lrc, lout] = testing::RunCommand(
      {kMagnav, "localize", "--measurements", testing::ReferencePath("localize_measurements.csv"), "--deployment",
       testing::ReferencePath("localize_deployment.csv"), "--gnss", testing::ReferencePath("localize_gnss_full.csv"),
       "--method", "ekf", "--output", dir + "/ekf.csv"},
      {}, std::chrono::seconds(120));
  ASSERT_EQ(lrc, 0) << lout;
  const auto [erc, eout] =
      Evaluate({"--estimate", dir + "/ekf.csv", "--truth", testing::ReferencePath("localize_truth_sensors.csv")});
  ASSERT_EQ(erc, 0) << eout;
  EXPECT_NE(eout.find("sensors 8 scored"), std::string::npos) << eout;
  const std::size_t at = eout.find("RMSE ");
  ASSERT_NE(at, std::string::npos) << eout;
  const double rmse = std::stod(eout.substr(at + 5));
  EXPECT_NEAR(rmse, 0.111, 0.111 * 0.5) << eout;  // docs/ACCURACY.md, Localizer: EKF 0.111 m (a 2x regression fails)
}

// --nees (scripts/calibration; core/nees.h), worked by hand: 2 runs, 2 dof.
// converging (epoch 0): NEES 1 and 3, ANEES 2 (accepted), the run average 2
// inside chi2(4)'s [0.4844, 11.143] / 2 = [0.242, 5.572]; RMS sqrt((4 + 0) / 2).
// converged (epoch 1): 2 and 30, ANEES 16 (> 4: not accepted), 16 outside;
// RMS sqrt((1 + 9) / 2). all: ANEES 9, 1 of 2 epochs inside, RMS sqrt(14 / 4).
TEST(EvaluateCli, NeesOverRunsPerRegime) {
  const std::string dir = testing::TempDir();
  std::ofstream(dir + "/nees.csv") << "run,epoch,regime,nees,error_sq\n"
                                   << "1,0,converging,1,4\n2,0,converging,3,0\n"
                                   << "1,1,converged,2,1\n2,1,converged,30,9\n";
  const auto [rc, out] = Evaluate({"--nees", dir + "/nees.csv", "--dof", "2"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("regime converging: runs 2, epochs 1, values 2, ANEES 2 (accepted), inside 95 % 1 of 1 epochs "
                     "(100.0 %), RMS 1.414"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("regime converged: runs 2, epochs 1, values 2, ANEES 16 (NOT accepted), inside 95 % 0 of 1 "
                     "epochs (0.0 %), RMS 2.236"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("regime all: runs 2, epochs 2, values 4, ANEES 9 (NOT accepted), inside 95 % 1 of 2 epochs "
                     "(50.0 %), RMS 1.871"),
            std::string::npos)
      << out;
  // A singular covariance ("inf") is counted, not dropped; a negative NEES, a missing --dof or an
  // estimate beside --nees: exit 2.
  std::ofstream(dir + "/inf.csv") << "run,epoch,regime,nees\n1,0,fix,inf\n2,0,fix,1\n";
  const auto [irc, iout] = Evaluate({"--nees", dir + "/inf.csv", "--dof", "3"});
  ASSERT_EQ(irc, 0) << iout;
  EXPECT_NE(iout.find("ANEES inf (NOT accepted)"), std::string::npos) << iout;
  std::ofstream(dir + "/neg.csv") << "run,epoch,regime,nees\n1,0,fix,-1\n";
  EXPECT_EQ(Evaluate({"--nees", dir + "/neg.csv", "--dof", "3"}).first, 2);
  EXPECT_EQ(Evaluate({"--nees", dir + "/nees.csv"}).first, 2);
  EXPECT_EQ(Evaluate({"--nees", dir + "/nees.csv", "--dof", "2", "--estimate", dir + "/nees.csv"}).first, 2);
  EXPECT_EQ(Evaluate({"--estimate", dir + "/nees.csv"}).first, 2);
}

}  // namespace
}  // namespace magnav
