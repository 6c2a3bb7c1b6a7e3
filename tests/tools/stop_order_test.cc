// Stopping a live pipeline without loss (issue 23 item 2; README "Stopping a
// live pipeline"): magnav replay -> magnav-inverter and magnav-tracker ->
// magnav record, stopped in the README's order (the producer ends, then the
// services by SIGTERM in data order, the recorder last). The services exit 0
// and the recording holds everything they produced: every fix of the pass
// and every track estimate, the tracker's last ones (held in its buffers
// until it stops) included, equal to what the offline commands give for the
// same pass.
#include <chrono>
#include <cmath>
#include <csignal>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav {
namespace {

using namespace std::chrono_literals;

TEST(StopOrder, ServicesStoppedBySigtermBeforeTheRecorderLoseNothing) {
  const std::string dir = testing::TempDir();
  const std::string pass = testing::ReferencePath("track_pass_auv_1sensor_squid.csv");
  const std::string b0 = "2e-05,1e-06,4.5e-05";  // the pass's B0 (its header)
  const std::map<std::string, std::string> env = {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}};

  // What the offline commands give for the pass (the services' defaults).
  ASSERT_EQ(testing::RunCommand({MAGNAV_BIN, "invert", "--input", pass, "--b0", b0, "--method", "ted-egt", "--output",
                                 dir + "/offline_fixes.csv"})
                .first,
            0);
  ASSERT_EQ(testing::RunCommand({MAGNAV_BIN, "track", "--input", pass, "--b0", b0, "--mode", "window", "--output",
                                 dir + "/offline_track.csv"})
                .first,
            0);

  testing::Subprocess recorder({MAGNAV_BIN, "record", "--topic", "dipole_fix,track", "--output-dir", dir + "/live"},
                               env, true);
  testing::Subprocess inverter({MAGNAV_INVERTER_BIN, "--b0", b0, "--stats-period", "0"}, env, true);
  testing::Subprocess tracker({MAGNAV_TRACKER_BIN, "--b0", b0, "--stats-period", "0"}, env, true);
  std::this_thread::sleep_for(1500ms);  // the recorder discovers the services' writers (replay waits for its readers)
  const auto [rc, out] = testing::RunCommand(
      {MAGNAV_BIN, "replay", "--input", pass, "--speed", "0", "--wait-readers", "2"}, env, 60s);
  ASSERT_EQ(rc, 0) << out;
  EXPECT_EQ(out.find("warning"), std::string::npos) << out;  // every sample acknowledged by both services

  // The README's order: the producer has ended; the services, each after the
  // one that feeds it; the recorder last.
  inverter.Signal(SIGTERM);
  ASSERT_EQ(inverter.Wait(20s), 0) << inverter.ReadAll();
  tracker.Signal(SIGTERM);
  ASSERT_EQ(tracker.Wait(20s), 0) << tracker.ReadAll();
  recorder.Signal(SIGTERM);
  ASSERT_EQ(recorder.Wait(20s), 0) << recorder.ReadAll();

  // Every fix: one per sample, as offline.
  const CsvTable fixes = CsvTable::Read(dir + "/live/dipole_fix.csv");
  const CsvTable offline_fixes = CsvTable::Read(dir + "/offline_fixes.csv");
  EXPECT_EQ(fixes.num_rows(), offline_fixes.num_rows());
  EXPECT_EQ(fixes.num_rows(), 2001u);

  // Every track estimate, in order, the last ones included, equal to the
  // offline track (to floating-point noise: 3e-7 m seen).
  const CsvTable live = CsvTable::Read(dir + "/live/track.csv");
  const CsvTable offline = CsvTable::Read(dir + "/offline_track.csv");
  ASSERT_GT(offline.num_rows(), 1000u);
  ASSERT_EQ(live.num_rows(), offline.num_rows()) << "the recording lost estimates (the last at t = "
                                                 << (live.num_rows() ? live.text(live.num_rows() - 1, live.column("t"))
                                                                     : std::string_view("none"))
                                                 << " s)";
  for (std::size_t i = 0; i < live.num_rows(); ++i) {
    ASSERT_NEAR(live.number(i, live.column("t")), offline.number(i, offline.column("t")), 1e-9) << i;
    ASSERT_EQ(live.integer(i, live.column("track_id")), offline.integer(i, offline.column("track_id"))) << i;
    for (const char* c : {"x", "y", "z"}) {
      ASSERT_NEAR(live.number(i, live.column(c)), offline.number(i, offline.column(c)), 1e-5) << i << " " << c;
    }
  }
}

}  // namespace
}  // namespace magnav
