// magnav-tracker as a process on loopback DDS: fed a reference pass, it
// publishes exactly the estimates the library's MultiTracker gives for the
// same samples, they follow the truth, and it stops cleanly; with
// --init-from dipole_fix it starts from the fixes it receives; on a field
// crossed by two vessels it publishes two tracks with their own ids.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "magnav/cli/scenario_file.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/units.h"
#include "magnav/dds/convert.h"
#include "magnav/dds/node.h"
#include "magnav/inversion/inverter.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"
#include "tracker_node.h"
#include "two_vessels.h"
#include "stock_relay.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::tracker {
namespace {

using namespace std::chrono_literals;
namespace msg = ::magnav::msg;

// RMS of the 3-D position error over the estimates within 30 m horizontal
// range of a 1-sensor pass's sensor (at the origin), and how many there were.
std::pair<double, int> RmsWithin30m(const std::vector<msg::TrackEstimate>& got, const std::string& vessel) {
  const CsvTable truth = CsvTable::Read(testing::ReferencePath("track_truth_" + vessel + ".csv"));
  double sum = 0;
  int n = 0;
  for (const auto& e : got) {
    const std::size_t row = static_cast<std::size_t>(std::llround(NanosToSeconds(e.stamp_ns()) * 10.0));
    const Eigen::Vector3d p_true(truth.number(row, truth.column("x")), truth.number(row, truth.column("y")),
                                 truth.number(row, truth.column("z")));
    if (p_true.head<2>().norm() > 30.0) continue;
    sum += (Eigen::Vector3d(e.position()[0], e.position()[1], e.position()[2]) - p_true).squaredNorm();
    ++n;
  }
  return {n > 0 ? std::sqrt(sum / n) : 0.0, n};
}

// The test's side of the exchange, on `domain`: records every TrackEstimate
// the service publishes and writes samples to it (unpaced, with the adapter's
// flow control: without it a burst longer than the keep-last history of 1000
// overwrites samples the service has not taken yet, its listeners waiting
// while the tracker solves).
// With `write_domain` the samples go to that domain (a StockRelay carries
// them on to the service's).
struct TestPeer {
  explicit TestPeer(int domain, std::optional<int> write_domain = std::nullopt) : node(Options(domain)) {
    reader = node.CreateReader<msg::TrackEstimate>([this](const msg::TrackEstimate& e, const auto&) {
      std::lock_guard<std::mutex> lk(mu);
      got.push_back(e);
    });
    if (write_domain) in_node = std::make_unique<dds::Node>(Options(*write_domain));
    writer = (in_node ? *in_node : node).CreateWriter<msg::GradiometerSample>();
    writer->SetFlowControl(500, 20s);
  }
  static dds::NodeOptions Options(int domain) {
    dds::NodeOptions o;
    o.name = "tracker_service_test";
    o.domain_id = domain;
    return o;
  }
  std::vector<msg::TrackEstimate> Got() {
    std::lock_guard<std::mutex> lk(mu);
    return got;
  }
  // Writes the pass, waits for the `expected` estimates (the last 0.25 s stay
  // in the service's reorder buffer until it stops), stops the service (exit
  // 0 expected) and returns what arrived.
  std::vector<msg::TrackEstimate> SendPassAndStop(const GradiometerFile& file, std::size_t expected,
                                                  testing::Subprocess* service) {
    return SendAndStop(file.samples, expected, service);
  }
  std::vector<msg::TrackEstimate> SendAndStop(const std::vector<GradiometerSample>& samples, std::size_t expected,
                                              testing::Subprocess* service) {
    for (std::size_t i = 0; i < samples.size(); ++i) EXPECT_TRUE(writer->Write(dds::ToMsg(samples[i], i)));
    if (writer) {  // (none once a relayed run closed its input)
      EXPECT_TRUE(writer->WaitForAcknowledgments(30s));
    }
    if (expected > 5) {
      EXPECT_TRUE(reader->WaitForSamples(expected - 5, 60s)) << reader->stats().samples.load();
    }
    service->Signal(SIGTERM);
    EXPECT_EQ(service->Wait(20s), 0);
    reader->WaitForSamples(expected, 5s);
    return Got();
  }

  dds::Node node;
  std::unique_ptr<dds::Node> in_node;  // the samples' domain, when relayed
  std::mutex mu;
  std::vector<msg::TrackEstimate> got;
  std::unique_ptr<dds::Reader<msg::TrackEstimate>> reader;
  std::unique_ptr<dds::Writer<msg::GradiometerSample>> writer;
};

// The library's estimates for samples as the service sees them: through the
// message, B0 subtracted by the node (the tracker runs with B0 = 0), `fixes`
// handed in before the samples; no back-filled start rows, as the node
// (TrackManagementOptions::backfill_start off: tracker_node.h).
std::vector<TrackOutput> LibraryTracks(const std::vector<GradiometerSample>& samples, const Eigen::Vector3d& B0,
                                       const MultiTrackerOptions& options = MultiTrackerOptions{},
                                       const std::vector<DipoleFix>& fixes = {}) {
  MultiTrackerOptions live = options;
  live.management.backfill_start = false;
  MultiTracker lib(Eigen::Vector3d::Zero(), live);
  for (const auto& f : fixes) lib.AddFix(f);
  std::vector<TrackOutput> want;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    GradiometerSample s = dds::FromMsg(dds::ToMsg(samples[i], i));
    if (CheckSample(s) != SampleDefect::kNone) continue;  // the node's door
    s.B -= B0;
    for (auto& e : lib.AddSample(s)) want.push_back(e);
  }
  for (auto& e : lib.Flush()) want.push_back(e);
  return want;
}

// Every published estimate equals the library's, in order.
void ExpectSameEstimates(const std::vector<msg::TrackEstimate>& got, const std::vector<TrackOutput>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    const EpochEstimate& w = want[i].estimate;
    EXPECT_EQ(got[i].track_id(), want[i].track_id) << i;
    EXPECT_EQ(got[i].stamp_ns(), SecondsToNanos(w.t_s)) << i;
    for (int k = 0; k < 3; ++k) ASSERT_EQ(got[i].position()[k], w.p_VinW[k]) << i;
    EXPECT_EQ(got[i].heading(), w.heading_rad) << i;
    EXPECT_EQ(got[i].usable(), w.usable) << i;
    EXPECT_EQ(got[i].state(), want[i].state == TrackState::kCoasting ? msg::TRACK_STATE_COASTING
                                                                     : msg::TRACK_STATE_CONFIRMED)
        << i;
    if (w.usable && w.has_covariance) {
      EXPECT_EQ(got[i].covariance()[0], w.cov_state(0, 0)) << i;
    }
    for (int k = 0; k < 3; ++k) EXPECT_EQ(got[i].moment_body()[k], want[i].m_B_Am2[k]) << i;
  }
}

// Runs magnav-tracker (the reference B0 and `extra` flags) on a fresh
// domain, sends `samples`, waits for `expected` estimates, stops it: what
// arrived and its log.
std::pair<std::vector<msg::TrackEstimate>, std::string> RunService(const std::vector<GradiometerSample>& samples,
                                                                   std::size_t expected,
                                                                   const std::vector<std::string>& extra = {}) {
  const int domain = testing::TestDomainId();
  std::vector<std::string> argv = {MAGNAV_SERVICE_BIN, "--b0", "2e-05,1e-06,4.5e-05", "--stats-period", "0"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  testing::Subprocess service(argv, {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}}, /*merge_stderr=*/true);
  std::vector<msg::TrackEstimate> got;
  {
    TestPeer peer(domain);
    EXPECT_TRUE(peer.writer->WaitForMatched(1, 20s));
    EXPECT_TRUE(peer.reader->WaitForMatched(1, 20s));
    got = peer.SendAndStop(samples, expected, &service);
  }
  return {got, service.ReadAll()};
}

TEST(TrackerService, PublishesTheLibraryEstimatesForAPass) {
  const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  const std::vector<TrackOutput> want = LibraryTracks(file.samples, *file.B0);
  ASSERT_GT(want.size(), 1000u);
  const auto [got, log] = RunService(file.samples, want.size());
  EXPECT_NE(log.find("track 1 started"), std::string::npos) << log;
  ExpectSameEstimates(got, want);
  EXPECT_EQ(want.front().track_id, 1u);
  EXPECT_EQ(want.back().track_id, 1u);
  // And they follow the truth near the sensor (issue 4: window figures; the
  // batch target 0.3 m RMS for fluxgate applies here too).
  const auto [rms, n] = RmsWithin30m(got, "ship");
  ASSERT_GT(n, 300);
  EXPECT_LT(rms, 0.3);
}

// A stock driver's writer (Cyclone DDS's default RELIABLE/VOLATILE QoS, or ROS
// 2's sensor-data BEST_EFFORT/VOLATILE), paced at 2000 samples/s, feeds the
// service: it publishes exactly the library's estimates for every sample, as
// it does for magnav's own writer (the service's readers once refused both:
// "incompatible QoS").
class TrackerStockWriter : public ::testing::TestWithParam<const char*> {};

TEST_P(TrackerStockWriter, EverySampleGivesTheLibrarysEstimates) {
  if (!testing::StockRelay::Available()) GTEST_SKIP() << "Cyclone DDS not found at configure time: no stock peer";
  const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  const std::vector<TrackOutput> want = LibraryTracks(file.samples, *file.B0);
  ASSERT_GT(want.size(), 1000u);
  const int domain = testing::TestDomainId();
  testing::Subprocess service({MAGNAV_SERVICE_BIN, "--b0", "2e-05,1e-06,4.5e-05", "--stats-period", "0"},
                              {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}}, /*merge_stderr=*/true);
  testing::StockRelay relay(GetParam(), "gradiometer", domain, 2000.0);
  ASSERT_TRUE(relay.ready());
  std::vector<msg::TrackEstimate> got;
  int rc = 0;
  std::string relay_log;
  {
    TestPeer peer(domain, testing::StockRelay::InputDomain(domain));
    EXPECT_TRUE(peer.writer->WaitForMatched(1, 20s));
    EXPECT_TRUE(peer.reader->WaitForMatched(1, 20s));
    for (std::size_t i = 0; i < file.samples.size(); ++i) {
      EXPECT_TRUE(peer.writer->Write(dds::ToMsg(file.samples[i], i)));
    }
    EXPECT_TRUE(peer.writer->WaitForAcknowledgments(30s));  // by the relay: it may still hold the last ones
    // The relay's input closes: it hands on what it holds and ends (tests/interop/cyclone_peer.c),
    // so every sample has left it before the service is stopped. (Stopped while the relay still held
    // the last sample, the service gave one estimate fewer: 1564 of 1565, on a loaded machine.)
    peer.writer.reset();
    peer.in_node.reset();
    relay_log = relay.Finish(30s, &rc);
    got = peer.SendAndStop({}, want.size(), &service);
  }
  EXPECT_EQ(rc, 0) << relay_log;
  EXPECT_NE(relay_log.find("relayed 2001 samples"), std::string::npos) << relay_log;
  const std::string log = service.ReadAll();
  EXPECT_EQ(log.find("incompatible QoS"), std::string::npos) << log;
  ExpectSameEstimates(got, want);
}

INSTANTIATE_TEST_SUITE_P(Qos, TrackerStockWriter, ::testing::Values("default", "sensor_data"));


// With --init-from dipole_fix the service starts its track only from the
// fixes it receives on magnav/dipole_fix (here the inverter library's on the
// same samples, rejected ones included, as magnav-inverter publishes them),
// skips a fix it cannot use and goes on. All fixes are sent before the
// samples (an inverter running ahead), so the order in which the two streams
// reach the tracker is fixed and its estimates are exactly the library's fed
// the same way (interleaved order: tracker_initialize_test). Its own fixes
// would start the track at 55 s; the inverter's first valid fix is at 68.5 s.
TEST(TrackerService, StartsFromTheInvertersFixes) {
  const int domain = testing::TestDomainId();
  const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  testing::Subprocess service({MAGNAV_SERVICE_BIN, "--b0", "2e-05,1e-06,4.5e-05", "--stats-period", "0",
                               "--init-from", "dipole_fix"},
                              {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}}, /*merge_stderr=*/true);
  inversion::InverterOptions io;
  io.B0_W = *file.B0;
  inversion::Inverter inverter(io);
  std::vector<msg::DipoleFix> fixes;
  msg::DipoleFix bad;  // claims to be valid, has no position
  bad.valid(true);
  bad.position({std::nan(""), 0.0, 0.0});
  fixes.push_back(bad);
  double first_valid_t = -1.0;
  for (std::size_t i = 0; i < file.samples.size(); ++i) {
    const inversion::DipoleFix f = inverter.Process(file.samples[i]);
    msg::DipoleFix m;
    m.sensor_id(f.sensor_id);
    m.stamp_ns(SecondsToNanos(file.samples[i].t_s));
    m.sample_seq(i);
    m.valid(f.valid);
    m.position({f.p_DinW.x(), f.p_DinW.y(), f.p_DinW.z()});
    fixes.push_back(m);
    if (f.valid && first_valid_t < 0) first_valid_t = file.samples[i].t_s;
  }
  ASSERT_GT(first_valid_t, 60.0);
  // The library fed the same way, through the messages.
  MultiTrackerOptions options;
  options.track.init.source = InitSource::kExternal;
  EXPECT_THROW(MultiTracker(Eigen::Vector3d::Zero(), options).AddFix(FromMsg(fixes[0])), InputError);
  std::vector<DipoleFix> lib_fixes;
  for (std::size_t i = 1; i < fixes.size(); ++i) lib_fixes.push_back(FromMsg(fixes[i]));
  const std::vector<TrackOutput> want = LibraryTracks(file.samples, *file.B0, options, lib_fixes);
  ASSERT_GT(want.size(), 1000u);
  EXPECT_GT(want.front().estimate.t_s, first_valid_t);

  std::vector<msg::TrackEstimate> got;
  {
    TestPeer peer(domain);
    auto fix_writer = peer.node.CreateWriter<msg::DipoleFix>();
    fix_writer->SetFlowControl(500, 20s);
    ASSERT_TRUE(fix_writer->WaitForMatched(1, 20s));
    ASSERT_TRUE(peer.writer->WaitForMatched(1, 20s));
    ASSERT_TRUE(peer.reader->WaitForMatched(1, 20s));
    for (const auto& f : fixes) ASSERT_TRUE(fix_writer->Write(f));
    ASSERT_TRUE(fix_writer->WaitForAcknowledgments(30s));
    got = peer.SendPassAndStop(file, want.size(), &service);
  }
  const std::string log = service.ReadAll();
  // "track 1 started at t = ... s (confirmed (tentative since ... s); from N dipole_fix fixes)"
  EXPECT_NE(log.find("dipole_fix fixes"), std::string::npos) << log;
  EXPECT_NE(log.find("track 1 started"), std::string::npos) << log;
  EXPECT_NE(log.find("dipole_fix skipped"), std::string::npos) << log;
  ExpectSameEstimates(got, want);
  const auto [rms, n] = RmsWithin30m(got, "ship");
  ASSERT_GT(n, 300);
  EXPECT_LT(rms, 0.3);
}

// A NaN sample, an infinite σ and a dead tensor mid-pass (the review's NaN at
// t = 100 s made the track coast 24 m off while claiming σ 0.6 m): skipped at
// the door, logged, and the track is the library's without those samples;
// after them it stays within a small part of its σ of the clean pass's track.
TEST(TrackerService, BadSamplesMidPassDoNotPoisonTheTrack) {
  const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  std::vector<GradiometerSample> input = file.samples, without;
  input[1000].B.x() = std::nan("");                               // t = 100.0 s
  input[1005].sigma_T = std::numeric_limits<double>::infinity();  // t = 100.5 s
  input[1010].T.setZero();                                        // t = 101.0 s
  for (const auto& s : input) {
    if (CheckSample(s) == SampleDefect::kNone) without.push_back(s);
  }
  ASSERT_EQ(without.size() + 3, input.size());
  const std::vector<TrackOutput> want = LibraryTracks(without, *file.B0);
  const std::vector<TrackOutput> clean = LibraryTracks(file.samples, *file.B0);
  const auto [got, log] = RunService(input, want.size());
  for (const char* defect : {"non_finite", "bad_sigma", "zero_tensor"}) {
    EXPECT_NE(log.find(std::string("skipped: ") + defect), std::string::npos) << log;
  }
  ExpectSameEstimates(got, want);
  std::size_t j = 0;
  double worst_z = 0.0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    const EpochEstimate& w = want[i].estimate;
    EXPECT_TRUE(got[i].usable()) << i;
    while (j + 1 < clean.size() && clean[j].estimate.t_s < w.t_s) ++j;
    const double sigma = std::sqrt(w.cov_p_W().trace());
    worst_z = std::max(worst_z, (w.p_VinW - clean[j].estimate.p_VinW).norm() / sigma);
  }
  EXPECT_LT(worst_z, 1.0);  // measured 0.56: three epochs of the turn left out
  const auto [rms, n] = RmsWithin30m(got, "ship");
  ASSERT_GT(n, 300);
  EXPECT_LT(rms, 0.3);
}

// The field scores (track_metrics.h) of the estimates that arrived over the
// wire, against the scenario's truth.
testing::FieldScores ScoreWire(const FieldScenario& sc, const SimulatedField& field,
                               const std::vector<msg::TrackEstimate>& got) {
  std::vector<std::pair<std::uint32_t, EpochEstimate>> rows;
  for (const auto& m : got) {
    EpochEstimate e;
    e.t_s = NanosToSeconds(m.stamp_ns());
    e.p_VinW = {m.position()[0], m.position()[1], m.position()[2]};
    rows.emplace_back(m.track_id(), e);
  }
  return testing::ScoreField(sc, field, rows);
}

// Two vessels cross a 3x3 field at once (two_vessels.h, held out): the
// service publishes two tracks with distinct ids, logs their starts and
// ends, and every estimate is the library's MultiTracker's; each track
// follows its vessel.
TEST(TrackerService, TwoVesselsGetTwoTracks) {
  const FieldScenario sc = testing::TwoVesselScenario();
  const SimulatedField field = SimulateField(sc);
  const std::vector<TrackOutput> want = LibraryTracks(field.samples, sc.B0);
  ASSERT_GT(want.size(), 1000u);
  const auto [got, log] = RunService(field.samples, want.size());
  EXPECT_NE(log.find("track 1 started"), std::string::npos) << log;
  EXPECT_NE(log.find("track 2 started"), std::string::npos) << log;
  EXPECT_NE(log.find("track 1 ended"), std::string::npos) << log;
  EXPECT_NE(log.find("track 2 ended"), std::string::npos) << log;
  ExpectSameEstimates(got, want);
  // Scored against the truth from what arrived over the wire.
  const testing::FieldScores s = ScoreWire(sc, field, got);
  EXPECT_EQ(s.false_rows, 0u);
  ASSERT_EQ(s.ids.size(), 2u);
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_EQ(s.ids[1], 1u);
  EXPECT_NE(s.rows_by_id[0].begin()->first, s.rows_by_id[1].begin()->first);
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_GE(s.coverage[v], 0.85) << "vessel " << v;  // the library's window figures (tracker_multi_test)
    EXPECT_LE(s.rms[v], 0.04) << "vessel " << v;
  }
}

// Two AUVs abreast 24 m apart (the held-out scenario
// tests/data/generated/scenarios/heldout/abreast.toml, issue 24 "What it must
// show"): the service publishes two tracks, one per vessel, every estimate
// the library's MultiTracker's; scored against the truth from what arrived
// over the wire, purity and RMS against the targets (one id per
// vessel, RMS <= 0.3 m) and coverage >= 0.8: the library's window figure is
// 0.873 / 0.873 since the approach starts and the pair refit (0.784 before,
// when this asserted only >= 0.65; docs/ACCURACY.md, "Abreast from when they
// come within reach").
TEST(TrackerService, TwoVesselsAbreastGetTwoTracks) {
  const FieldScenario sc =
      cli::ReadScenarioFile(testing::TestDataDir() + "/generated/scenarios/heldout/abreast.toml");
  ASSERT_EQ(sc.B0, Eigen::Vector3d(2e-05, 1e-06, 4.5e-05));  // RunService's --b0
  const SimulatedField field = SimulateField(sc);
  const std::vector<TrackOutput> want = LibraryTracks(field.samples, sc.B0);
  ASSERT_GT(want.size(), 1000u);
  const auto [got, log] = RunService(field.samples, want.size());
  EXPECT_NE(log.find("track 1 started"), std::string::npos) << log;
  EXPECT_NE(log.find("track 2 started"), std::string::npos) << log;
  ExpectSameEstimates(got, want);
  const testing::FieldScores s = ScoreWire(sc, field, got);
  testing::PrintFieldScores("held-out abreast, magnav-tracker", s);
  EXPECT_LE(static_cast<double>(s.false_rows), 0.05 * static_cast<double>(s.rows));
  ASSERT_EQ(s.ids.size(), 2u);
  EXPECT_EQ(s.ids[0], 1u);
  EXPECT_EQ(s.ids[1], 1u);
  EXPECT_NE(s.rows_by_id[0].begin()->first, s.rows_by_id[1].begin()->first);
  for (std::size_t v = 0; v < 2; ++v) {
    int n = 0, most = 0;  // purity: the share of the vessel's rows under its main id
    for (const auto& [id, k] : s.rows_by_id[v]) {
      n += k;
      most = std::max(most, k);
    }
    ASSERT_GT(n, 0) << "vessel " << v;
    EXPECT_GE(static_cast<double>(most) / n, 0.95) << "vessel " << v;
    EXPECT_LE(s.rms[v], 0.3) << "vessel " << v;
    EXPECT_GE(s.coverage[v], 0.8) << "vessel " << v;  // the target; the library's 0.873
  }
}

// A tracker running for weeks keeps the estimates of only the last
// --kept-ended-tracks ended tracks (default 10) in its writer's history
// (KEEP_LAST 1000 per track; older ended ones are unregistered): a consumer
// that starts late gets those and the live track, not every track since the
// start. Found by the soak (bench/soak.sh, docs/BENCHMARKS.md): with the last
// 50 ended tracks kept, the service's memory grew by ~0.45 MB per track for
// 50 tracks (35 -> 62 MB over 6 h of a field crossed every 6 min). Here 1 is
// kept, so that 3 passes suffice (each takes the service ~8 s on the shared
// 2-core machine): the ship's pass 3 times makes tracks 1..3; the late reader
// must see 2 (ended) and 3 (live), not 1. The end rule beyond the reach
// (out_of_reach_s, on by default since 2026-11-26) would end track 3 too
// before the data end (then only 3 is seen); it is turned off here so that
// a track is still live, as this test needs.
TEST(TrackerService, ALateConsumerGetsOnlyTheLastEndedTracksAndTheLiveOne) {
  EXPECT_EQ(TrackerNodeOptions{}.kept_ended_tracks, 10);
  const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  const double span = file.samples.back().t_s - file.samples.front().t_s + 60.0;  // 60 s without a sample between passes
  constexpr int kPasses = 3, kKept = 1;
  std::vector<GradiometerSample> samples;
  for (int k = 0; k < kPasses; ++k) {
    for (GradiometerSample s : file.samples) {
      s.t_s += k * span;
      samples.push_back(s);
    }
  }
  const int domain = testing::TestDomainId();
  testing::Subprocess service({MAGNAV_SERVICE_BIN, "--b0", "2e-05,1e-06,4.5e-05", "--stats-period", "0",
                               "--kept-ended-tracks", std::to_string(kKept), "--out-of-reach", "0"},
                              {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}}, /*merge_stderr=*/true);
  TestPeer peer(domain);
  ASSERT_TRUE(peer.writer->WaitForMatched(1, 20s));
  ASSERT_TRUE(peer.reader->WaitForMatched(1, 20s));
  for (std::size_t i = 0; i < samples.size(); ++i) ASSERT_TRUE(peer.writer->Write(dds::ToMsg(samples[i], i)));
  ASSERT_TRUE(peer.writer->WaitForAcknowledgments(60s));
  // Until the estimates stop coming (the service has taken every sample).
  for (std::uint64_t n = 0, m = 1; n != m;) {
    n = peer.reader->stats().samples.load();
    std::this_thread::sleep_for(1s);
    m = peer.reader->stats().samples.load();
  }
  std::set<std::uint32_t> all;
  for (const auto& e : peer.Got()) all.insert(e.track_id());
  ASSERT_EQ(all.size(), static_cast<std::size_t>(kPasses)) << service.ReadAll();

  std::mutex mu;
  std::set<std::uint32_t> late;
  dds::Node late_node(TestPeer::Options(domain));
  auto late_reader = late_node.CreateReader<msg::TrackEstimate>([&](const msg::TrackEstimate& e, const auto&) {
    std::lock_guard<std::mutex> lk(mu);
    late.insert(e.track_id());
  });
  ASSERT_TRUE(late_reader->WaitForMatched(1, 20s));
  // The history arrives (up to 1000 per track kept); then nothing more.
  for (std::uint64_t n = 0, m = 1; n != m;) {
    n = late_reader->stats().samples.load();
    std::this_thread::sleep_for(2s);
    m = late_reader->stats().samples.load();
  }
  service.Signal(SIGTERM);
  EXPECT_EQ(service.Wait(20s), 0);
  std::lock_guard<std::mutex> lk(mu);
  EXPECT_EQ(late, (std::set<std::uint32_t>{2, 3}));
}

// Without --b0 the service refuses to start. With --b0 estimate it estimates
// each sensor's B0 from its quiet stretches and says so. On the AUV fluxgate
// pass (quiet start) that B0 is 1.1 nT off (the AUV's own field 111 m away),
// and the window track, which leans on B at this noise level, degrades from
// 0.11 m to 0.60 m RMS — measured and asserted here, stated in
// tracker/README.md (joint estimation of B0 in the tracker is not done). On
// the ship SQUID pass (never quiet) there is no B0, so no track — rather than
// one made with B0 = 0.
TEST(TrackerService, B0IsGivenOrEstimatedNeverAssumed) {
  {
    const auto [rc, out] = testing::RunCommand({MAGNAV_SERVICE_BIN, "--stats-period", "0"});
    EXPECT_EQ(rc, 2);
    EXPECT_NE(out.find("--b0 estimate"), std::string::npos) << out;
  }
  const GradiometerFile auv = ReadGradiometerFile(testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv"));
  const std::vector<TrackOutput> known = LibraryTracks(auv.samples, *auv.B0);
  // 340 with the default end rule beyond the reach (since 2026-11-26: the
  // track ends 2 s out of reach), 5xx before.
  ASSERT_GT(known.size(), 300u);
  {
    const int domain = testing::TestDomainId();
    testing::Subprocess service({MAGNAV_SERVICE_BIN, "--b0", "estimate", "--stats-period", "0"},
                                {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}}, /*merge_stderr=*/true);
    std::vector<msg::TrackEstimate> got;
    {
      TestPeer peer(domain);
      ASSERT_TRUE(peer.writer->WaitForMatched(1, 20s));
      ASSERT_TRUE(peer.reader->WaitForMatched(1, 20s));
      // Waits for half the true-B0 run's count: with B0 off by 1 nT the
      // track is shorter (ended by misses sooner); what matters is below.
      got = peer.SendPassAndStop(auv, known.size() / 2, &service);
    }
    const std::string log = service.ReadAll();
    EXPECT_NE(log.find("estimated per sensor"), std::string::npos) << log;
    EXPECT_NE(log.find("B0 estimated"), std::string::npos) << log;
    std::vector<msg::TrackEstimate> ref;
    for (const auto& e : known) ref.push_back(ToMsg(e.estimate, e.m_B_Am2, e.cov_m_B, e.track_id, e.state));
    const auto [rms, n] = RmsWithin30m(got, "auv");
    const auto [rms_known, n_known] = RmsWithin30m(ref, "auv");
    std::printf("AUV fluxgate window, B0 estimated: RMS %.4f m over %d (%zu estimates); true B0: %.4f m over %d "
                "(%zu)\n",
                rms, n, got.size(), rms_known, n_known, known.size());
    EXPECT_GE(n, n_known * 9 / 10);
    // Measured 0.269 m (0.077 m with the true B0) over the rows within reach
    // (the default end rule since 2026-11-26); 0.60 m (0.107 m) before.
    EXPECT_LE(rms, 1.5 * 0.269);
  }
  {
    const GradiometerFile ship = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_squid.csv"));
    const int domain = testing::TestDomainId();
    testing::Subprocess service({MAGNAV_SERVICE_BIN, "--b0", "estimate", "--stats-period", "0"},
                                {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}});
    TestPeer peer(domain);
    ASSERT_TRUE(peer.writer->WaitForMatched(1, 20s));
    ASSERT_TRUE(peer.reader->WaitForMatched(1, 20s));
    EXPECT_TRUE(peer.SendPassAndStop(ship, 0, &service).empty());
  }
}

}  // namespace
}  // namespace magnav::tracker
