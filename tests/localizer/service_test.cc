// magnav-localizer as a process on loopback DDS: fed the reference pass
// (magnetometer samples and GNSS fixes, merged in time order as `magnav
// replay --magnetometer --gnss` sends them) with bad samples mixed in, it
// skips and counts the bad ones (one warning per sensor), publishes for every
// sensor the estimates the library's EKF gives on the good stream, serves a
// late joiner the last estimates, and stops cleanly.
#include <signal.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include <gtest/gtest.h>

#include "localize_data.h"
#include "localizer_node.h"
#include "magnav/core/csv.h"
#include "magnav/core/units.h"
#include "magnav/dds/node.h"
#include "magnav/localizer/checkpoint.h"
#include "magnav/localizer/ekf.h"
#include "stock_relay.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::localizer {
namespace {

using namespace std::chrono_literals;
namespace msg = ::magnav::msg;

dds::NodeOptions PeerOptions(int domain) {
  dds::NodeOptions o;
  o.name = "localizer_service_test";
  o.domain_id = domain;
  return o;
}

msg::MagnetometerSample SampleMsg(const MagSample& s) {
  msg::MagnetometerSample m;
  m.sensor_id(s.sensor_id);
  m.stamp_ns(SecondsToNanos(s.t_s));
  m.B({s.B_T.x(), s.B_T.y(), s.B_T.z()});
  m.sigma_B(1e-9);
  return m;
}

msg::VesselNav FixMsg(const GnssFix& f) {
  msg::VesselNav m;
  m.stamp_ns(SecondsToNanos(f.t_s));
  m.source(msg::NAV_GNSS);
  m.position({f.p_xy_m.x(), f.p_xy_m.y(), 0.0});
  m.sigma_position({f.sigma_m, f.sigma_m, 0.0});
  return m;
}

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

TEST(LocalizerService, SkipsBadSamplesAndPublishesTheLibrarysEkfEstimates) {
  const int domain = testing::TestDomainId();
  const PassFile file = test::ReferencePass();
  testing::Subprocess service({MAGNAV_SERVICE_BIN, "--deployment", testing::ReferencePath("localize_deployment.csv"),
                               "--moment-body", "30000,2000,10000", "--vessel-z", "0", "--sigma-b", "1e-9",
                               "--publish-period", "0.5", "--stats-period", "0"},
                              {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}}, /*merge_stderr=*/true);

  // The library on the good stream as the service sees it (times through ns).
  Pass seen = file.pass;
  for (auto& s : seen.samples) s.t_s = FromMsg(SampleMsg(s)).t_s;
  for (auto& f : seen.gnss) f.t_s = FromMsg(FixMsg(f)).t_s;
  const Localization want = RunEkfBounded(seen, LocalizerOptions{});  // the service runs the bounded EKF

  std::mutex mu;
  std::map<std::uint32_t, msg::SensorPositionEstimate> last;
  std::size_t late_joiner_got = 0;
  {
    dds::Node peer(PeerOptions(domain));
    auto reader = peer.CreateReader<msg::SensorPositionEstimate>([&](const msg::SensorPositionEstimate& e, const auto&) {
      std::lock_guard<std::mutex> lk(mu);
      last[e.sensor_id()] = e;
    });
    auto samples = peer.CreateWriter<msg::MagnetometerSample>();
    auto fixes = peer.CreateWriter<msg::VesselNav>();
    samples->SetFlowControl(500, 20s);
    fixes->SetFlowControl(500, 20s);
    ASSERT_TRUE(samples->WaitForMatched(1, 20s));
    ASSERT_TRUE(fixes->WaitForMatched(1, 20s));
    ASSERT_TRUE(reader->WaitForMatched(1, 20s));
    std::size_t g = 0;
    const auto& gnss = file.pass.gnss;
    for (std::size_t i = 0; i < file.pass.samples.size(); ++i) {
      const MagSample& s = file.pass.samples[i];
      while (g < gnss.size() && gnss[g].t_s <= s.t_s) ASSERT_TRUE(fixes->Write(FixMsg(gnss[g++])));
      ASSERT_TRUE(samples->Write(SampleMsg(s)));
      if (i == 4000) {  // bad samples mid-stream: each must be skipped, none may touch the state
        MagSample nan = s;
        nan.sensor_id = 3;
        nan.B_T.y() = std::nan("");
        ASSERT_TRUE(samples->Write(SampleMsg(nan)));
        ASSERT_TRUE(samples->Write(SampleMsg(nan)));  // warned once, counted twice
        MagSample unknown = s;
        unknown.sensor_id = 42;
        ASSERT_TRUE(samples->Write(SampleMsg(unknown)));
        ASSERT_TRUE(samples->Write(SampleMsg(file.pass.samples[i - 80])));  // an exact repeat: dropped as such
        MagSample backwards = file.pass.samples[i - 80];  // sensor of row i−80, 2 s in the past, a new stamp
        backwards.t_s += 0.0005;
        ASSERT_TRUE(samples->Write(SampleMsg(backwards)));
        MagSample nT_as_T = s;  // out of range: B in nT sent as T
        nT_as_T.sensor_id = 5;
        nT_as_T.B_T *= 1e9;
        nT_as_T.B_T.z() = 45000.0;
        ASSERT_TRUE(samples->Write(SampleMsg(nT_as_T)));
        GnssFix bad_fix = gnss[g - 1];  // a new stamp (the same one would be a repeat of gnss[g - 1])
        bad_fix.t_s += 0.0005;
        bad_fix.sigma_m = 0.0;
        ASSERT_TRUE(fixes->Write(FixMsg(bad_fix)));
        GnssFix far_fix = gnss[g - 1];  // out of range: a position beyond 1e7 m
        far_fix.t_s += 0.0006;
        far_fix.p_xy_m.x() = 1e308;
        ASSERT_TRUE(fixes->Write(FixMsg(far_fix)));
      }
    }
    while (g < gnss.size()) ASSERT_TRUE(fixes->Write(FixMsg(gnss[g++])));
    ASSERT_TRUE(samples->WaitForAcknowledgments(60s));
    ASSERT_TRUE(fixes->WaitForAcknowledgments(60s));
    // A late joiner gets the last estimate of every sensor (TRANSIENT_LOCAL).
    ASSERT_TRUE(reader->WaitForSamples(8, 60s));
    {
      dds::Node late(PeerOptions(domain));
      std::atomic<std::size_t> n{0};
      auto late_reader = late.CreateReader<msg::SensorPositionEstimate>(
          [&](const msg::SensorPositionEstimate&, const auto&) { ++n; });
      for (int k = 0; k < 100 && n < 8; ++k) std::this_thread::sleep_for(100ms);
      late_joiner_got = n;
    }
    service.Signal(SIGTERM);
    EXPECT_EQ(service.Wait(30s), 0);
  }
  const std::string log = service.ReadAll();
  EXPECT_GE(late_joiner_got, 8u);
  EXPECT_EQ(Count(log, "magnetometer 3 sample"), 1) << log;   // NaN: warned once
  EXPECT_EQ(Count(log, "magnetometer 42 sample"), 1) << log;  // unknown sensor
  EXPECT_EQ(Count(log, "time goes backwards"), 1) << log;
  EXPECT_EQ(Count(log, "magnetometer 5 sample"), 1) << log;  // out of range
  EXPECT_EQ(Count(log, "value out of range"), 1) << log;     // (the GNSS stream was warned already)
  EXPECT_EQ(Count(log, "vessel_nav sample"), 1) << log;
  EXPECT_NE(log.find("7 skipped, 1 repeated"), std::string::npos) << log;  // the final line's counts

  ASSERT_EQ(last.size(), 8u) << log;
  for (const SensorEstimate& e : want.sensors) {
    SCOPED_TRACE(e.sensor_id);
    const msg::SensorPositionEstimate& m = last.at(e.sensor_id);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(m.position()[k], e.p_SinW_m[k], 1e-9);
    EXPECT_NEAR(m.covariance()[0], e.cov_xy_m2(0, 0), 1e-9 * e.cov_xy_m2(0, 0));
    EXPECT_NEAR(m.covariance()[4], e.cov_xy_m2(1, 1), 1e-9 * e.cov_xy_m2(1, 1));
    EXPECT_NEAR(m.crlb()[0], e.crlb_joint_m2(0, 0), 1e-6 * e.crlb_joint_m2(0, 0));
    EXPECT_EQ(m.stamp_ns(), SecondsToNanos(want.trajectory_t_s.back()));
  }
}

}  // namespace
}  // namespace magnav::localizer

namespace magnav::localizer {
namespace {

// The whole run through the tools: `magnav replay --magnetometer --gnss` feeds
// the service, `magnav record --topic sensor_position` keeps what it
// publishes, and the last recorded row of every sensor equals the offline
// `magnav localize --method ekf-bounded` row (the service's default method). With `stock_qos` ("default": Cyclone
// DDS's RELIABLE/VOLATILE writer; "sensor_data": ROS 2's BEST_EFFORT/VOLATILE)
// the replay goes to another domain and a Cyclone relay writes every sample
// again with that QoS to the service's, paced (replay at 200×, ≤ 20000
// samples/s): the service (and the recorders of its input) hear only a stock
// writer, and the result must be the same.
void ReplayedAndRecordedRunEqualsTheOfflineCommand(const char* stock_qos) {
  const int domain = testing::TestDomainId();
  const std::map<std::string, std::string> env = {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}};
  const std::string dir = testing::TempDir();
  const std::string m = testing::ReferencePath("localize_measurements.csv"),
                    d = testing::ReferencePath("localize_deployment.csv"),
                    g = testing::ReferencePath("localize_gnss_full.csv");
  const auto [rc, out] = testing::RunCommand({MAGNAV_BIN, "localize", "--measurements", m, "--deployment", d, "--gnss",
                                              g, "--method", "ekf-bounded", "--output", dir + "/offline.csv"},
                                             {}, 120s);
  ASSERT_EQ(rc, 0) << out;

  testing::Subprocess service({MAGNAV_SERVICE_BIN, "--deployment", d, "--moment-body", "30000,2000,10000",
                               "--vessel-z", "0", "--sigma-b", "1e-9", "--stats-period", "0"},
                              env, /*merge_stderr=*/true);
  testing::Subprocess record({MAGNAV_BIN, "record", "--topic", "sensor_position", "--output", dir + "/live.csv"}, env,
                             /*merge_stderr=*/true);
  // The input streams recorded too: the GNSS one in the file format `magnav localize --gnss` reads.
  testing::Subprocess record_nav({MAGNAV_BIN, "record", "--topic", "vessel_nav", "--count", "1111", "--output",
                                  dir + "/nav.csv"},
                                 env, /*merge_stderr=*/true);
  testing::Subprocess record_mag({MAGNAV_BIN, "record", "--topic", "magnetometer", "--count", "44432", "--output",
                                  dir + "/mag.csv"},
                                 env, /*merge_stderr=*/true);
  std::optional<testing::StockRelay> relay;
  std::vector<std::string> replay = {MAGNAV_BIN, "replay", "--magnetometer", m, "--gnss", g, "--speed", "0",
                                     "--wait-readers", "2"};
  std::map<std::string, std::string> replay_env = env;
  if (stock_qos) {
    relay.emplace(stock_qos, "magnetometer,vessel_nav", domain, 20000.0, /*readers=*/2);
    ASSERT_TRUE(relay->ready());
    replay_env["MAGNAV_DOMAIN_ID"] = std::to_string(testing::StockRelay::InputDomain(domain));
    replay[7] = "200";  // --speed: both streams in time order, as live
    replay[9] = "1";    // --wait-readers: the relay
  }
  const auto [replay_rc, replay_out] = testing::RunCommand(replay, replay_env, 120s);
  ASSERT_EQ(replay_rc, 0) << replay_out;
  if (relay) {
    int relay_rc = 0;
    const std::string relay_out = relay->Finish(60s, &relay_rc);
    ASSERT_EQ(relay_rc, 0) << relay_out;
    EXPECT_NE(relay_out.find("relayed 45543 samples"), std::string::npos) << relay_out;
  }
  EXPECT_NE(replay_out.find("replayed 44432 magnetometer samples and 1111 vessel_nav fixes"), std::string::npos)
      << replay_out;
  service.Signal(SIGTERM);
  ASSERT_EQ(service.Wait(30s), 0) << service.ReadAll();
  const std::string service_log = service.ReadAll();
  SCOPED_TRACE(service_log);
  EXPECT_NE(service_log.find(" 0 skipped"), std::string::npos);
  std::this_thread::sleep_for(1s);  // the final estimates reach the recorder
  record.Signal(SIGTERM);
  ASSERT_EQ(record.Wait(30s), 0) << record.ReadAll();
  ASSERT_EQ(record_nav.Wait(30s), 0) << record_nav.ReadAll();
  ASSERT_EQ(record_mag.Wait(30s), 0) << record_mag.ReadAll();
  {
    const CsvTable a = CsvTable::Read(g), b = CsvTable::Read(dir + "/nav.csv");
    ASSERT_EQ(b.num_rows(), a.num_rows());
    for (std::size_t i = 0; i < a.num_rows(); i += 97) {
      for (const char* c : {"t", "x", "y", "sigma"}) EXPECT_EQ(b.number(i, b.column(c)), a.number(i, a.column(c))) << c;
    }
    // Order is guaranteed per sensor only: match rows by (t, sensor_id).
    const CsvTable ma = CsvTable::Read(m), mb = CsvTable::Read(dir + "/mag.csv");
    ASSERT_EQ(mb.num_rows(), ma.num_rows());
    std::map<std::pair<double, std::uint32_t>, std::size_t> row_of;
    for (std::size_t i = 0; i < mb.num_rows(); ++i) {
      row_of[{mb.number(i, mb.column("t")), mb.uint32(i, mb.column("sensor_id"))}] = i;
    }
    for (std::size_t i = 0; i < ma.num_rows(); i += 997) {
      const auto it = row_of.find({ma.number(i, ma.column("t")), ma.uint32(i, ma.column("sensor_id"))});
      ASSERT_NE(it, row_of.end()) << "row " << i;
      for (const char* c : {"B_x", "B_y", "B_z"}) EXPECT_EQ(mb.number(it->second, mb.column(c)), ma.number(i, ma.column(c))) << c;
    }
  }

  const CsvTable offline = CsvTable::Read(dir + "/offline.csv");
  const CsvTable live = CsvTable::Read(dir + "/live.csv");
  std::map<std::uint32_t, std::size_t> last_row;
  for (std::size_t i = 0; i < live.num_rows(); ++i) last_row[live.uint32(i, live.column("sensor_id"))] = i;
  ASSERT_EQ(last_row.size(), offline.num_rows());
  for (std::size_t j = 0; j < offline.num_rows(); ++j) {
    const std::uint32_t id = offline.uint32(j, offline.column("sensor_id"));
    SCOPED_TRACE(id);
    ASSERT_TRUE(last_row.count(id));
    const std::size_t r = last_row[id];
    for (const char* c : {"x", "y", "z", "sigma_x", "sigma_y"}) {
      EXPECT_NEAR(live.number(r, live.column(c)), offline.number(j, offline.column(c)), 1e-9) << c;
    }
    for (const char* c : {"crlb_x", "crlb_y"}) {
      EXPECT_NEAR(live.number(r, live.column(c)), offline.number(j, offline.column(c)), 1e-6) << c;
    }
  }
}

TEST(LocalizerService, ReplayedAndRecordedRunEqualsTheOfflineCommand) { ReplayedAndRecordedRunEqualsTheOfflineCommand(nullptr); }

class LocalizerStockWriter : public ::testing::TestWithParam<const char*> {};

TEST_P(LocalizerStockWriter, EverySampleCountsAsFromMagnavsOwnWriter) {
  if (!testing::StockRelay::Available()) GTEST_SKIP() << "Cyclone DDS not found at configure time: no stock peer";
  ReplayedAndRecordedRunEqualsTheOfflineCommand(GetParam());
}

INSTANTIATE_TEST_SUITE_P(Qos, LocalizerStockWriter, ::testing::Values("default", "sensor_data"));

// --state-dir: a checkpoint of this configuration is resumed from; one that is
// corrupt, truncated, of another version or another configuration is refused
// with the reason, kept aside as .refused, and the service starts fresh (and
// does not crash). The restart itself: Dds.RestartAfterKill_localizer.
std::string StartWithCheckpoint(const std::string& dir, const std::string& file, bool* renamed) {
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  WriteFileAtomically(dir + "/magnav-localizer.state", file);
  testing::Subprocess service({MAGNAV_SERVICE_BIN, "--deployment", testing::ReferencePath("localize_deployment.csv"),
                               "--moment-body", "30000,2000,10000", "--vessel-z", "0", "--sigma-b", "1e-9",
                               "--stats-period", "0", "--state-dir", dir},
                              {{"MAGNAV_DOMAIN_ID", std::to_string(testing::TestDomainId())}}, /*merge_stderr=*/true);
  std::string line, log;
  while (!(line = service.ReadLine()).empty() && line.find("checkpoint") == std::string::npos) log += line;
  service.Signal(SIGTERM);
  EXPECT_EQ(service.Wait(30s), 0) << log << line << service.ReadAll();
  *renamed = std::filesystem::exists(dir + "/magnav-localizer.state.refused");
  return line;
}

TEST(LocalizerService, ResumesFromItsCheckpointAndRefusesABadOne) {
  const PassFile d = test::ReferencePass();
  StreamOptions so;
  so.bounded = true;
  so.merge = StreamMerge::kWatermark;
  auto checkpoint = [&](const Pass& pass) {
    StreamingLocalizer s(pass.vessel, pass.sensors, LocalizerOptions{}, so);
    std::size_t g = 0;
    for (std::size_t i = 0; i < 4000; ++i) {
      while (g < pass.gnss.size() && pass.gnss[g].t_s <= pass.samples[i].t_s) s.Add(pass.gnss[g++]);
      s.Add(pass.samples[i]);
    }
    return EncodeCheckpoint(s.SaveState());
  };
  const std::string good = checkpoint(d.pass);
  const std::string dir = testing::TempDir() + "/state";
  bool renamed = false;
  std::string line = StartWithCheckpoint(dir, good, &renamed);
  EXPECT_NE(line.find("resumed from checkpoint"), std::string::npos) << line;
  EXPECT_FALSE(renamed);
  // The clean stop wrote it again (still a checkpoint of this configuration).
  std::string again;
  ASSERT_TRUE(ReadWholeFile(dir + "/magnav-localizer.state", &again));
  EXPECT_NO_THROW(DecodeCheckpoint(again));

  std::string flipped = good, v2 = good;
  flipped[flipped.size() / 2] ^= 1;
  v2[8] = 2;
  Pass moved = d.pass;
  moved.sensors[0].p_SinW_m.y() += 5.0;
  const std::pair<const char*, std::string> bad[] = {
      {"corrupt: checksum mismatch", flipped},
      {"truncated", good.substr(0, good.size() / 3)},
      {"format version 2", v2},
      {"made for another deployment", checkpoint(moved)},
      {"no MAGNAVLC magic", "garbage"},
  };
  for (const auto& [why, file] : bad) {
    SCOPED_TRACE(why);
    line = StartWithCheckpoint(dir, file, &renamed);
    EXPECT_NE(line.find("refused ("), std::string::npos) << line;
    EXPECT_NE(line.find(why), std::string::npos) << line;
    EXPECT_NE(line.find("starting fresh"), std::string::npos) << line;
    EXPECT_TRUE(renamed);
  }
}

}  // namespace
}  // namespace magnav::localizer
