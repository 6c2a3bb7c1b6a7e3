// `magnav match` end to end: the output file holds exactly the library's
// matched path (k,lat,lon and the summary line), and bad input exits 2 naming
// the file, line and field, without leaving an output or temporary file.
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/mapmatch/match.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

const std::string kMagnav = MAGNAV_BIN;

std::pair<int, std::string> RunMatch(const std::vector<std::string>& args) {
  std::vector<std::string> argv = {kMagnav, "match"};
  argv.insert(argv.end(), args.begin(), args.end());
  return testing::RunCommand(argv, {}, std::chrono::seconds(60));
}

std::vector<std::string> Args(const std::string& map, const std::string& column, const std::string& path,
                              const std::string& meas, const std::string& method, const std::string& out) {
  return {"--map", map, "--value-column", column, "--path", path, "--meas-column", meas, "--method", method,
          "--output", out};
}

TEST(MatchCli, OutputIsTheLibrarysMatchedPath) {
  const std::string dir = testing::TempDir();
  const std::string map = testing::ReferencePath("map_crustal_anomaly.csv");
  const std::string path = testing::ReferencePath("mappath_crustal_off0p01deg_noise0p5nT.csv");
  const GeoGrid grid = ReadGeoGridCsv(map, {"anomaly_nT"});
  const MatchPath p = ReadMatchPath(path, "meas_nT");
  for (const std::string method : {"fast-msd", "icp", "msd"}) {
    const std::string out = dir + "/" + method + ".csv";
    std::vector<std::string> args = Args(map, "anomaly_nT", path, "meas_nT", method, out);
    args.insert(args.end(), {"--search-window", "0.15"});
    const auto [code, text] = RunMatch(args);
    ASSERT_EQ(code, 0) << text;
    MatchOptions o;
    o.correlation.search_window_deg = 0.15;
    o.fast_msd.search_window_deg = 0.15;
    const MatchResult lib = Match(*ParseMethod(method), grid, 0, p, o);
    const CsvTable t = CsvTable::Read(out);
    // fast-msd publishes its covariance (deg², fast_msd.h) per point; the others none.
    const bool cov = method == std::string("fast-msd");
    ASSERT_EQ(t.header(), cov ? (std::vector<std::string>{"k", "lat", "lon", "on_map", "cov_lat_lat", "cov_lat_lon",
                                                          "cov_lon_lon"})
                              : (std::vector<std::string>{"k", "lat", "lon", "on_map"}));
    ASSERT_EQ(t.num_rows(), p.size());
    for (std::size_t r = 0; r < t.num_rows(); ++r) {
      EXPECT_EQ(t.integer(r, 0), p.k[r]);
      EXPECT_EQ(t.number(r, 1), lib.lat_deg[r]);
      EXPECT_EQ(t.number(r, 2), lib.lon_deg[r]);
      EXPECT_EQ(t.integer(r, 3), grid.Contains(lib.lat_deg[r], lib.lon_deg[r]) ? 1 : 0);
      if (cov) {
        EXPECT_EQ(t.number(r, 4), lib.cov_lat_lat[r]);
        EXPECT_EQ(t.number(r, 5), lib.cov_lat_lon[r]);
        EXPECT_EQ(t.number(r, 6), lib.cov_lon_lon[r]);
        EXPECT_GT(t.number(r, 4), 0.0);
        EXPECT_GT(t.number(r, 4) * t.number(r, 6), t.number(r, 5) * t.number(r, 5));
      }
    }
    ASSERT_TRUE(t.has_param("summary"));
    EXPECT_EQ(t.params().at("summary"), lib.BriefReport());
    EXPECT_NE(t.params().at("summary").find("method " + method), std::string::npos);
    EXPECT_NE(t.params().at("summary").find("iterations"), std::string::npos);
  }
}

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

TEST(MatchCli, BadInputExits2NamingFileLineAndField) {
  const std::string dir = testing::TempDir();
  const std::string map = testing::ReferencePath("map_wmm_0p5deg.csv");
  const std::string good_path = testing::ReferencePath("mappath_wmm_0p5deg_noise0nT.csv");
  const std::string out = dir + "/out.csv";
  struct Case {
    std::string name;
    std::vector<std::string> args;
    std::string expected;
  };
  WriteText(dir + "/text.csv", "k,ins_lat,ins_lon,meas_nT\n0,15,65,40000\n1,15.1,abc,40010\n");
  WriteText(dir + "/nan.csv", "k,ins_lat,ins_lon,meas_nT\n0,15,65,40000\n1,15.1,65.1,nan\n");
  WriteText(dir + "/short.csv", "k,ins_lat,ins_lon,meas_nT\n0,15,65,40000\n1,15.1,65.1\n");
  WriteText(dir + "/hole.csv", "lat,lon,F_nT\n10,60,1\n10,61,2\n11,60,3\n");
  WriteText(dir + "/irregular.csv", "lat,lon,F_nT\n10,60,1\n10,61,2\n11,60,3\n11,61,4\n13,60,5\n13,61,6\n");
  const std::vector<Case> cases = {
      {"missing measurement column", Args(map, "F_nT", good_path, "meas_Y_nT", "icp", out),
       "missing column 'meas_Y_nT'"},
      {"missing map layer", Args(map, "G_nT", good_path, "meas_nT", "icp", out), "missing column 'G_nT'"},
      {"text in a number", Args(map, "F_nT", dir + "/text.csv", "meas_nT", "icp", out), "text.csv:3"},
      {"NaN measurement", Args(map, "F_nT", dir + "/nan.csv", "meas_nT", "icp", out), "nan.csv:3"},
      {"short row", Args(map, "F_nT", dir + "/short.csv", "meas_nT", "icp", out), "short.csv:3"},
      {"map with a hole", Args(dir + "/hole.csv", "F_nT", good_path, "meas_nT", "icp", out), "hole in the map"},
      {"irregular map", Args(dir + "/irregular.csv", "F_nT", good_path, "meas_nT", "icp", out),
       "irregular latitude spacing"},
      {"unknown method", Args(map, "F_nT", good_path, "meas_nT", "sift", out), "--method"},
      {"correlation without a window", Args(map, "F_nT", good_path, "meas_nT", "mad", out), "--search-window"},
      {"missing file", Args(dir + "/none.csv", "F_nT", good_path, "meas_nT", "icp", out), "none.csv"},
  };
  for (const Case& c : cases) {
    const auto [code, text] = RunMatch(c.args);
    EXPECT_EQ(code, 2) << c.name << ": " << text;
    EXPECT_NE(text.find(c.expected), std::string::npos) << c.name << ": " << text;
    EXPECT_FALSE(std::filesystem::exists(out)) << c.name;
  }
  // Nothing but the inputs left in the directory (no temporary output).
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.path().filename().string().find(".tmp") != std::string::npos;
  EXPECT_EQ(files, 0);
}

TEST(MatchCli, ReadsAnNgdcTextMapLikeItsCsv) {
  // The WMM 0.5° F layer rewritten as "lon lat value" lines gives the same match.
  const std::string dir = testing::TempDir();
  const CsvTable m = CsvTable::Read(testing::ReferencePath("map_wmm_0p5deg.csv"));
  {
    std::ofstream xyz(dir + "/wmm.xyz");
    xyz << "# lon lat F_nT\n";
    for (std::size_t r = 0; r < m.num_rows(); ++r) {
      xyz << m.text(r, m.column("lon")) << " " << m.text(r, m.column("lat")) << " " << m.text(r, m.column("F_nT"))
          << "\n";
    }
  }
  const std::string path = testing::ReferencePath("mappath_wmm_0p5deg_noise0nT.csv");
  ASSERT_EQ(RunMatch(Args(dir + "/wmm.xyz", "F_nT", path, "meas_nT", "icp", dir + "/a.csv")).first, 0);
  ASSERT_EQ(RunMatch(Args(testing::ReferencePath("map_wmm_0p5deg.csv"), "F_nT", path, "meas_nT", "icp",
                          dir + "/b.csv"))
                .first,
            0);
  const CsvTable a = CsvTable::Read(dir + "/a.csv"), b = CsvTable::Read(dir + "/b.csv");
  ASSERT_EQ(a.num_rows(), b.num_rows());
  for (std::size_t r = 0; r < a.num_rows(); ++r) {
    EXPECT_EQ(a.text(r, 1), b.text(r, 1));
    EXPECT_EQ(a.text(r, 2), b.text(r, 2));
  }
  EXPECT_EQ(a.params().at("summary"), b.params().at("summary"));
}

TEST(MatchCli, AnOffMapPathIsRefused) {
  // Every INS point far outside the map: exit 2 naming the path file, no
  // output (it used to be written, "not converged", with exit 0).
  const std::string dir = testing::TempDir();
  WriteText(dir + "/far.csv", "k,ins_lat,ins_lon,meas_nT\n0,50,65,40000\n1,50.1,65.1,40010\n2,50.2,65.2,40020\n");
  const auto [code, text] = RunMatch(Args(testing::ReferencePath("map_wmm_0p5deg.csv"), "F_nT", dir + "/far.csv", "meas_nT",
                                     "fast-msd", dir + "/out.csv"));
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find(dir + "/far.csv: fast-msd: the path is entirely off the map"), std::string::npos) << text;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out.csv"));
}

TEST(MatchCli, ParticleFiltersWriteTheLibrarysRunAndItsDiagnostics) {
  const std::string dir = testing::TempDir();
  const std::string map = testing::ReferencePath("map_crustal_anomaly.csv");
  const std::string path = testing::ReferencePath("mappath_crustal_off0p01deg_noise3nT.csv");
  const GeoGrid grid = ReadGeoGridCsv(map, {"anomaly_nT"});
  const MatchPath p = ReadMatchPath(path, "meas_nT");
  for (const std::string method : {"pf", "afpf"}) {
    const std::string out = dir + "/" + method + ".csv", diag = dir + "/" + method + "_steps.csv";
    std::vector<std::string> args = Args(map, "anomaly_nT", path, "meas_nT", method, out);
    args.insert(args.end(), {"--particles", "1000", "--max-particles", "5000", "--seed", "5", "--sigma", "6",
                             "--diagnostics", diag});
    const auto [code, text] = RunMatch(args);
    ASSERT_EQ(code, 0) << text;
    ParticleFilterOptions o;
    o.num_particles = 1000;
    o.max_particles = 5000;
    o.seed = 5;
    o.measurement_sigma_nT = 6.0;
    std::vector<StepDiagnostics> steps;
    MatchOptions mo;  // the tool's entry point: Match (the filter's run, its status reviewed)
    mo.particle_filter = o;
    const MatchResult lib = Match(*ParseMethod(method), grid, 0, p, mo, &steps);
    const CsvTable t = CsvTable::Read(out);
    ASSERT_EQ(t.num_rows(), p.size());
    for (std::size_t r = 0; r < t.num_rows(); ++r) {
      EXPECT_EQ(t.number(r, 1), lib.lat_deg[r]);
      EXPECT_EQ(t.number(r, 2), lib.lon_deg[r]);
    }
    EXPECT_EQ(t.params().at("summary"), lib.BriefReport());
    EXPECT_NE(lib.BriefReport().find("seed 5"), std::string::npos);
    const CsvTable d = CsvTable::Read(diag);
    ASSERT_EQ(d.num_rows(), p.size());
    const std::size_t cp = d.column("particles"), cu = d.column("update");
    EXPECT_EQ(d.integer(p.size() - 1, cp), steps.back().particles);
    EXPECT_EQ(d.text(0, cu), "updated");
  }
}

TEST(MatchCli, ParticleFilterBadOptionsExit2) {
  const std::string dir = testing::TempDir();
  const std::string map = testing::ReferencePath("map_crustal_anomaly.csv");
  const std::string path = testing::ReferencePath("mappath_crustal_off0p01deg_noise3nT.csv");
  const std::string out = dir + "/out.csv";
  struct Case {
    std::vector<std::string> extra;
    std::string method, expected;
  };
  for (const Case& c : {Case{{"--particles", "0"}, "pf", "num_particles"},
                        Case{{"--particles", "4000", "--max-particles", "3000"}, "afpf", "max_particles"},
                        Case{{"--sigma", "-1"}, "afpf", "measurement_sigma_nT"},
                        Case{{"--resample-ess", "2"}, "pf", "resample_ess_fraction"},
                        Case{{"--acquisition-ensemble-covariance", "equal"}, "pf", "acquisition_ensemble_covariance"},
                        Case{{"--acquisition-ensemble", "3", "--acquisition-ensemble-covariance", "mean"}, "pf",
                             "--acquisition-ensemble-covariance"},
                        Case{{"--diagnostics", dir + "/d.csv"}, "icp", "--diagnostics"}}) {
    std::vector<std::string> args = Args(map, "anomaly_nT", path, "meas_nT", c.method, out);
    args.insert(args.end(), c.extra.begin(), c.extra.end());
    const auto [code, text] = RunMatch(args);
    EXPECT_EQ(code, 2) << c.expected << ": " << text;
    EXPECT_NE(text.find(c.expected), std::string::npos) << text;
    EXPECT_FALSE(std::filesystem::exists(out));
  }
}

}  // namespace
}  // namespace magnav::mapmatch
