// The start in the residual beside a live track (tracker/residual_start.h):
// a vessel whose tensor stays below the field's start SNR (20) but above the
// residual start's (10) is found by it alone; not where a live track's
// predicted tensor dominates the residual (its model error), nor when off.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/residual_start.h"

namespace magnav::tracker {
namespace {

// One sensor at the origin; a vessel 12.5 m beside it, 5 m above, 1.1 m/s
// north for 30 s: its noise-free tensor peaks at ≈ 14 σ_T (below 20).
FieldScenario WeakPassScenario() {
  FieldScenario sc;
  sc.sensors = {{0.0, 0.0, 0.0}};
  FieldVessel a;
  a.vessel_id = 1;
  a.moment_body = {1500.0, -300.0, 600.0};
  a.start_position = {-16.5, 12.5, -5.0};
  a.speed_mps = 1.1;
  a.segments = {{30.0, 0.0}};
  sc.vessels = {a};
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 2403;
  return sc;
}

TEST(ResidualStart, FindsAVesselBelowTheStartSnr) {
  const MultiTrackerOptions field;
  const FieldScenario sc = WeakPassScenario();
  const std::vector<Epoch> epochs = GroupEpochs(SimulateField(sc).samples, field.track.epoch_tolerance_s);
  const Eigen::Vector3d B0 = sc.B0;
  // The field's initiator (SNR 20) finds nothing.
  EXPECT_FALSE(InitializeTrack(epochs, B0, field.track).has_value());
  const ResidualStartOptions o;  // 10
  const auto none = [](double, const GradiometerSample&) { return 0.0; };
  const std::optional<InitialTrack> line = InitializeInResidual(epochs, B0, field.track, o, none);
  ASSERT_TRUE(line.has_value());
  const double t = line->t_ref_s;
  const Eigen::Vector2d truth(-16.5 + 1.1 * t, 12.5);
  const double d = (Eigen::Vector2d(line->state.x, line->state.y) - truth).norm();
  std::printf("line %.3f m from the vessel at %.1f s, from %zu fixes\n", d, t, line->fixes.size());
  EXPECT_LT(d, 1.5 * 0.721);  // m, measured 0.721
  // A live track whose predicted tensor is stronger than the residual
  // there: its model error, not offered.
  const auto dominated = [](double, const GradiometerSample& s) { return 2.0 * s.T.norm(); };
  EXPECT_FALSE(InitializeInResidual(epochs, B0, field.track, o, dominated).has_value());
  ResidualStartOptions off;
  off.tensor_snr = 0.0;
  EXPECT_FALSE(InitializeInResidual(epochs, B0, field.track, off, none).has_value());
}

TEST(ResidualStart, OptionsAndTheirCheck) {
  ResidualStartOptions o;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  TrackerOptions track;
  track.init.min_tensor_snr = 20.0;
  EXPECT_EQ(ResidualStartTrackerOptions(track, o).init.min_tensor_snr, 10.0);
  o.tensor_snr = 30.0;  // never raised
  EXPECT_EQ(ResidualStartTrackerOptions(track, o).init.min_tensor_snr, 20.0);
  for (double bad : {-1.0, std::nan("")}) {
    ResidualStartOptions b;
    b.tensor_snr = bad;
    EXPECT_FALSE(b.IsValid(&error));
    b = ResidualStartOptions{};
    b.track_share = bad;
    EXPECT_FALSE(b.IsValid(&error));
  }
  ResidualStartOptions z;
  z.max_track_shift_m = 0.0;
  EXPECT_FALSE(z.IsValid(&error));
  MultiTrackerOptions m;
  m.management.residual_start.tensor_snr = -1.0;
  EXPECT_FALSE(m.IsValid(&error));
  // The lone start: twice the strong start's fixes over twice its span, at
  // the residual start's SNR, from the tracker's own fixes; never fewer.
  ResidualStartOptions lone;
  lone.lone_min_fixes = 40;
  lone.lone_min_span_s = 10.0;
  EXPECT_TRUE(lone.IsValid(&error)) << error;
  track.init.min_fixes = 20;
  track.init.min_span_s = 5.0;
  track.init.source = InitSource::kAuto;
  const TrackerOptions l = LoneStartTrackerOptions(track, lone);
  EXPECT_EQ(l.init.min_tensor_snr, 10.0);
  EXPECT_EQ(l.init.min_fixes, 40);
  EXPECT_EQ(l.init.min_span_s, 10.0);
  EXPECT_EQ(l.init.source, InitSource::kSamples);
  track.init.source = InitSource::kExternal;  // only external fixes start tracks: kept (no lone start then)
  EXPECT_EQ(LoneStartTrackerOptions(track, lone).init.source, InitSource::kExternal);
  track.init.min_fixes = 60;
  EXPECT_EQ(LoneStartTrackerOptions(track, lone).init.min_fixes, 60);
  // The lone pair start: on by default (it takes the lone start's options);
  // off is valid too.
  EXPECT_TRUE(ResidualStartOptions{}.lone_pair);
  lone.lone_pair = false;
  EXPECT_TRUE(lone.IsValid(&error)) << error;
  lone.lone_pair = true;
  lone.lone_min_fixes = -1;
  EXPECT_FALSE(lone.IsValid(&error));
  lone.lone_min_fixes = 40;
  lone.lone_min_span_s = std::nan("");
  EXPECT_FALSE(lone.IsValid(&error));
}

}  // namespace
}  // namespace magnav::tracker
