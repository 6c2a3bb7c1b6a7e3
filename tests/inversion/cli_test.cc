// `magnav invert` end to end: runs the built binary on small files.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/dipole.h"
#include "test_data.h"

namespace magnav {
namespace {

struct RunResult {
  int exit_code = -1;
  std::string output;  // stdout + stderr
};

RunResult RunMagnav(const std::string& args) {
  const std::string cmd = std::string(MAGNAV_BINARY) + " " + args + " 2>&1";
  RunResult r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  std::size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// Three cases with known dipoles, written with the file column names.
std::string WriteCases(const std::string& dir, bool corrupt) {
  const std::string path = dir + (corrupt ? "/bad.csv" : "/cases.csv");
  std::ofstream out(path);
  out << "# a small test file\ncase_id,sensor_x,sensor_y,sensor_z,B_x,B_y,B_z,T00,T01,T02,T10,T11,T12,T20,T21,T22\n";
  const Vec3 sensors[3] = {{0, 0, 0}, {10, -5, 2}, {-3, 7, 1}};
  const Vec3 dipoles[3] = {{3, 4, -5}, {12, -1, -6}, {-8, 9, -4}};
  for (int k = 0; k < 3; ++k) {
    Vec3 B;
    Mat3 T;
    DipoleBT(sensors[k] - dipoles[k], Vec3(2000, 300, 800), &B, &T);
    out << k << "," << FormatNumber(sensors[k].x()) << "," << FormatNumber(sensors[k].y()) << ","
        << FormatNumber(sensors[k].z());
    for (int i = 0; i < 3; ++i) out << "," << FormatNumber(B[i]);
    for (int i = 0; i < 9; ++i) {
      if (corrupt && k == 1 && i == 4) {
        out << ",abc";
      } else {
        out << "," << FormatNumber(T(i / 3, i % 3));
      }
    }
    out << "\n";
  }
  return path;
}

TEST(InvertCli, WritesOneRowPerCaseWithIdColumns) {
  const std::string dir = testing::TempDir();
  const std::string in = WriteCases(dir, false);
  for (const char* method : {"ted", "ted-egt", "egt"}) {
    const std::string out = dir + "/out_" + method + ".csv";
    const RunResult r = RunMagnav("invert --input " + in + " --b0 0,0,0 --method " + method + " --output " + out);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const CsvTable t = CsvTable::Read(out);
    const std::vector<std::string> expected = {"case_id", "dipole_x", "dipole_y", "dipole_z", "valid",
                                               "reason",  "cond",     "sigma_x",  "sigma_y",  "sigma_z",
                                               "cov_xx",  "cov_xy",   "cov_xz",   "cov_yy",   "cov_yz",
                                               "cov_zz"};
    EXPECT_EQ(t.header(), expected);
    ASSERT_EQ(t.num_rows(), 3u);
    const Vec3 dipoles[3] = {{3, 4, -5}, {12, -1, -6}, {-8, 9, -4}};
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_EQ(t.integer(i, 0), static_cast<long long>(i));
      // No sigmas in the file: only the input-consistency gates and cond apply.
      ASSERT_EQ(t.text(i, t.column("valid")), "1") << method << " row " << i << ": " << t.text(i, 5);
      EXPECT_EQ(t.text(i, t.column("reason")), "");
      const Vec3 p(t.number(i, 1), t.number(i, 2), t.number(i, 3));
      EXPECT_LT((p - dipoles[i]).norm(), 1e-9) << method << " row " << i;
    }
  }
}

TEST(InvertCli, TrackFileGivesTimeAndSensorColumnsForMc) {
  const std::string dir = testing::TempDir();
  const std::string out = dir + "/mc.csv";
  const std::string in = testing::ReferencePath("track_pass_ship_1sensor_squid.csv");
  const RunResult r = RunMagnav("invert --input " + in + " --method mc --output " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const CsvTable t = CsvTable::Read(out);
  ASSERT_EQ(t.header().size(), 17u);  // t, sensor_id, dipole_*, valid, reason, cond, sigma_*, cov_*
  EXPECT_EQ(t.header()[0], "t");
  EXPECT_EQ(t.header()[1], "sensor_id");
  EXPECT_EQ(t.num_rows(), 2001u);
  // The filter starts once 5 accepted fixes span 0.5 s; rows before say why.
  EXPECT_EQ(t.text(0, t.column("valid")), "0");
  EXPECT_EQ(t.text(0, t.column("reason")), "not_initialized");
  EXPECT_EQ(t.text(0, t.column("dipole_x")), "");
  EXPECT_EQ(t.text(100, t.column("valid")), "1");
  EXPECT_EQ(t.text(100, t.column("reason")), "");
  EXPECT_EQ(t.param_vec3("moment_body_Am2"), Eigen::Vector3d(500000, 50000, 200000));
}

TEST(InvertCli, MalformedNumberNamesFileLineAndColumn) {
  const std::string dir = testing::TempDir();
  const std::string in = WriteCases(dir, true);
  const RunResult r = RunMagnav("invert --input " + in + " --b0 0,0,0 --method ted --output " + dir + "/o.csv");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(in + ":4"), std::string::npos) << r.output;  // line 4: the second data row
  EXPECT_NE(r.output.find("T11"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("abc"), std::string::npos) << r.output;
}

TEST(InvertCli, MissingInputsAreErrorsNotCrashes) {
  const std::string dir = testing::TempDir();
  const std::string in = WriteCases(dir, false);
  RunResult r = RunMagnav("invert --input " + in + " --b0 0,0,0 --method mc --output " + dir + "/o.csv");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--moment-body"), std::string::npos) << r.output;
  r = RunMagnav("invert --input " + dir + "/does_not_exist.csv --method ted --output " + dir + "/o.csv");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("does_not_exist.csv"), std::string::npos) << r.output;
  r = RunMagnav("invert --input " + in + " --method ted --b0 1,2 --output " + dir + "/o.csv");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--b0"), std::string::npos) << r.output;
  r = RunMagnav("invert --input " + in + " --method magic --output " + dir + "/o.csv");
  EXPECT_NE(r.exit_code, 0);
  // No B0 in the file and no --b0: refused, never B0 = 0.
  r = RunMagnav("invert --input " + in + " --method ted --output " + dir + "/o.csv");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("no regional field"), std::string::npos) << r.output;
  // A valid run with every option.
  r = RunMagnav("invert --input " + in + " --method mc --moment-body 2000,300,800 --b0 0,0,0 --sigma-b 1e-9 " +
          "--sigma-t 1.4e-9 --particles 100 --seed 3 --output " + dir + "/o.csv");
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

TEST(InvertCli, DegenerateRowsAreReportedNotFatal) {
  const std::string dir = testing::TempDir();
  const std::string in = dir + "/degenerate.csv";
  std::ofstream(in) << "case_id,sensor_x,sensor_y,sensor_z,B_x,B_y,B_z,T00,T01,T02,T10,T11,T12,T20,T21,T22\n"
                    << "0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n"               // all-zero tensor
                    << "1,0,0,0,1e-9,0,0,1e-9,0,0,0,-1e-9,0,0,0,0\n"     // singular tensor
                    << "2,0,0,0,1e-9,0,0,1e-9,5e-10,0,0,-1e-9,0,0,0,0\n";  // asymmetric
  const RunResult r = RunMagnav("invert --input " + in + " --b0 0,0,0 --method ted --output " + dir + "/o.csv");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const CsvTable t = CsvTable::Read(dir + "/o.csv");
  ASSERT_EQ(t.num_rows(), 3u);
  const std::size_t valid = t.column("valid"), reason = t.column("reason"), cond = t.column("cond");
  EXPECT_EQ(t.text(0, valid), "0");
  EXPECT_EQ(t.text(0, reason), "zero_tensor");
  EXPECT_EQ(t.text(0, cond), "");
  EXPECT_EQ(t.text(1, reason), "ill_conditioned");
  EXPECT_EQ(t.text(1, cond), "inf");
  EXPECT_EQ(t.text(2, reason), "asymmetric");
}

// The gate flags on the reference AUV fluxgate pass (docs/ACCURACY.md): the
// defaults (SNR ≥ 20, σ_3d ≤ 0.4 m: 156 accepted fixes), the former defaults
// (--min-snr 100 --max-relative-sigma 0.015 --max-position-sigma 0: 93), the
// absolute 5 cm gate (39), a too tight relative limit, a negative one.
TEST(InvertCli, UncertaintyGateFlags) {
  const std::string dir = testing::TempDir();
  const std::string in = testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv");
  auto accepted = [&](const std::string& flags) {
    const RunResult r = RunMagnav("invert --input " + in + " --method ted-egt " + flags + " --output " + dir + "/g.csv");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    const CsvTable t = CsvTable::Read(dir + "/g.csv");
    int n = 0, uncertain = 0;
    for (std::size_t i = 0; i < t.num_rows(); ++i) {
      n += t.text(i, t.column("valid")) == "1";
      uncertain += t.text(i, t.column("reason")) == "uncertain";
    }
    return std::pair{n, uncertain};
  };
  EXPECT_EQ(accepted("").first, 156);
  EXPECT_EQ(accepted("--min-snr 100 --max-relative-sigma 0.015 --max-position-sigma 0").first, 93);
  EXPECT_EQ(accepted("--max-relative-sigma 0 --max-position-sigma 0.05").first, 39);
  const auto [n, uncertain] = accepted("--max-relative-sigma 0.001");
  EXPECT_EQ(n, 0);
  EXPECT_GT(uncertain, 156);
  const RunResult r = RunMagnav("invert --input " + in + " --method ted-egt --max-relative-sigma -1 --output " + dir +
                                "/g.csv");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--max-relative-sigma"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace magnav
