// The bad-input corpus (tests/data/bad/, see its README): every offline
// command (and, in DDS builds, replay) on every malformed file of the kind it
// reads exits 2 with a message naming the file and, where one applies, the
// line and the column, and leaves no output file (nor a temporary) behind.
// Also: an existing output is untouched by a failed run, --output equal to an
// input is refused, a UTF-8 BOM and CRLF line ends are read like plain files.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "subprocess.h"
#include "test_data.h"

namespace magnav {
namespace {

namespace fs = std::filesystem;
const std::string kMagnav = MAGNAV_BIN;

std::string Bad(const std::string& name) { return testing::TestDataDir() + "/bad/" + name; }

// How a command is run on one bad file of one kind; `out` is the output path.
enum class Kind {
  kInvert, kTrack, kTrackFixes, kEstimate, kTruth, kMeasurements, kDeployment, kGnss,
  kReplay, kReplayMeasurements, kReplayGnss,  // DDS builds: the file is read before any DDS entity is made
  kMatchMap, kMatchPath,  // magnav match: the bad file as --map (with mappath_ok.csv) or --path (with map_ok.csv)
  kInfo, kExport  // DDS builds: MCAP recordings (mcap/)
};

std::vector<std::string> Command(Kind kind, const std::string& file, const std::string& out) {
  switch (kind) {
    case Kind::kInvert:
      return {kMagnav, "invert", "--input", file, "--method", "ted", "--output", out};
    case Kind::kTrack:
      return {kMagnav, "track", "--input", file, "--output", out};
    case Kind::kTrackFixes:
      return {kMagnav, "track", "--input", Bad("pass_ok.csv"), "--fixes", file, "--output", out};
    case Kind::kEstimate:
      return {kMagnav, "evaluate", "--estimate", file, "--truth", Bad("truth_ok.csv")};
    case Kind::kTruth:
      return {kMagnav, "evaluate", "--estimate", Bad("fixes_ok.csv"), "--truth", file};
    case Kind::kMeasurements:
      return {kMagnav, "localize", "--method", "ekf", "--measurements", file, "--deployment",
              Bad("deployment_ok.csv"), "--output", out};
    case Kind::kDeployment:
      return {kMagnav, "localize", "--method", "ekf", "--measurements", Bad("measurements_ok.csv"), "--deployment",
              file, "--output", out};
    case Kind::kGnss:
      return {kMagnav, "localize", "--method", "ekf", "--measurements", Bad("measurements_ok.csv"), "--deployment",
              Bad("deployment_ok.csv"), "--gnss", file, "--output", out};
    case Kind::kReplay:
      return {kMagnav, "replay", "--input", file, "--wait-readers", "0"};
    case Kind::kReplayMeasurements:
      return {kMagnav, "replay", "--magnetometer", file, "--wait-readers", "0"};
    case Kind::kReplayGnss:
      return {kMagnav, "replay", "--magnetometer", Bad("measurements_ok.csv"), "--gnss", file, "--wait-readers", "0"};
    case Kind::kInfo:
      return {kMagnav, "info", file};
    case Kind::kExport:
      return {kMagnav, "export", file, "--output-dir", out};
    case Kind::kMatchMap:
      return {kMagnav, "match", "--map", file, "--value-column", "anomaly_nT", "--path", Bad("mappath_ok.csv"),
              "--meas-column", "meas_nT", "--method", "fast-msd", "--output", out};
    case Kind::kMatchPath:
      return {kMagnav, "match", "--map", Bad("map_ok.csv"), "--value-column", "anomaly_nT", "--path", file,
              "--meas-column", "meas_nT", "--method", "fast-msd", "--output", out};
  }
  return {};
}

struct BadInput {
  Kind kind;
  std::string file;      // in tests/data/bad/, or an absolute path
  std::string expected;  // what the message says right after the file name
};

// Malformed pass files, read the same way by invert and track.
const std::vector<std::pair<std::string, std::string>> kBadPasses = {
    {"pass_empty.csv", ": empty file: no header row"},
    {"pass_comments_only.csv", ": empty file: no header row (only comments"},
    {"pass_header_only.csv", ":4: no data rows"},
    {"pass_missing_column.csv", ": missing column 'T22'"},
    {"pass_duplicate_column.csv", ":4: duplicate column 'B_x' in header"},
    {"pass_no_time_column.csv", ": missing column 't'"},
    {"pass_text_in_number.csv", ":6: column 'B_z': 'oops' is not a finite number"},
    {"pass_nan.csv", ":6: column 'T01': 'nan' is not a finite number"},
    {"pass_inf.csv", ":6: column 'B_y': '-inf' is not a finite number"},
    {"pass_empty_field.csv", ":6: column 'sensor_y': empty field"},
    {"pass_truncated_row.csv", ":6: short row"},
    {"pass_long_row.csv", ":6: long row"},
    {"pass_crlf_bad_value.csv", ":6: column 'sensor_x': 'x1' is not a finite number"},
    {"pass_bom_bad_time.csv", ":2: column 't': 'zero' is not a finite number"},
    {"pass_1e308.csv", ":6: column 'T00': 1e+308 T/m is out of range"},
    {"pass_1e309.csv", ":6: column 'T11': '1e309' is not a finite number"},
    {"pass_tensor_1e200.csv", ":6: column 'T00': 1e+200 T/m is out of range"},
    {"pass_B_in_nT.csv", ":5: column 'B_x': 21000 T is out of range"},
    {"pass_position_1e308.csv", ":6: column 'sensor_z': 1e+308 m is out of range"},
    {"pass_negative_sensor_id.csv", ":6: column 'sensor_id': '-1' is not a non-negative integer"},
    {"pass_binary.csv", ":6: binary data (NUL byte)"},
    {"/dev/zero", ":1: line longer than 1 MiB (no newline)"},
};

std::vector<BadInput> Corpus() {
  std::vector<BadInput> c;
  for (const auto& [file, expected] : kBadPasses) {
    c.push_back({Kind::kInvert, file, expected});
    c.push_back({Kind::kTrack, file, expected});
#ifdef MAGNAV_WITH_DDS
    c.push_back({Kind::kReplay, file, expected});
#endif
  }
#ifdef MAGNAV_WITH_DDS
  // Replay passes samples on as they are (the consumers' door judges them):
  // it refuses what it cannot read.
  c.push_back({Kind::kReplayMeasurements, "measurements_header_only.csv", ":4: no data rows"});
  c.push_back({Kind::kReplayMeasurements, "measurements_missing_column.csv", ": missing column 'B_z'"});
  c.push_back({Kind::kReplayMeasurements, "measurements_duplicate_column.csv", ":4: duplicate column 'B_y' in header"});
  c.push_back({Kind::kReplayGnss, "gnss_header_only.csv", ":1: no data rows"});
  c.push_back({Kind::kReplayGnss, "gnss_inf.csv", ":3: column 'x': 'inf' is not a finite number"});
  // MCAP recordings (tests/data/bad/mcap/, from a 25-sample recording):
  // info, export and replay refuse invalid content with exit 2.
  const std::vector<std::pair<std::string, std::string>> mcap = {
      {"mcap/empty.mcap", ": empty file (not MCAP)"},
      {"mcap/bad_magic.mcap", ": not an MCAP file"},
      {"mcap/chunk_crc_mismatch.mcap", ": byte 5796: Chunk record: CRC mismatch of the uncompressed records"},
      {"mcap/chunk_zstd_corrupt.mcap", ": byte 6158: Chunk record: CRC mismatch of the uncompressed records"},
      {"mcap/chunk_unknown_compression.mcap", ": byte 5800: Chunk record: unknown compression 'zzzz'"},
      {"mcap/chunk_length_huge.mcap", ": byte 5800: a Chunk record of 4611686018427387904 bytes is over the limit"},
      {"mcap/statistics_count_wrong.mcap", ": the Statistics record counts 26 messages, the data section holds 25"},
      {"mcap/trailing_bytes.mcap", ": byte 15402: 4 byte(s) after the closing magic"},
  };
  for (const auto& [file, expected] : mcap) {
    for (const Kind k : {Kind::kInfo, Kind::kExport, Kind::kReplay}) c.push_back({k, file, expected});
  }
  // Well-formed MCAP whose message is not CDR of its type: info counts it,
  // export and replay refuse the file.
  for (const Kind k : {Kind::kExport, Kind::kReplay}) {
    c.push_back({k, "mcap/message_not_cdr.mcap",
                 ": a message on magnav/gradiometer (log time 1795637612417362239 ns) is not CDR of "
                 "magnav::msg::GradiometerSample"});
  }
#endif
  c.push_back({Kind::kTrack, "pass_time_backwards.csv", ":7: column 't': time goes backwards"});
  for (const Kind k : {Kind::kTrackFixes, Kind::kEstimate}) {
    c.push_back({k, "fixes_empty.csv", ": empty file: no header row"});
    c.push_back({k, "fixes_header_only.csv", ":1: no data rows"});
    c.push_back({k, "fixes_missing_time.csv", ": missing column 't'"});
    c.push_back({k, "fixes_text_in_number.csv", ":3: column 'dipole_y': 'abc' is not a finite number"});
  }
  c.push_back({Kind::kTrackFixes, "fixes_unknown_sensor.csv", ":3: column 'sensor_id': sensor 7 is not in the pass"});
  c.push_back({Kind::kTrackFixes, "fixes_1e308.csv", ":3: column 'dipole_x': 1e+308 m is out of range"});
  c.push_back({Kind::kTruth, "truth_header_only.csv", ":1: no data rows"});
  c.push_back({Kind::kTruth, "truth_missing_column.csv", ": missing column 'z'"});
  c.push_back({Kind::kTruth, "truth_nan.csv", ":3: column 'x': 'nan' is not a finite number"});
  c.push_back({Kind::kTruth, "truth_text_time.csv", ":3: column 't': '0.1s' is not a finite number"});
  c.push_back({Kind::kMeasurements, "measurements_header_only.csv", ":4: no data rows"});
  c.push_back({Kind::kMeasurements, "measurements_missing_column.csv", ": missing column 'B_z'"});
  c.push_back({Kind::kMeasurements, "measurements_duplicate_column.csv", ":4: duplicate column 'B_y' in header"});
  c.push_back({Kind::kMeasurements, "measurements_unknown_sensor.csv",
               ":6: column 'sensor_id': sensor 9 is not in the deployment file"});
  c.push_back({Kind::kMeasurements, "measurements_time_backwards.csv", ":6: column 't': time goes backwards"});
  c.push_back({Kind::kMeasurements, "measurements_B_in_nT.csv", ":6: column 'B_x': 21000 T is out of range"});
  c.push_back({Kind::kMeasurements, "measurements_time_1e300.csv", ":9: column 't': 1e+300 s is out of range"});
  c.push_back({Kind::kMeasurements, "measurements_time_jump.csv", ":9: column 't': time jumps 7200 s ahead"});
  c.push_back({Kind::kDeployment, "deployment_header_only.csv", ":1: no data rows"});
  c.push_back({Kind::kDeployment, "deployment_duplicate_sensor.csv", ":4: column 'sensor_id': sensor 1 listed twice"});
  c.push_back({Kind::kDeployment, "deployment_text_in_number.csv", ":3: column 'y': 'zero' is not a finite number"});
  c.push_back({Kind::kDeployment, "deployment_bad_sigma.csv", ":3: column 'sigma_xy': must be > 0"});
  c.push_back({Kind::kDeployment, "deployment_position_1e308.csv", ":3: column 'y': 1e+308 m is out of range"});
  c.push_back({Kind::kGnss, "gnss_header_only.csv", ":1: no data rows"});
  c.push_back({Kind::kGnss, "gnss_time_backwards.csv", ":4: column 't': time goes backwards"});
  c.push_back({Kind::kGnss, "gnss_position_1e12.csv", ":3: column 'x': 5e+12 m is out of range"});
  c.push_back({Kind::kGnss, "gnss_inf.csv", ":3: column 'x': 'inf' is not a finite number"});
  c.push_back({Kind::kGnss, "gnss_time_1e300.csv", ":4: column 't': 1e+300 s is out of range"});
  // Map matching: maps of every format and map paths (limits: core/limits.h).
  c.push_back({Kind::kMatchMap, "map_node_1e308.csv", ":10: column 'anomaly_nT': 1e+308 nT is out of range"});
#ifdef MAGNAV_WITH_GDAL
  c.push_back({Kind::kMatchMap, "map_asc_16384x16384.asc",
               " (layer 'anomaly_nT'): the header claims 16384 rows x 16384 columns"});
  c.push_back({Kind::kMatchMap, "map_asc_30000x30000.asc",
               " (layer 'anomaly_nT'): the header claims 30000 rows x 30000 columns"});
#endif
  c.push_back({Kind::kMatchPath, "mappath_1e308.csv", ":7: column 'meas_nT': 1e+308 nT is out of range"});
  c.push_back({Kind::kMatchPath, "mappath_5e9nT.csv", ":7: column 'meas_nT': 5e+09 nT is out of range"});
  c.push_back({Kind::kMatchPath, "mappath_lat_95.csv", ":5: column 'ins_lat': 95 deg is out of range"});
  c.push_back({Kind::kMatchPath, "mappath_off_map.csv", ": fast-msd: the path is entirely off the map"});
  return c;
}

// Files in `dir` (the output and any temporary the command made).
std::vector<std::string> Listing(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

std::string Text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(BadInput, EveryCommandOnEveryBadFileGivesACleanError) {
  const std::vector<BadInput> corpus = Corpus();
  int clean = 0;
  for (std::size_t i = 0; i < corpus.size(); ++i) {
    const BadInput& b = corpus[i];
    const std::string file = b.file.front() == '/' ? b.file : Bad(b.file);
    const std::string dir = testing::TempDir();  // a fresh one per case
    const auto argv = Command(b.kind, file, dir + "/out.csv");
    const auto [rc, out] = testing::RunCommand(
        argv, {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}}, std::chrono::seconds(30));
    const bool named = out.find(file + b.expected) != std::string::npos;
    const bool nothing_left = Listing(dir).empty();
    EXPECT_EQ(rc, 2) << b.file << " (" << argv[1] << "): " << out;
    EXPECT_TRUE(named) << b.file << " (" << argv[1] << "): expected '" << file + b.expected << "' in: " << out;
    EXPECT_TRUE(nothing_left) << b.file << " (" << argv[1] << "): output left behind";
    if (rc == 2 && named && nothing_left) ++clean;
  }
  std::printf("%zu bad inputs tried, %d clean errors (%.0f %%)\n", corpus.size(), clean,
              100.0 * clean / static_cast<double>(corpus.size()));
  EXPECT_EQ(clean, static_cast<int>(corpus.size()));
}

#ifdef MAGNAV_WITH_DDS
// An MCAP recording cut short (kill -9 of the recorder, a disk full): read up
// to its last complete chunk, with a warning naming what is missing; exit 0.
TEST(BadInput, TruncatedMcapIsReadUpToItsLastCompleteChunk) {
  for (const std::string name : {"truncated_in_chunk.mcap", "truncated_after_two_chunks.mcap"}) {
    const std::string file = Bad("mcap/" + name);
    const std::string dir = testing::TempDir();
    const auto [rc, out] = testing::RunCommand({kMagnav, "export", file, "--output-dir", dir + "/csv"});
    EXPECT_EQ(rc, 0) << out;
    EXPECT_NE(out.find("export: warning: " + file + ": cut short at byte 7506"), std::string::npos) << out;
    EXPECT_NE(out.find("read 2 complete chunk(s), 12 message(s)"), std::string::npos) << out;
    EXPECT_NE(out.find("missing: the rest of the data section, Data End, the summary"), std::string::npos) << out;
    EXPECT_NE(out.find("exported 12 gradiometer row(s)"), std::string::npos) << out;
    const auto [rc2, info] = testing::RunCommand({kMagnav, "info", file});
    EXPECT_EQ(rc2, 0) << info;
    EXPECT_NE(info.find("magnav/gradiometer (magnav::msg::GradiometerSample): 12 message(s)"), std::string::npos) << info;
    EXPECT_NE(info.find("info: warning: " + file + ": cut short"), std::string::npos) << info;
  }
  // The whole file: no warning, every sample.
  const auto [rc, info] = testing::RunCommand({kMagnav, "info", Bad("mcap/ok.mcap")});
  EXPECT_EQ(rc, 0) << info;
  EXPECT_NE(info.find("25 message(s)"), std::string::npos) << info;
  EXPECT_EQ(info.find("warning"), std::string::npos) << info;
}
#endif

// A directory is not a file to read.
TEST(BadInput, ADirectoryIsRefused) {
  const std::string dir = testing::TempDir();
  const auto [rc, out] = testing::RunCommand(Command(Kind::kInvert, dir, dir + "/o.csv"));
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find(dir + ": is a directory"), std::string::npos) << out;
}

// A failed run leaves an existing output file as it was.
TEST(BadInput, ExistingOutputIsUntouchedByAFailedRun) {
  const std::string dir = testing::TempDir();
  const std::string out = dir + "/previous.csv";
  std::ofstream(out) << "previous result\n";
  for (const Kind k : {Kind::kInvert, Kind::kTrack}) {
    const auto [rc, msg] = testing::RunCommand(Command(k, Bad("pass_text_in_number.csv"), out));
    EXPECT_EQ(rc, 2) << msg;
    EXPECT_EQ(Text(out), "previous result\n");
  }
  EXPECT_EQ(Listing(dir), std::vector<std::string>{"previous.csv"});  // no temporary left
}

// --output equal to an input (the same path, another spelling of it, or a
// hard link to it) is refused before anything is read or written.
TEST(BadInput, OutputEqualToAnInputIsRefused) {
  const std::string dir = testing::TempDir();
  const std::string pass = dir + "/pass.csv";
  fs::copy_file(Bad("pass_ok.csv"), pass, fs::copy_options::overwrite_existing);
  const std::string before = Text(pass);
  fs::create_hard_link(pass, dir + "/link.csv");
  for (const std::string& out : {pass, dir + "/../" + fs::path(dir).filename().string() + "/pass.csv", dir + "/link.csv"}) {
    for (const Kind k : {Kind::kInvert, Kind::kTrack}) {
      const auto [rc, msg] = testing::RunCommand(Command(k, pass, out));
      EXPECT_EQ(rc, 2) << msg;
      EXPECT_NE(msg.find("are the same file: refusing to overwrite an input"), std::string::npos) << msg;
    }
  }
  const auto [rc, msg] = testing::RunCommand({kMagnav, "track", "--input", pass, "--fixes", dir + "/fixes.csv",
                                              "--output", dir + "/fixes.csv"});
  EXPECT_EQ(rc, 2) << msg;
  const auto [rc2, msg2] = testing::RunCommand(Command(Kind::kDeployment, pass, pass));
  EXPECT_EQ(rc2, 2) << msg2;
  const auto [rc3, msg3] =
      testing::RunCommand({kMagnav, "simulate", "--output", dir + "/sim.csv", "--truth", dir + "/sim.csv"});
  EXPECT_EQ(rc3, 2) << msg3;
  const auto [rc4, msg4] = testing::RunCommand({kMagnav, "match", "--map", dir + "/map.csv", "--value-column", "F",
                                                "--path", pass, "--meas-column", "B", "--method", "point",
                                                "--output", dir + "/link.csv"});
  EXPECT_EQ(rc4, 2) << msg4;
  EXPECT_NE(msg4.find("are the same file"), std::string::npos) << msg4;
  EXPECT_EQ(Text(pass), before);
}

// A UTF-8 byte-order mark and CRLF line ends (as spreadsheets write) are read
// like the plain file: the same result.
TEST(BadInput, BomAndCrlfAreReadLikeThePlainFile) {
  const std::string dir = testing::TempDir();
  std::string text = Text(Bad("pass_ok.csv"));
  std::string crlf;
  for (const char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  std::ofstream(dir + "/bom_crlf.csv", std::ios::binary) << "\xEF\xBB\xBF" << crlf;
  const auto [rc1, out1] = testing::RunCommand(Command(Kind::kInvert, Bad("pass_ok.csv"), dir + "/plain_out.csv"));
  const auto [rc2, out2] = testing::RunCommand(Command(Kind::kInvert, dir + "/bom_crlf.csv", dir + "/bom_out.csv"));
  ASSERT_EQ(rc1, 0) << out1;
  ASSERT_EQ(rc2, 0) << out2;
  std::string a = Text(dir + "/plain_out.csv"), b = Text(dir + "/bom_out.csv");
  // Only the "# input:" line differs.
  const auto drop_input = [](std::string s) {
    const auto p = s.find("# input: ");
    return s.erase(p, s.find('\n', p) - p);
  };
  EXPECT_EQ(drop_input(a), drop_input(b));
}

}  // namespace
}  // namespace magnav
