// `magnav track` end to end: the binary's track file holds exactly what the
// library computes (columns, one row per epoch, moment line, σ columns), both
// solvers give the same track, and bad input exits 2 naming the place.
#include <cmath>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "magnav/tracker/tracker.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::tracker {
namespace {

const std::string kMagnav = MAGNAV_BIN;

std::pair<int, std::string> Track(const std::vector<std::string>& args) {
  std::vector<std::string> argv = {kMagnav, "track"};
  argv.insert(argv.end(), args.begin(), args.end());
  return testing::RunCommand(argv);
}

TEST(TrackCli, BatchFileEqualsTheLibraryAndCarriesTheMoment) {
  const std::string dir = testing::TempDir();
  const std::string input = testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv");
  const auto [rc, out] = Track({"--input", input, "--output", dir + "/track.csv"});
  ASSERT_EQ(rc, 0) << out;

  const GradiometerFile f = ReadGradiometerFile(input);
  const TrackerOptions opt;
  const TrackEstimate lib = SolveBatch(GroupEpochs(f.samples, opt.epoch_tolerance_s), *f.B0, opt);
  const CsvTable t = CsvTable::Read(dir + "/track.csv");
  const std::vector<std::string> header = {"t", "x", "y", "z", "vx", "vy", "heading", "sigma_x", "sigma_y", "sigma_z"};
  ASSERT_EQ(t.header(), header);
  ASSERT_EQ(t.num_rows(), lib.epochs.size());
  ASSERT_EQ(t.num_rows(), 2001u);  // 200 s at 10 Hz
  for (std::size_t k = 0; k < t.num_rows(); ++k) {
    const EpochEstimate& e = lib.epochs[k];
    // The file is written with round-trip precision: the library's numbers exactly.
    EXPECT_EQ(t.number(k, t.column("t")), e.t_s);
    EXPECT_EQ(t.number(k, t.column("x")), e.p_VinW.x());
    EXPECT_EQ(t.number(k, t.column("y")), e.p_VinW.y());
    EXPECT_EQ(t.number(k, t.column("z")), e.p_VinW.z());
    EXPECT_EQ(t.number(k, t.column("vx")), e.v_VinW().x());
    EXPECT_EQ(t.number(k, t.column("heading")), e.heading_rad);
    EXPECT_EQ(t.number(k, t.column("sigma_z")), std::sqrt(e.cov_state(2, 2)));
  }
  const auto m = t.param_vec3("moment_body_Am2");
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(*m, lib.m_B_Am2);
  // Within 2 % of the moment the reference file was generated with.
  EXPECT_LT((*m - *f.moment_body).norm() / f.moment_body->norm(), 0.02);
}

TEST(TrackCli, CeresSolverGivesTheSameTrack) {
  const std::string dir = testing::TempDir();
  const std::string input = testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv");
  ASSERT_EQ(Track({"--input", input, "--output", dir + "/chain.csv"}).first, 0);
  const auto [rc, out] = Track({"--input", input, "--solver", "ceres", "--output", dir + "/ceres.csv"});
  ASSERT_EQ(rc, 0) << out;
  const CsvTable a = CsvTable::Read(dir + "/chain.csv"), b = CsvTable::Read(dir + "/ceres.csv");
  ASSERT_EQ(a.num_rows(), b.num_rows());
  for (std::size_t k = 0; k < a.num_rows(); ++k) {
    double d2 = 0.0, s2 = 0.0;
    for (const char* c : {"x", "y", "z"}) {
      d2 += std::pow(a.number(k, a.column(c)) - b.number(k, b.column(c)), 2);
      s2 += std::pow(b.number(k, b.column(std::string("sigma_") + c)), 2);
    }
    EXPECT_LT(std::sqrt(d2), 0.01 * std::sqrt(s2)) << "row " << k;
  }
}

TEST(TrackCli, WindowModeWritesOneRowPerEstimatedEpoch) {
  const std::string dir = testing::TempDir();
  const auto [rc, out] = Track({"--input", testing::ReferencePath("track_pass_ship_4sensor_fluxgate.csv"), "--mode",
                                "window", "--window", "10", "--output", dir + "/w.csv"});
  ASSERT_EQ(rc, 0) << out;
  const CsvTable t = CsvTable::Read(dir + "/w.csv");
  EXPECT_EQ(t.params().at("mode"), "window");
  ASSERT_GT(t.num_rows(), 1000u);  // the track starts once enough strong fixes exist
  for (std::size_t k = 1; k < t.num_rows(); ++k) {
    EXPECT_GT(t.number(k, t.column("t")), t.number(k - 1, t.column("t")));
    EXPECT_GT(t.number(k, t.column("sigma_x")), 0.0);
  }
}

TEST(TrackCli, BadInputExitsTwoAndNamesThePlace) {
  const std::string dir = testing::TempDir();
  const std::string cols = "t,sensor_id,sensor_x,sensor_y,sensor_z,B_x,B_y,B_z,T00,T01,T02,T10,T11,T12,T20,T21,T22\n";
  std::ofstream(dir + "/no_b0.csv") << cols << "0,0,0,0,0,1e-6,0,0,0,0,0,0,0,0,0,0,0\n";
  auto [rc, out] = Track({"--input", dir + "/no_b0.csv", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find(dir + "/no_b0.csv: no background field"), std::string::npos) << out;

  std::ofstream(dir + "/back.csv") << "# B0_T: 2e-05, 1e-06, 4.5e-05\n"
                                   << cols << "0.2,0,0,0,0,1e-6,0,0,0,0,0,0,0,0,0,0,0\n"
                                   << "0.1,0,0,0,0,1e-6,0,0,0,0,0,0,0,0,0,0,0\n";
  std::tie(rc, out) = Track({"--input", dir + "/back.csv", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find(dir + "/back.csv:4: column 't': time goes backwards"), std::string::npos) << out;

  std::tie(rc, out) = Track({"--input", testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"), "--solver",
                             "fast", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("--solver"), std::string::npos) << out;

  // Far below the noise everywhere: no track, said so, no output claimed.
  std::ofstream(dir + "/quiet.csv") << "# B0_T: 2e-05, 1e-06, 4.5e-05\n" << cols
                                    << "0,0,0,0,0,2e-05,1e-06,4.5e-05,0,0,0,0,0,0,0,0,0\n";
  std::tie(rc, out) = Track({"--input", dir + "/quiet.csv", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("no track"), std::string::npos) << out;
}

}  // namespace
}  // namespace magnav::tracker
