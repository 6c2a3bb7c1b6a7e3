// `magnav localize` end to end: the output file holds exactly the library's
// estimates (columns, one row per sensor, summary line), the moment flag
// replaces the file's line, and bad input exits 2 naming file, line and field.
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "localize_data.h"
#include "magnav/core/csv.h"
#include "magnav/localizer/batch.h"
#include "magnav/localizer/ekf.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::localizer {
namespace {

const std::string kMagnav = MAGNAV_BIN;

std::pair<int, std::string> Localize(const std::vector<std::string>& args) {
  std::vector<std::string> argv = {kMagnav, "localize"};
  argv.insert(argv.end(), args.begin(), args.end());
  return testing::RunCommand(argv, {}, std::chrono::seconds(120));
}

std::vector<std::string> ReferenceArgs(const std::string& method, const std::string& out) {
  return {"--measurements", testing::ReferencePath("localize_measurements.csv"),
          "--deployment",   testing::ReferencePath("localize_deployment.csv"),
          "--gnss",         testing::ReferencePath("localize_gnss_full.csv"),
          "--method",       method,
          "--output",       out};
}

void ExpectFileEqualsLibrary(const std::string& path, const Localization& lib) {
  const CsvTable t = CsvTable::Read(path);
  const std::vector<std::string> header = {"sensor_id", "x", "y", "z", "sigma_x", "sigma_y", "crlb_x", "crlb_y", "cov_xy"};
  ASSERT_EQ(t.header(), header);
  ASSERT_EQ(t.num_rows(), lib.sensors.size());
  ASSERT_EQ(t.num_rows(), 8u);
  for (std::size_t j = 0; j < t.num_rows(); ++j) {
    const SensorEstimate& e = lib.sensors[j];
    EXPECT_EQ(t.uint32(j, t.column("sensor_id")), e.sensor_id);
    EXPECT_EQ(t.number(j, t.column("x")), e.p_SinW_m.x());
    EXPECT_EQ(t.number(j, t.column("y")), e.p_SinW_m.y());
    EXPECT_EQ(t.number(j, t.column("z")), e.p_SinW_m.z());
    EXPECT_EQ(t.number(j, t.column("sigma_x")), std::sqrt(e.cov_xy_m2(0, 0)));
    EXPECT_EQ(t.number(j, t.column("sigma_y")), std::sqrt(e.cov_xy_m2(1, 1)));
    EXPECT_EQ(t.number(j, t.column("crlb_x")), std::sqrt(e.crlb_joint_m2(0, 0)));
    EXPECT_EQ(t.number(j, t.column("crlb_y")), std::sqrt(e.crlb_joint_m2(1, 1)));
    EXPECT_EQ(t.number(j, t.column("cov_xy")), e.cov_xy_m2(1, 0));
  }
  ASSERT_TRUE(t.has_param("status"));
  EXPECT_EQ(t.params().at("status"), lib.summary.Status());
  ASSERT_TRUE(t.has_param("summary"));
  EXPECT_NE(t.params().at("summary").find("method " + lib.summary.method), std::string::npos);
  EXPECT_NE(t.params().at("summary").find("iterations"), std::string::npos);
}

TEST(LocalizeCli, EkfAndBatchFilesEqualTheLibrary) {
  const std::string dir = testing::TempDir();
  const PassFile f = test::ReferencePass();
  const LocalizerOptions opt;  // σ_B = the file's 1e-9
  for (const std::string method : {"ekf", "ekf-bounded", "batch"}) {
    SCOPED_TRACE(method);
    const auto [rc, out] = Localize(ReferenceArgs(method, dir + "/" + method + ".csv"));
    ASSERT_EQ(rc, 0) << out;
    const Localization lib = method == "ekf"           ? RunEkf(f.pass, opt)
                             : method == "ekf-bounded" ? RunEkfBounded(f.pass, opt)
                                                       : SolveBatch(f.pass, opt);
    ExpectFileEqualsLibrary(dir + "/" + method + ".csv", lib);
    // --check-batch (default 1): the EKF's estimate was taken against the
    // smoother's (docs/ACCURACY.md "Trust: honest status"); a clean pass.
    const CsvTable t = CsvTable::Read(dir + "/" + method + ".csv");
    EXPECT_EQ(t.params().at("summary").find("against the batch: NEES") != std::string::npos, method != "batch")
        << t.params().at("summary");
  }
}

TEST(LocalizeCli, MomentFlagReplacesTheFileLine) {
  const std::string dir = testing::TempDir();
  auto args = ReferenceArgs("ekf", dir + "/m.csv");
  args.insert(args.end(), {"--moment-body", "15000,1000,5000"});  // half the true moment
  args.insert(args.end(), {"--check-batch", "0"});                  // the EKF alone
  const auto [rc, out] = Localize(args);
  ASSERT_EQ(rc, 0) << out;
  const CsvTable t = CsvTable::Read(dir + "/m.csv");
  EXPECT_EQ(t.params().at("summary").find("against the batch"), std::string::npos) << t.params().at("summary");
  EXPECT_EQ(t.params().at("moment_body_Am2"), "15000, 1000, 5000");
  // The wrong moment gives a visibly different answer than the true one.
  const PassFile f = test::ReferencePass();
  const Localization lib = RunEkf(f.pass, LocalizerOptions{});
  double diff = 0.0;
  for (std::size_t j = 0; j < 8; ++j) diff += std::abs(t.number(j, t.column("x")) - lib.sensors[j].p_SinW_m.x());
  EXPECT_GT(diff, 0.1);
}

std::string Write(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

TEST(LocalizeCli, BadInputExitsTwoNamingFileLineAndField) {
  const std::string dir = testing::TempDir();
  const std::string head =
      "# moment_body_Am2: 30000, 2000, 10000\n# vessel_z_m: 0\n# sigma_B_T: 1e-9\nt,sensor_id,B_x,B_y,B_z\n";
  const std::string good_rows = "0,0,1e-9,0,0\n0,1,1e-9,0,0\n";
  const std::string deploy = Write(dir + "/d.csv", "sensor_id,x,y,z,sigma_xy\n0,1,2,30,15\n1,5,6,30,15\n");
  const std::string gnss = Write(dir + "/g.csv", "t,x,y,sigma\n0,0,0,3\n1,2,0,3\n2,4,0,3\n");
  struct Case {
    std::string name, measurements, expect;
    std::vector<std::string> extra;
  };
  const std::vector<Case> cases = {
      {"unknown sensor", head + good_rows + "0,9,1e-9,0,0\n", "m.csv:7: column 'sensor_id': sensor 9 is not in", {}},
      {"time backwards", head + "1,0,1e-9,0,0\n1,1,1e-9,0,0\n0.5,0,1e-9,0,0\n", "m.csv:7: column 't': time goes backwards", {}},
      {"missing moment", "# vessel_z_m: 0\n# sigma_B_T: 1e-9\nt,sensor_id,B_x,B_y,B_z\n" + good_rows,
       "m.csv: no vessel moment: give --moment-body", {}},
      {"nan", head + "0,0,1e-9,0,NaN\n0,1,1e-9,0,0\n", "m.csv:5: column 'B_z'", {}},
      {"sensor never seen", head + "0,0,1e-9,0,0\n", "d.csv:3: column 'sensor_id': sensor 1 has no sample", {}},
      {"missing noise level", "# moment_body_Am2: 1, 2, 3\n# vessel_z_m: 0\nt,sensor_id,B_x,B_y,B_z\n" + good_rows,
       "no magnetometer noise level", {}},
      {"bad method", head + good_rows, "--method", {"--method", "kalman"}},
      // A broken time as the last row (time does not go backwards there): before, exit 0 with every number -nan.
      {"time 1e300", head + good_rows + "1e300,0,1e-9,0,0\n", "m.csv:7: column 't': 1e+300 s is out of range", {}},
      {"time jump", head + good_rows + "7200,0,1e-9,0,0\n", "m.csv:7: column 't': time jumps 7200 s ahead", {}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string m = Write(dir + "/m.csv", c.measurements);
    std::vector<std::string> args = {"--measurements", m,      "--deployment", deploy, "--gnss",
                                     gnss,             "--output", dir + "/out.csv"};
    if (c.extra.empty()) {
      args.insert(args.end(), {"--method", "ekf"});
    } else {
      args.insert(args.end(), c.extra.begin(), c.extra.end());
    }
    const auto [rc, out] = Localize(args);
    EXPECT_EQ(rc, 2) << out;
    EXPECT_NE(out.find(c.expect), std::string::npos) << out;
  }
  // A GNSS fix an hour beyond the measurements' span.
  {
    const std::string m = Write(dir + "/m.csv", head + good_rows);
    const std::string g = Write(dir + "/g2.csv", "t,x,y,sigma\n0,0,0,3\n1,2,0,3\n1800,4,0,3\n3602,4,0,3\n");
    const auto [rc, out] = Localize({"--measurements", m, "--deployment", deploy, "--gnss", g, "--method", "ekf",
                                     "--output", dir + "/out.csv"});
    EXPECT_EQ(rc, 2) << out;
    EXPECT_NE(out.find("g2.csv:5: column 't': 3602 s is more than 3600 s outside the measurements' time span"),
              std::string::npos)
        << out;
  }
  // Without GNSS the vessel's start is unknown: refused, not guessed.
  const std::string m = Write(dir + "/m.csv", head + good_rows);
  const auto [rc, out] = Localize({"--measurements", m, "--deployment", deploy, "--method", "ekf", "--output",
                                   dir + "/out.csv"});
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("start is unknown"), std::string::npos) << out;
  const auto [rc2, out2] = Localize({"--measurements", m, "--deployment", deploy, "--method", "ekf", "--output",
                                     dir + "/out.csv", "--vessel-start", "1,2"});
  EXPECT_EQ(rc2, 2) << out2;
  EXPECT_NE(out2.find("--vessel-start: expected X,Y,SPEED,HEADING"), std::string::npos) << out2;
}

TEST(LocalizeCli, WithoutGnssAGivenStartIsUsed) {
  const std::string dir = testing::TempDir();
  const auto [rc, out] = Localize({"--measurements", testing::ReferencePath("localize_measurements.csv"),
                                   "--deployment", testing::ReferencePath("localize_deployment.csv"), "--vessel-start",
                                   "-125,-95,2,0.1", "--method", "ekf", "--output", dir + "/s.csv"});
  ASSERT_EQ(rc, 0) << out;
  PassFile f = test::ReferencePass("");
  LocalizerOptions opt;
  VesselVector start;
  start << -125.0, -95.0, 2.0, 0.1, 0.0;
  opt.vessel_start = start;
  ExpectFileEqualsLibrary(dir + "/s.csv", RunEkf(f.pass, opt));
}

}  // namespace
}  // namespace magnav::localizer
