// `magnav track` end to end: the binary's track file holds exactly what the
// library computes (columns, one row per epoch, moment line, σ columns), both
// solvers give the same track, fixes from `magnav invert` start the track as
// in the library, and bad input exits 2 naming the place.
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::tracker {
namespace {

const std::string kMagnav = MAGNAV_BIN;

// A track file with no data row (CsvTable refuses those): its header line and
// its `# key: value` lines.
struct EmptyTrackFile {
  std::string header;
  std::map<std::string, std::string> params;
  int data_lines = 0;
};
EmptyTrackFile ReadEmptyTrackFile(const std::string& path) {
  EmptyTrackFile f;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("# ", 0) == 0) {
      const std::size_t colon = line.find(": ");
      if (colon != std::string::npos) f.params[line.substr(2, colon - 2)] = line.substr(colon + 2);
    } else if (f.header.empty()) {
      f.header = line;
    } else if (!line.empty()) {
      ++f.data_lines;
    }
  }
  return f;
}

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

  // One vessel: one track (id 1), the library's SolveBatchMulti exactly.
  const GradiometerFile f = ReadGradiometerFile(input);
  const MultiTrackerOptions opt;
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), *f.B0, opt);
  ASSERT_EQ(tracks.size(), 1u);
  ASSERT_EQ(tracks[0].track_id, 1u);
  std::vector<EpochEstimate> rows;
  std::vector<TrackState> states;
  for (std::size_t k = 0; k < tracks[0].track.epochs.size(); ++k) {
    if (!tracks[0].track.epochs[k].usable) continue;
    rows.push_back(tracks[0].track.epochs[k]);
    states.push_back(tracks[0].states.at(k));
  }
  const TrackEstimate& lib = tracks[0].track;
  const CsvTable t = CsvTable::Read(dir + "/track.csv");
  const std::vector<std::string> header = {"t",       "track_id", "x",       "y",     "z",      "vx",
                                           "vy",      "heading",  "sigma_x", "sigma_y", "sigma_z", "state",
                                           "cov_xy",  "cov_xz",   "cov_yz"};
  ASSERT_EQ(t.header(), header);
  ASSERT_EQ(t.num_rows(), rows.size());
  ASSERT_GT(t.num_rows(), 1000u);  // the part of the 200 s pass where the vessel is seen
  for (std::size_t k = 0; k < t.num_rows(); ++k) {
    const EpochEstimate& e = rows[k];
    // The file is written with round-trip precision: the library's numbers exactly.
    EXPECT_EQ(t.integer(k, t.column("track_id")), 1);
    EXPECT_EQ(t.number(k, t.column("t")), e.t_s);
    EXPECT_EQ(t.number(k, t.column("x")), e.p_VinW.x());
    EXPECT_EQ(t.number(k, t.column("y")), e.p_VinW.y());
    EXPECT_EQ(t.number(k, t.column("z")), e.p_VinW.z());
    EXPECT_EQ(t.number(k, t.column("vx")), e.v_VinW().x());
    EXPECT_EQ(t.number(k, t.column("heading")), e.heading_rad);
    EXPECT_EQ(t.number(k, t.column("sigma_z")), std::sqrt(e.cov_state(2, 2)));
    EXPECT_EQ(t.text(k, t.column("state")), TrackStateName(states[k]));
    EXPECT_EQ(t.number(k, t.column("cov_xy")), e.cov_state(0, 1));
    EXPECT_EQ(t.number(k, t.column("cov_xz")), e.cov_state(0, 2));
    EXPECT_EQ(t.number(k, t.column("cov_yz")), e.cov_state(1, 2));
  }
  EXPECT_EQ(t.params().at("track_moment_body_Am2").substr(0, 3), "1, ");
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

// --fixes: the track started from `magnav invert`'s fixes equals the library
// started from the same fixes, and says so; with --init-from dipole_fix the
// window starts only after the first valid fix.
TEST(TrackCli, FixesFromInvertStartTheTrack) {
  const std::string dir = testing::TempDir();
  const std::string input = testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv");
  auto [rc, out] = testing::RunCommand(
      {kMagnav, "invert", "--input", input, "--method", "ted-egt", "--output", dir + "/fixes.csv"});
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = Track({"--input", input, "--fixes", dir + "/fixes.csv", "--output", dir + "/track.csv"});
  ASSERT_EQ(rc, 0) << out;

  const CsvTable fx = CsvTable::Read(dir + "/fixes.csv");
  std::vector<DipoleFix> fixes;
  double first_valid_t = -1.0;
  for (std::size_t i = 0; i < fx.num_rows(); ++i) {
    DipoleFix f;
    f.t_s = fx.number(i, fx.column("t"));
    f.sensor_id = static_cast<std::uint32_t>(fx.integer(i, fx.column("sensor_id")));
    f.valid = fx.integer(i, fx.column("valid")) == 1;
    if (!f.valid) continue;
    if (first_valid_t < 0) first_valid_t = f.t_s;
    f.p_DinW = {fx.number(i, fx.column("dipole_x")), fx.number(i, fx.column("dipole_y")),
                fx.number(i, fx.column("dipole_z"))};
    fixes.push_back(f);
  }
  const GradiometerFile f = ReadGradiometerFile(input);
  const MultiTrackerOptions opt;
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), *f.B0, opt, &fixes);
  ASSERT_EQ(tracks.size(), 1u);
  std::vector<EpochEstimate> rows;
  std::vector<TrackState> states;
  for (std::size_t k = 0; k < tracks[0].track.epochs.size(); ++k) {
    if (!tracks[0].track.epochs[k].usable) continue;
    rows.push_back(tracks[0].track.epochs[k]);
    states.push_back(tracks[0].states.at(k));
  }
  const CsvTable t = CsvTable::Read(dir + "/track.csv");
  EXPECT_NE(t.params().at("summary").find("external init fixes"), std::string::npos);
  ASSERT_EQ(t.num_rows(), rows.size());
  for (std::size_t k = 0; k < t.num_rows(); ++k) {
    ASSERT_EQ(t.number(k, t.column("x")), rows[k].p_VinW.x()) << k;
    ASSERT_EQ(t.number(k, t.column("y")), rows[k].p_VinW.y()) << k;
  }

  std::tie(rc, out) = Track({"--input", input, "--fixes", dir + "/fixes.csv", "--init-from", "dipole_fix", "--mode",
                             "window", "--output", dir + "/window.csv"});
  ASSERT_EQ(rc, 0) << out;
  const CsvTable w = CsvTable::Read(dir + "/window.csv");
  ASSERT_GT(w.num_rows(), 1000u);
  // Its first live row comes after the first valid fix: the track waited
  // for the fixes (its back-filled start rows, state start, may go back to
  // its window's first strong epoch).
  std::size_t live = 0;
  while (live < w.num_rows() && w.text(live, w.column("state")) == "start") ++live;
  ASSERT_LT(live, w.num_rows());
  EXPECT_GT(w.number(live, w.column("t")), first_valid_t);
}

TEST(TrackCli, BadFixesExitTwoAndNameThePlace) {
  const std::string dir = testing::TempDir();
  const std::string input = testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv");
  std::ofstream(dir + "/text.csv") << "t,sensor_id,dipole_x,dipole_y,dipole_z,valid\n"
                                   << "0,0,,,,0\n"  // a rejected fix may have no position
                                   << "0.1,0,1.5,abc,2,1\n";
  auto [rc, out] = Track({"--input", input, "--fixes", dir + "/text.csv", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find(dir + "/text.csv:3: column 'dipole_y'"), std::string::npos) << out;

  std::ofstream(dir + "/id.csv") << "t,sensor_id,dipole_x,dipole_y,dipole_z,valid\n"
                                 << "0,4294967296,1,2,3,1\n";
  std::tie(rc, out) = Track({"--input", input, "--fixes", dir + "/id.csv", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find(dir + "/id.csv:2: column 'sensor_id': out of range"), std::string::npos) << out;

  std::ofstream(dir + "/cols.csv") << "t,sensor_id,x,y,z\n0,0,1,2,3\n";
  std::tie(rc, out) = Track({"--input", input, "--fixes", dir + "/cols.csv", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("missing column 'dipole_x'"), std::string::npos) << out;

  std::tie(rc, out) = Track({"--input", input, "--init-from", "dipole_fix", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("--init-from dipole_fix needs --fixes"), std::string::npos) << out;

  // Fixes that match no sample of the pass (another time base): no track, said
  // so on stderr and in the summary of an empty track file (issue 24 item 7).
  std::ofstream(dir + "/elsewhere.csv") << "t,sensor_id,dipole_x,dipole_y,dipole_z,valid\n"
                                        << "1000.05,0,1,2,3,1\n";
  std::tie(rc, out) = Track({"--input", input, "--fixes", dir + "/elsewhere.csv", "--init-from", "dipole_fix",
                             "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("no track: too few of the given fixes"), std::string::npos) << out;
  const EmptyTrackFile none = ReadEmptyTrackFile(dir + "/o.csv");
  EXPECT_EQ(none.data_lines, 0);
  EXPECT_EQ(none.params.at("summary").rfind("no track: too few of the given fixes", 0), 0u);
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

}

// Nothing to track is a result (issue 24 item 7): a field whose vessels all
// pass 25 m or more from every sensor (tensor ~3 σ at the closest, far below
// the initialiser's 50 σ) gives, in both modes, a track file with its header,
// no row and a summary saying why, and exit 0; so does a single quiet sample.
TEST(TrackCli, NothingToTrackGivesAnEmptyTrackFileAndExitZero) {
  const std::string dir = testing::TempDir();
  // 2 x 2 sensors at (±20, ±20, 0); vessels along y = 45 and y = -50.
  auto [rc, out] = testing::RunCommand(
      {kMagnav, "simulate", "--noise", "fluxgate", "--seed", "3", "--grid", "2,2,40", "--vessel",
       "id=1;start=-60,45,-5;heading=0;speed=1.5;moment=2500,300,900;turns=80:0", "--vessel",
       "id=2;start=60,-50,-6;heading=3.141592653589793;speed=1.2;moment=1800,-500,700;turns=80:0", "--output",
       dir + "/far.csv", "--truth", dir + "/far_truth.csv"});
  ASSERT_EQ(rc, 0) << out;
  for (const char* mode : {"window", "batch"}) {
    const std::string o = dir + "/far_" + mode + ".csv";
    std::tie(rc, out) = Track({"--input", dir + "/far.csv", "--mode", mode, "--output", o});
    ASSERT_EQ(rc, 0) << mode << ": " << out;
    EXPECT_NE(out.find("no track: too few strong single-sample fixes to initialise"), std::string::npos) << out;
    const EmptyTrackFile t = ReadEmptyTrackFile(o);
    EXPECT_EQ(t.header, "t,track_id,x,y,z,vx,vy,heading,sigma_x,sigma_y,sigma_z,state,cov_xy,cov_xz,cov_yz") << mode;
    EXPECT_EQ(t.data_lines, 0) << mode;
    EXPECT_EQ(t.params.at("mode"), mode);
    EXPECT_EQ(t.params.at("summary").rfind("no track: too few strong single-sample fixes to initialise", 0), 0u)
        << t.params.at("summary");
    EXPECT_EQ(t.params.count("track"), 0u);
    // And what the far source did (on by default; 4 sensors, no ship: every
    // fit refused, nothing removed).
    EXPECT_NE(t.params.at("summary").find("far source: "), std::string::npos) << t.params.at("summary");
    EXPECT_NE(t.params.at("summary").find("(0 accepted, "), std::string::npos) << t.params.at("summary");
  }
  // The window summary also carries the multi-tracker's counts.
  const EmptyTrackFile w = ReadEmptyTrackFile(dir + "/far_window.csv");
  EXPECT_NE(w.params.at("summary").find("0 tracks confirmed"), std::string::npos) << w.params.at("summary");
  // `magnav evaluate` scores the empty file: no vessel within 15 m of a
  // sensor, nothing claimed: GOSPA 0 over 0 epochs; over the whole pass both
  // vessels are missed at every instant: √(2 · 50 m²) = 10 m.
  std::tie(rc, out) = testing::RunCommand({kMagnav, "evaluate", "--estimate", dir + "/far_window.csv", "--truth",
                                           dir + "/far_truth.csv", "--max-range", "15", "--pass", dir + "/far.csv"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("over 0 epochs: mean 0 m"), std::string::npos) << out;
  std::tie(rc, out) = testing::RunCommand(
      {kMagnav, "evaluate", "--estimate", dir + "/far_batch.csv", "--truth", dir + "/far_truth.csv"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("over 801 epochs: mean 10 m, max 10 m"), std::string::npos) << out;
  EXPECT_NE(out.find("coverage 0.0000"), std::string::npos) << out;

  // One sample far below the noise.
  const std::string cols = "t,sensor_id,sensor_x,sensor_y,sensor_z,B_x,B_y,B_z,T00,T01,T02,T10,T11,T12,T20,T21,T22\n";
  std::ofstream(dir + "/quiet.csv") << "# B0_T: 2e-05, 1e-06, 4.5e-05\n" << cols
                                    << "0,0,0,0,0,2e-05,1e-06,4.5e-05,0,0,0,0,0,0,0,0,0\n";
  std::tie(rc, out) = Track({"--input", dir + "/quiet.csv", "--output", dir + "/o.csv"});
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("no track"), std::string::npos) << out;
  EXPECT_EQ(ReadEmptyTrackFile(dir + "/o.csv").data_lines, 0);
  EXPECT_NE(ReadEmptyTrackFile(dir + "/o.csv").params.at("summary").find("no track"), std::string::npos);
}

// A user's field end to end: `magnav simulate --vessel` twice (the held-out
// two-vessel field of two_vessels.h, written by the CLI), `magnav track
// --mode window` and `magnav evaluate` against the vessel_id truth: one
// track per vessel, no false rows, each vessel covered near the sensors.
TEST(TrackCli, SimulatedTwoVesselFieldIsTrackedAndScoredPerVessel) {
  const std::string dir = testing::TempDir();
  const auto [rc, out] = testing::RunCommand(
      {kMagnav, "simulate", "--noise", "fluxgate", "--seed", "11", "--grid", "3,3,40", "--vessel",
       "id=1;start=-100,38,-5;heading=0;speed=1.5;moment=2500,300,900;turns=140:0", "--vessel",
       "id=2;start=38,100,-6;heading=-1.5707963267948966;speed=1.2;moment=1800,-500,700;turns=140:0", "--output",
       dir + "/field.csv", "--truth", dir + "/truth.csv"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("wrote 12609 samples (9 sensors, 2 vessels, 140 s)"), std::string::npos) << out;
  const CsvTable truth = CsvTable::Read(dir + "/truth.csv");
  ASSERT_TRUE(truth.has_column("vessel_id"));
  EXPECT_EQ(truth.num_rows(), 2u * 1401u);
  const auto [rc2, out2] = Track({"--input", dir + "/field.csv", "--mode", "window", "--output", dir + "/t.csv"});
  ASSERT_EQ(rc2, 0) << out2;
  const CsvTable t = CsvTable::Read(dir + "/t.csv");
  std::set<long long> ids;
  for (std::size_t k = 0; k < t.num_rows(); ++k) ids.insert(t.integer(k, t.column("track_id")));
  EXPECT_EQ(ids.size(), 2u);
  const auto [rc3, out3] =
      testing::RunCommand({kMagnav, "evaluate", "--estimate", dir + "/t.csv", "--truth", dir + "/truth.csv",
                           "--max-range", "15", "--pass", dir + "/field.csv"});
  ASSERT_EQ(rc3, 0) << out3;
  EXPECT_NE(out3.find(": 0 false"), std::string::npos) << out3;
  // Within 15 m of a sensor, coverage per vessel as the library's
  // (tracker_multi_test: 0.903 each).
  for (const char* v : {"vessel 1:", "vessel 2:"}) {
    const std::size_t at = out3.find(v);
    ASSERT_NE(at, std::string::npos) << out3;
    const std::size_t c = out3.find("coverage ", at);
    ASSERT_NE(c, std::string::npos) << out3;
    EXPECT_GE(std::stod(out3.substr(c + 9)), 0.85) << out3;
  }
  // Bad vessel specs are refused with the flag named.
  const auto [rc4, out4] = testing::RunCommand(
      {kMagnav, "simulate", "--vessel", "id=1;speed=fast", "--output", dir + "/x.csv"});
  EXPECT_EQ(rc4, 2);
  EXPECT_NE(out4.find("--vessel 'id=1;speed=fast': speed: 'fast' is not a number"), std::string::npos) << out4;
  const auto [rc5, out5] = testing::RunCommand(
      {kMagnav, "simulate", "--vessel", "id=1", "--vessel", "id=1", "--output", dir + "/x.csv"});
  EXPECT_EQ(rc5, 2);
  EXPECT_NE(out5.find("vessel ids must be unique"), std::string::npos) << out5;
}

// A long pass (100,001 rows, a vessel passing and then 10,000 s of data):
// tracked in one go, and off a terminal `magnav track` says what it is doing
// (each track's refinement; at least every 10 s the window pass's progress).
TEST(TrackCli, LongPassSaysWhatItIsDoing) {
  const std::string dir = testing::TempDir();
  auto [rc, out] = testing::RunCommand({kMagnav, "simulate", "--noise", "fluxgate", "--turns", "10000:0", "--sensors",
                                        "0,0,0", "--output", dir + "/long.csv", "--truth", dir + "/truth.csv"});
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = Track({"--input", dir + "/long.csv", "--output", dir + "/track.csv"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("track: refining track 1, round 1 of 2"), std::string::npos) << out;
  EXPECT_NE(out.find("track: refining track 1, round 2 of 2"), std::string::npos) << out;
  const CsvTable t = CsvTable::Read(dir + "/track.csv");
  EXPECT_GT(t.num_rows(), 300u);  // the vessel's pass near the sensor
}

}  // namespace
}  // namespace magnav::tracker
