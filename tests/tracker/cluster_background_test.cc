// The cluster background (cluster_background.h; issue 24 items 1 and 3):
// the offset smoother's dynamics (what it follows of a far ship and a drift,
// what it takes of a near vessel), the clusters against brute force, and a
// vessel crossing a field whose sensor drifts 20 nT/min: tracked with the
// offsets estimated, biased without.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <cstdio>
#include <random>
#include <set>

#include "magnav/core/simulate.h"
#include "magnav/tracker/cluster_background.h"
#include "magnav/tracker/multi_tracker.h"
#include "two_vessels.h"

namespace magnav::tracker {
namespace {

constexpr double kNt = 1e-9;

// A 10 Hz residual series on one axis, σ 1 nT noise-free (the truth `f`).
std::vector<OffsetSample> Series(double duration_s, const std::function<double(double)>& f) {
  std::vector<OffsetSample> s;
  for (int k = 0; k <= static_cast<int>(duration_s * 10.0); ++k) {
    const double t = 0.1 * k;
    s.push_back({t, Eigen::Vector3d(f(t), 0.0, 0.0), 1.0 * kNt * kNt});
  }
  return s;
}

double MaxError(const std::vector<OffsetEstimate>& est, const std::function<double(double)>& truth, double from_s) {
  double worst = 0.0;
  for (const auto& e : est) {
    if (e.t_s >= from_s) worst = std::max(worst, std::abs(e.b_W.x() - truth(e.t_s)));
  }
  return worst;
}


// The dynamics choice, over a 20 s window (the window tracker's span), σ_B
// 1 nT, 10 Hz: the largest error of the smoothed offset on a drift of
// 20 nT/min and on a far ship as in the `far_ship` scenarios (a 30 nT bell
// ~50 s wide, its steepest 20 s), and what it takes of an untracked near
// vessel whose tensor is not seen (a 300 nT bell 8 s wide: the offset at its
// peak). A track explains a near vessel's B and the tensor gate keeps an
// untracked near vessel's samples out; this is the worst case. Printed for
// several random walks; the default asserted.
struct Dynamics {
  double drift_error, ship_error, near_taken;
};
Dynamics Measure(const ClusterBackgroundOptions& o) {
  const auto drift = [](double t) { return 20.0 * kNt / 60.0 * t + 15.0 * kNt; };
  const auto ship = [](double t) { return 30.0 * kNt * std::exp(-0.5 * std::pow((t - 10.0 - 25.0) / 12.5, 2)); };
  const auto near = [](double t) { return 300.0 * kNt * std::exp(-0.5 * std::pow((t - 10.0) / 2.0, 2)); };
  return {MaxError(SmoothOffsets(Series(20.0, drift), o), drift, 0.0),
          MaxError(SmoothOffsets(Series(20.0, ship), o), ship, 0.0), SmoothOffsets(Series(20.0, near), o)[100].b_W.x()};
}

TEST(ClusterBackground, DynamicsFollowAFarShipMoreThanANearVessel) {
  for (double walk : {0.02, 0.05, 0.1, 0.2, 0.5, 1.0}) {
    ClusterBackgroundOptions o;
    o.walk_T_per_sqrt_s = walk * kNt;
    const Dynamics d = Measure(o);
    std::printf("walk %.2f nT/sqrt(s): drift error %.3f nT, far ship error %.3f nT, near vessel taken %.1f of 300 nT\n",
                walk, d.drift_error / kNt, d.ship_error / kNt, d.near_taken / kNt);
  }
  const Dynamics d = Measure(ClusterBackgroundOptions{});
  EXPECT_LE(d.drift_error, 1.0 * kNt);  // measured 0.51 nT
  EXPECT_LE(d.ship_error, 4.0 * kNt);   // measured 2.0 nT
  EXPECT_LE(d.near_taken, 250.0 * kNt);  // measured 218 nT: a 20 s level takes most of an unseen near vessel
}

TEST(ClusterBackground, ClustersAreTheConnectedTracks) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    const std::size_t n = 1 + rng() % 7;
    std::vector<std::vector<std::uint32_t>> sensors(n);
    for (auto& s : sensors) {
      for (int k = rng() % 3; k > 0; --k) s.push_back(rng() % 12);
    }
    const auto clusters = TrackClusters(sensors);
    // Brute force: i and j together iff linked through shared sensors.
    std::vector<std::vector<bool>> link(n, std::vector<bool>(n, false));
    for (std::size_t i = 0; i < n; ++i) {
      link[i][i] = true;
      for (std::size_t j = 0; j < n; ++j) {
        for (auto a : sensors[i]) {
          for (auto b : sensors[j]) link[i][j] = link[i][j] || a == b;
        }
      }
    }
    for (std::size_t k = 0; k < n; ++k) {
      for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t j = 0; j < n; ++j) link[i][j] = link[i][j] || (link[i][k] && link[k][j]);
      }
    }
    std::vector<int> of(n, -1);
    std::size_t total = 0;
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      total += clusters[c].size();
      for (std::size_t i : clusters[c]) of[i] = static_cast<int>(c);
    }
    ASSERT_EQ(total, n);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = 0; j < n; ++j) ASSERT_EQ(link[i][j], of[i] == of[j]) << trial;
    }
  }
}

TEST(ClusterBackground, OffsetsHoldOutsideTheirSeries) {
  SensorOffsets o;
  EXPECT_EQ(o.At(3, 1.0), Eigen::Vector3d::Zero());
  o.Set(3, {{1.0, {1, 0, 0}, 0.0}, {2.0, {2, 0, 0}, 0.0}});
  EXPECT_EQ(o.At(3, 0.0).x(), 1.0);
  EXPECT_EQ(o.At(3, 1.5).x(), 1.0);
  EXPECT_EQ(o.At(3, 2.0).x(), 2.0);
  EXPECT_EQ(o.At(3, 9.0).x(), 2.0);
  EXPECT_EQ(o.At(4, 9.0), Eigen::Vector3d::Zero());
}

// One AUV crosses a 3x3 field (40 m spacing) over the middle of a sensor
// column; the sensor it passes nearest drifts 20 nT/min (0 at t = 0, 47 nT
// at the end). Fixed B0: that sensor's B is wrong by tens of nT and the
// track is pulled off; with the cluster background the offset takes it.
FieldScenario DriftingSensorField() {
  FieldScenario sc;
  sc.sensors = SensorGrid(3, 3, 40.0);
  FieldVessel a;
  a.vessel_id = 1;
  a.moment_body = {2500.0, 300.0, 900.0};
  a.start_position = {-100.0, 34.0, -5.0};
  a.speed_mps = 1.5;
  a.segments = {{140.0, 0.0}};
  sc.vessels = {a};
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 31;
  sc.background_drift_Tps.assign(sc.sensors.size(), Eigen::Vector3d::Zero());
  std::size_t nearest = 0;
  for (std::size_t j = 0; j < sc.sensors.size(); ++j) {
    if ((sc.sensors[j] - Eigen::Vector3d(0, 40, 0)).norm() < (sc.sensors[nearest] - Eigen::Vector3d(0, 40, 0)).norm()) {
      nearest = j;
    }
  }
  sc.background_drift_Tps[nearest] = Eigen::Vector3d(12.0, -8.0, 13.4).normalized() * (20.0 * kNt / 60.0);
  return sc;
}

TEST(ClusterBackground, VesselOverADriftingSensorWindow) {
  const FieldScenario sc = DriftingSensorField();
  const SimulatedField f = SimulateField(sc);
  MultiTrackerOptions off;
  MultiTrackerOptions on;
  on.cluster_background.enabled = true;
  on.far_source.enabled = false;  // on by default; exclusive with a background model
  MultiTracker t_off(sc.B0, off), t_on(sc.B0, on);
  const testing::FieldScores s_off = testing::ScoreField(sc, f, testing::WindowRows(&t_off, f.samples));
  const testing::FieldScores s_on = testing::ScoreField(sc, f, testing::WindowRows(&t_on, f.samples));
  testing::PrintFieldScores("fixed B0, window", s_off);
  testing::PrintFieldScores("cluster background, window", s_on);
  EXPECT_EQ(s_on.false_rows, 0u);
  EXPECT_EQ(s_on.ids[0], 1u);
  EXPECT_GE(s_on.coverage[0], 0.85);  // measured 0.896 (fixed B0: 0.843)
  EXPECT_LE(s_on.rms[0], 0.25);       // measured 0.14 m
  EXPECT_GE(s_off.rms[0], 0.25);      // measured 0.50 m: the drift's bias
}

TEST(ClusterBackground, VesselOverADriftingSensorBatch) {
  const FieldScenario sc = DriftingSensorField();
  const SimulatedField f = SimulateField(sc);
  MultiTrackerOptions off;
  off.track.sensor_offset.batch = false;  // B0 fixed: the batch's own offsets (the default) take the drift out too
  MultiTrackerOptions on;
  on.track.sensor_offset.batch = false;
  on.cluster_background.enabled = true;
  on.far_source.enabled = false;  // on by default; exclusive with a background model
  const auto epochs = GroupEpochs(f.samples, on.track.epoch_tolerance_s);
  const testing::FieldScores s_off = testing::ScoreField(sc, f, testing::BatchRows(SolveBatchMulti(epochs, sc.B0, off)));
  const testing::FieldScores s_on = testing::ScoreField(sc, f, testing::BatchRows(SolveBatchMulti(epochs, sc.B0, on)));
  testing::PrintFieldScores("fixed B0, batch", s_off);
  testing::PrintFieldScores("cluster background, batch", s_on);
  EXPECT_EQ(s_on.false_rows, 0u);
  EXPECT_EQ(s_on.ids[0], 1u);
  EXPECT_GE(s_on.coverage[0], 0.95);  // measured 1.000 (fixed B0: 1.000)
  EXPECT_LE(s_on.rms[0], 0.085);      // measured 0.044 m
  EXPECT_GE(s_off.rms[0], 0.18);      // measured 0.35 m: the drift's bias
}

TEST(ClusterBackground, OptionsAreChecked) {
  MultiTrackerOptions o;
  std::string why;
  o.cluster_background.enabled = true;
  o.far_source.enabled = false;  // on by default; exclusive with a background model
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.background.enabled = true;
  o.far_source.enabled = false;  // on by default; exclusive with a background model
  EXPECT_FALSE(o.IsValid(&why));
  o.background.enabled = false;
  for (double* v : {&o.cluster_background.prior_sigma_T, &o.cluster_background.walk_T_per_sqrt_s,
                    &o.cluster_background.tensor_gate, &o.cluster_background.track_field_share,
                    &o.cluster_background.prior_rate_sigma_T_per_s}) {
    const double keep = *v;
    for (double bad : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
      *v = bad;
      EXPECT_FALSE(o.IsValid(&why)) << bad;
    }
    *v = 1e308;  // a variance that overflows
    EXPECT_EQ(o.IsValid(&why), v == &o.cluster_background.tensor_gate) << why;
    *v = keep;
  }
  for (double* v : {&o.cluster_background.occupied_tensor_snr, &o.cluster_background.rate_walk_T_per_s_per_sqrt_s}) {
    *v = 0.0;
    EXPECT_TRUE(o.IsValid(&why)) << why;
    for (double bad : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
      *v = bad;
      EXPECT_FALSE(o.IsValid(&why)) << bad;
    }
    *v = 1e308;
    EXPECT_EQ(o.IsValid(&why), v == &o.cluster_background.occupied_tensor_snr) << why;
    *v = 0.0;
  }
}

}  // namespace
}  // namespace magnav::tracker
