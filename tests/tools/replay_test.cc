// `magnav replay --loop`: a file replayed over and over until stopped, each
// pass shifted in time by the file's span, so a consumer sees time going
// forward and more samples than the file holds; SIGTERM stops it cleanly.
// `magnav record` of several topics at once into a directory; a recorded CSV
// replayed.
#include <signal.h>

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav {
namespace {

using namespace std::chrono_literals;
const std::string kMagnav = MAGNAV_BIN;

TEST(Replay, LoopKeepsTimeGoingForwardUntilStopped) {
  const std::string dir = testing::TempDir();
  ASSERT_EQ(testing::RunCommand({kMagnav, "simulate", "--turns", "2:0", "--output", dir + "/p.csv"}).first, 0);
  const std::map<std::string, std::string> env = {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}};
  testing::Subprocess record({kMagnav, "record", "--topic", "gradiometer", "--count", "60", "--duration", "60",
                              "--output", dir + "/rec.csv"},
                             env);
  testing::Subprocess replay(
      {kMagnav, "replay", "--input", dir + "/p.csv", "--loop", "--speed", "20", "--wait-readers", "1"}, env, true);
  EXPECT_EQ(record.Wait(60s), 0);
  replay.Signal(SIGTERM);
  EXPECT_EQ(replay.Wait(20s), 0);
  const std::string log = replay.ReadAll();
  EXPECT_NE(log.find("replayed "), std::string::npos) << log;
  const CsvTable t = CsvTable::Read(dir + "/rec.csv");
  ASSERT_EQ(t.num_rows(), 60u);  // the file has 21 (t = 0 .. 2 s at 10 Hz)
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    EXPECT_NEAR(t.number(i, t.column("t")), 0.1 * static_cast<double>(i), 1e-9) << i;  // 2.0 s, then 2.1 s, ...
  }
  // --loop is for gradiometer files only.
  const auto [rc, out] = testing::RunCommand(
      {kMagnav, "replay", "--map-path", testing::ReferencePath("mappath_crustal_off0p01deg_noise0p5nT.csv"),
       "--reference-field", "47693", "--loop"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("--loop goes with --input"), std::string::npos) << out;
}

// A CSV recording's gradiometer file is a replay input as it is (its extra
// seq, sigma_B and sigma_T columns are ignored): recorded again, every sample
// comes back with the same time, sensor and values.
TEST(Replay, ARecordedCsvReplaysAsItWasRecorded) {
  const std::string dir = testing::TempDir();
  ASSERT_EQ(testing::RunCommand({kMagnav, "simulate", "--turns", "2:0", "--output", dir + "/p.csv"}).first, 0);
  const std::map<std::string, std::string> env = {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}};
  for (const char* pass : {"1", "2"}) {
    testing::Subprocess record({kMagnav, "record", "--topic", "gradiometer", "--count", "21", "--duration", "60",
                                "--output", dir + "/rec" + pass + ".csv"},
                               env, true);
    const std::string input = std::string(pass) == "1" ? dir + "/p.csv" : dir + "/rec1.csv";
    const auto [rc, out] =
        testing::RunCommand({kMagnav, "replay", "--input", input, "--speed", "0", "--wait-readers", "1"}, env);
    ASSERT_EQ(rc, 0) << out;
    ASSERT_EQ(record.Wait(60s), 0) << record.ReadAll();
  }
  const CsvTable a = CsvTable::Read(dir + "/rec1.csv");
  const CsvTable b = CsvTable::Read(dir + "/rec2.csv");
  ASSERT_EQ(a.num_rows(), 21u);
  ASSERT_EQ(b.num_rows(), a.num_rows());
  for (const char* c : {"t", "sensor_id", "B_x", "B_z", "T00", "T12", "T22", "sensor_x"}) {
    for (std::size_t i = 0; i < a.num_rows(); ++i) {
      EXPECT_EQ(a.number(i, a.column(c)), b.number(i, b.column(c))) << c << " row " << i;
    }
  }
}

TEST(Record, SeveralTopicsIntoADirectory) {
  const std::string dir = testing::TempDir();
  const std::map<std::string, std::string> env = {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}};
  testing::Subprocess record({kMagnav, "record", "--topic", "magnetometer,vessel_nav", "--output-dir", dir + "/rec",
                              "--count", "150", "--duration", "60"},
                             env, true);
  const auto [rc, out] = testing::RunCommand(
      {kMagnav, "replay", "--map-path", testing::ReferencePath("mappath_crustal_off0p01deg_noise0p5nT.csv"),
       "--reference-field", "47693.77", "--step-period", "0.01", "--wait-readers", "1"},
      env);
  ASSERT_EQ(rc, 0) << out;
  EXPECT_EQ(record.Wait(60s), 0);
  const std::string log = record.ReadAll();
  EXPECT_NE(log.find("recorded 150 magnetometer sample(s)"), std::string::npos) << log;
  EXPECT_NE(log.find("recorded 150 vessel_nav sample(s)"), std::string::npos) << log;
  EXPECT_EQ(CsvTable::Read(dir + "/rec/magnetometer.csv").num_rows(), 150u);
  EXPECT_EQ(CsvTable::Read(dir + "/rec/vessel_nav.csv").num_rows(), 150u);
  // Several topics need a directory.
  const auto [rc2, out2] = testing::RunCommand({kMagnav, "record", "--topic", "track", "--topic", "map_fix"});
  EXPECT_EQ(rc2, 2);
  EXPECT_NE(out2.find("several topics need --output-dir"), std::string::npos) << out2;
}

}  // namespace
}  // namespace magnav
