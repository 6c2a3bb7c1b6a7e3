// The `magnav` program end to end: clear errors on bad input, and a
// simulate -> replay -> record round trip over DDS (loopback) that delivers
// every sample unchanged.
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav {
namespace {

using namespace std::chrono_literals;
const std::string kMagnav = MAGNAV_BIN;

TEST(MagnavCli, SimulateWritesAFileTheReaderAccepts) {
  const std::string dir = testing::TempDir();
  const auto [rc, out] = testing::RunCommand({kMagnav, "simulate", "--noise", "squid", "--turns", "10:0.1",
                                              "--sensors", "0,0,0;20,20,0", "--output", dir + "/p.csv"});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("wrote 202 samples (101 instants, 2 sensors)"), std::string::npos) << out;
  const GradiometerFile f = ReadGradiometerFile(dir + "/p.csv");
  EXPECT_EQ(f.samples.size(), 202u);
  EXPECT_EQ(*f.sigma_T, 1e-13);
}

TEST(MagnavCli, BadInputGivesExitCode2AndNamesThePlace) {
  const std::string dir = testing::TempDir();
  std::ofstream(dir + "/bad.csv") << "t,sensor_id,sensor_x,sensor_y,sensor_z,B_x,B_y,B_z,T00,T01,T02,T10,T11,T12,T20,T21,T22\n"
                                  << "0,0,0,0,0,1,1,1,1,1,1,1,1,1,1,1,1\n"
                                  << "0.1,0,0,0,0,1,1,oops,1,1,1,1,1,1,1,1,1\n";
  const auto [rc, out] = testing::RunCommand({kMagnav, "replay", "--input", dir + "/bad.csv", "--wait-readers", "0"},
                                             {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find(dir + "/bad.csv:3: column 'B_z': 'oops' is not a finite number"), std::string::npos) << out;
  const auto [rc2, out2] = testing::RunCommand({kMagnav, "simulate", "--output", dir + "/x.csv", "--turns", "5:abc"});
  EXPECT_EQ(rc2, 2);
  EXPECT_NE(out2.find("--turns: '5:abc'"), std::string::npos) << out2;
  const auto [rc3, out3] = testing::RunCommand({kMagnav, "replay", "--input", dir + "/missing.csv"});
  EXPECT_NE(rc3, 0);
}

TEST(MagnavCli, ReplayThenRecordDeliversEverySampleUnchanged) {
  const std::string dir = testing::TempDir();
  const std::map<std::string, std::string> env = {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}};
  ASSERT_EQ(testing::RunCommand({kMagnav, "simulate", "--noise", "fluxgate", "--sensors", "0,0,0;20,20,0",
                                 "--output", dir + "/p.csv"}).first, 0);
  testing::Subprocess rec({kMagnav, "record", "--topic", "gradiometer", "--count", "4002", "--duration", "60",
                           "--output", dir + "/r.csv"}, env);
  const auto [rc, out] = testing::RunCommand({kMagnav, "replay", "--input", dir + "/p.csv", "--speed", "0"}, env);
  ASSERT_EQ(rc, 0) << out;
  ASSERT_EQ(rec.Wait(60s), 0);
  const GradiometerFile sent = ReadGradiometerFile(dir + "/p.csv");
  const CsvTable got = CsvTable::Read(dir + "/r.csv");
  ASSERT_EQ(got.num_rows(), sent.samples.size());
  // DDS orders samples per instance (sensor), not across sensors: match each
  // received row to the sent sample with its sensor and sequence number, and
  // check that each sensor's stream arrives in order.
  std::map<long long, long long> next_seq;
  std::set<std::pair<long long, long long>> seen;
  for (std::size_t r = 0; r < got.num_rows(); ++r) {
    const long long id = got.integer(r, got.column("sensor_id"));
    const long long seq = got.integer(r, got.column("seq"));
    ASSERT_EQ(seq, next_seq[id]++) << "sensor " << id << " out of order at row " << r;
    ASSERT_TRUE(seen.insert({id, seq}).second);
    const std::size_t i = static_cast<std::size_t>(2 * seq + id);  // file: t, then sensor id
    ASSERT_LT(i, sent.samples.size());
    const auto& s = sent.samples[i];
    ASSERT_EQ(id, s.sensor_id);
    ASSERT_NEAR(got.number(r, got.column("t")), s.t_s, 1e-9);
    ASSERT_EQ(got.number(r, got.column("B_y")), s.B.y());
    ASSERT_EQ(got.number(r, got.column("T12")), s.T(1, 2));
  }
}

// SIGTERM stops the recorder cleanly: the output holds every row received,
// each whole, and no temporary is left (rows go to OUTPUT.tmp-PID-N until
// the recorder stops, then it is renamed).
TEST(MagnavCli, RecordStoppedBySigtermLeavesACompleteFile) {
  const std::string dir = testing::TempDir();
  const std::map<std::string, std::string> env = {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}};
  ASSERT_EQ(testing::RunCommand({kMagnav, "simulate", "--turns", "10:0.1", "--sensors", "0,0,0", "--output",
                                 dir + "/p.csv"}).first, 0);
  testing::Subprocess rec({kMagnav, "record", "--topic", "gradiometer", "--output", dir + "/r.csv"}, env);
  const auto [rc, out] = testing::RunCommand({kMagnav, "replay", "--input", dir + "/p.csv", "--speed", "0"}, env);
  ASSERT_EQ(rc, 0) << out;
  std::this_thread::sleep_for(200ms);  // acknowledged samples reach the recorder's callback
  rec.Signal(SIGTERM);
  ASSERT_EQ(rec.Wait(20s), 0);
  EXPECT_EQ(CsvTable::Read(dir + "/r.csv").num_rows(), 101u);
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 2u);  // p.csv, r.csv
}

// kill -9 (no chance to close): the output is absent and the rows received
// up to a second before are in its temporary OUTPUT.tmp-PID-N, each whole
// (record flushes once a second; without that, these 21 rows, about 6 KB,
// would still be in the stream's buffer and the file would hold no row).
TEST(MagnavCli, RecordKilledLeavesItsRowsWholeInTheTemporary) {
  const std::string dir = testing::TempDir();
  const std::map<std::string, std::string> env = {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}};
  ASSERT_EQ(testing::RunCommand({kMagnav, "simulate", "--turns", "2:0.1", "--sensors", "0,0,0", "--output",
                                 dir + "/p.csv"}).first, 0);
  const GradiometerFile sent = ReadGradiometerFile(dir + "/p.csv");
  ASSERT_EQ(sent.samples.size(), 21u);
  testing::Subprocess rec({kMagnav, "record", "--topic", "gradiometer", "--output", dir + "/r.csv"}, env);
  const auto [rc, out] = testing::RunCommand({kMagnav, "replay", "--input", dir + "/p.csv", "--speed", "0"}, env);
  ASSERT_EQ(rc, 0) << out;
  std::this_thread::sleep_for(2500ms);  // two of record's once-a-second flushes
  rec.Signal(SIGKILL);
  EXPECT_EQ(rec.Wait(10s), -1);  // died of the signal
  EXPECT_FALSE(std::filesystem::exists(dir + "/r.csv"));
  std::vector<std::string> temps;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("r.csv.tmp-", 0) == 0) temps.push_back(e.path().string());
  }
  ASSERT_EQ(temps.size(), 1u);
  std::ifstream in(temps[0], std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_FALSE(text.empty());
  EXPECT_EQ(text.back(), '\n') << "a row was cut";
  const CsvTable got = CsvTable::Parse(text, temps[0]);
  ASSERT_EQ(got.num_rows(), sent.samples.size());
  for (std::size_t r = 0; r < got.num_rows(); ++r) {
    EXPECT_EQ(got.integer(r, got.column("seq")), static_cast<long long>(r));
    EXPECT_NEAR(got.number(r, got.column("t")), sent.samples[r].t_s, 1e-9);
    EXPECT_EQ(got.number(r, got.column("T12")), sent.samples[r].T(1, 2));
  }
}

}  // namespace
}  // namespace magnav
