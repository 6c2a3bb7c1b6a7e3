// The pair start beside a tracked vessel (tracker/pair_beside.h): one sensor,
// a slow vessel tracked, a fast one overtaking it 8 m to its side.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "magnav/core/simulate.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/pair_beside.h"
#include "short_overtaking.h"

namespace magnav::tracker {
namespace {

// Over one sensor at the origin for 20 s: vessel 1 at y = +4 m, 0.8 m/s,
// vessel 2 at y = −4 m, 1.8 m/s, from 18 m behind; both 5 m above the
// sensor, heading north; vessel 2 draws level at 18 s.
FieldScenario OvertakingOverOneSensor(bool both) {
  FieldScenario sc;
  sc.sensors = {{0.0, 0.0, 0.0}};
  FieldVessel a;
  a.vessel_id = 1;
  a.moment_body = {1800.0, -300.0, 900.0};
  a.start_position = {-12.0, 4.0, -5.0};
  a.speed_mps = 0.8;
  a.segments = {{20.0, 0.0}};
  FieldVessel b = a;
  b.vessel_id = 2;
  b.moment_body = {2200.0, 400.0, 600.0};
  b.start_position = {-30.0, -4.0, -5.0};
  b.speed_mps = 1.8;
  sc.vessels = both ? std::vector<FieldVessel>{a, b} : std::vector<FieldVessel>{a};
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 24;
  return sc;
}

TrackerOptions FieldOptions() { return MultiTrackerOptions{}.track; }

// Vessel 1's track at 10 s, 1 m ahead of it and its moment 5 % high (a
// track its neighbour's field has pulled).
InitialTrack TrackOfVessel1(const FieldScenario& sc) {
  InitialTrack a;
  a.t_ref_s = 10.0;
  a.state = CtState<double>{-12.0 + 0.8 * 10.0 + 1.0, 4.0, -5.0, 0.8, 0.0, 0.0};
  a.m_B_Am2 = 1.05 * sc.vessels[0].moment_body;
  return a;
}

TEST(PairBeside, FindsTheVesselOvertakingATrackedOne) {
  const FieldScenario sc = OvertakingOverOneSensor(true);
  const SimulatedField f = SimulateField(sc);
  const TrackerOptions opt = FieldOptions();
  const std::vector<Epoch> epochs = GroupEpochs(f.samples, opt.epoch_tolerance_s);
  const std::vector<InitialTrack> pair = InitializeBeside(epochs, sc.B0, opt, TrackOfVessel1(sc), 8.0);
  ASSERT_EQ(pair.size(), 2u);
  const double measured_m[2] = {0.0049, 0.0109};  // the start's 1 m error and the moment's 5 % are gone
  for (std::size_t v = 0; v < 2; ++v) {
    const double u = pair[v].t_ref_s * sc.rate_hz;
    const auto k = static_cast<std::size_t>(std::floor(u));
    const double w = u - static_cast<double>(k);
    const Eigen::Vector3d truth = (1.0 - w) * f.truth[v].at(k).p_VinW + w * f.truth[v].at(k + 1).p_VinW;
    const double d = (Eigen::Vector3d(pair[v].state.x, pair[v].state.y, pair[v].state.z) - truth).norm();
    std::printf("vessel %zu: %.4f m from its line at %.1f s, speed %.3f m/s\n", v + 1, d, pair[v].t_ref_s,
                pair[v].state.v);
    EXPECT_LT(d, 1.5 * measured_m[v]) << "vessel " << v + 1;
    EXPECT_NEAR(pair[v].state.v, sc.vessels[v].speed_mps, 0.01) << "vessel " << v + 1;  // measured 0.800 / 1.799
    EXPECT_TRUE(pair[v].has_pair_covariance);
  }
}

TEST(PairBeside, NothingBesideALoneVesselOrWithTheGateOff) {
  const FieldScenario sc = OvertakingOverOneSensor(false);
  const SimulatedField f = SimulateField(sc);
  TrackerOptions opt = FieldOptions();
  const std::vector<Epoch> epochs = GroupEpochs(f.samples, opt.epoch_tolerance_s);
  EXPECT_TRUE(InitializeBeside(epochs, sc.B0, opt, TrackOfVessel1(sc), 8.0).empty());
  const FieldScenario two = OvertakingOverOneSensor(true);
  const SimulatedField g = SimulateField(two);
  opt.init.max_dipole_misfit = 0.0;
  EXPECT_TRUE(
      InitializeBeside(GroupEpochs(g.samples, opt.epoch_tolerance_s), two.B0, opt, TrackOfVessel1(two), 8.0).empty());
}

// A track started beside a tracked vessel (MultiTracker's pair start,
// StartOn) has its start time: its confirmation event says since when it was
// tentative, the time the second live track appeared. It had none (0 s), so
// the far source's back-prediction never took it for a young track (its
// field before its start was never given back) and the joint start never
// took it for a young partner. The short overtaking (short_overtaking.h).
TEST(PairBeside, ATrackStartedBesideATrackedVesselHasItsStartTime) {
  const FieldScenario sc = testing::ShortOvertaking();
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, MultiTrackerOptions{});
  double t_beside = -1.0;
  std::vector<TrackEvent> events;
  for (const auto& s : f.samples) {
    tracker.AddSample(s);
    if (t_beside < 0.0 && tracker.summary().num_confirmed >= 1 && tracker.num_live_tracks() == 2) t_beside = s.t_s;
    for (TrackEvent& e : tracker.TakeEvents()) events.push_back(std::move(e));
  }
  ASSERT_GT(t_beside, 0.0) << "no second track beside the first";
  const TrackEvent* beside = nullptr;
  for (const TrackEvent& e : events) {
    if (e.kind == TrackEvent::Kind::kStarted && e.reason.find("beside track") != std::string::npos) beside = &e;
  }
  ASSERT_NE(beside, nullptr) << "no start beside a track";
  const auto at = beside->reason.find("tentative since ");
  ASSERT_NE(at, std::string::npos) << beside->reason;
  const double t_started = std::stod(beside->reason.substr(at + 16));
  std::printf("%s (second live track at %.1f s)\n", beside->reason.c_str(), t_beside);
  EXPECT_NEAR(t_started, t_beside, 0.15);  // s (the sample's time within its epoch)
}

}  // namespace
}  // namespace magnav::tracker
