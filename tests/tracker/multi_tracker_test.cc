// The multi-vessel tracker on a field built here: two AUV-sized vessels cross
// a 3x3 gradiometer grid at the same time, 50-60 m apart (held-out: the
// management defaults were chosen on the reference field, not on this one).
// Scored against the simulator's truth (not the tracker's helpers): one track
// per vessel, coverage near the sensors, RMS, no false rows.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "magnav/core/error.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::tracker {
namespace {

struct Field {
  std::vector<GradiometerSample> samples;
  std::vector<std::vector<VesselTruth>> truth;  // per vessel, per instant
  std::vector<Eigen::Vector3d> sensors;
  Eigen::Vector3d B0;
};

Field TwoVessels() {
  PassScenario a;
  for (double x : {-40.0, 0.0, 40.0}) {
    for (double y : {-40.0, 0.0, 40.0}) a.sensors.push_back({x, y, 0.0});
  }
  a.sensors.erase(a.sensors.begin());  // the default sensor (origin); the grid has its own
  a.moment_body = {2500.0, 300.0, 900.0};
  a.start_position = {-100.0, 38.0, -5.0};
  a.start_heading_rad = 0.0;  // north, along x
  a.speed_mps = 1.5;
  a.segments = {{140.0, 0.0}};
  a.sigma_B = 1e-9;
  a.sigma_T = 1.4e-9;
  a.seed = 11;
  PassScenario b = a;
  b.moment_body = {1800.0, -500.0, 700.0};
  b.start_position = {38.0, 100.0, -6.0};
  b.start_heading_rad = -M_PI / 2;  // west, along -y
  b.speed_mps = 1.2;
  b.sigma_B = b.sigma_T = 0.0;  // the noise is in a's samples once
  const SimulatedPass pa = SimulatePass(a), pb = SimulatePass(b);
  Field f;
  f.B0 = a.B0;
  f.sensors = a.sensors;
  f.truth = {pa.truth, pb.truth};
  EXPECT_EQ(pa.samples.size(), pb.samples.size());
  for (std::size_t i = 0; i < pa.samples.size(); ++i) {
    GradiometerSample s = pa.samples[i];
    EXPECT_EQ(s.sensor_id, pb.samples[i].sensor_id);
    s.B += pb.samples[i].B - b.B0;
    s.T += pb.samples[i].T;
    f.samples.push_back(s);
  }
  return f;
}

struct Scores {
  std::size_t rows = 0, false_rows = 0;
  std::vector<double> coverage, rms;
  std::vector<std::size_t> ids;  // track ids per vessel
};

// Rows go to the nearest vessel (3-D) or, farther than 5 m from both, count
// as false; coverage over the instants a vessel is within 15 m horizontally
// of a sensor.
Scores Score(const Field& f, const std::vector<std::pair<std::uint32_t, EpochEstimate>>& rows) {
  Scores s;
  const std::size_t nv = f.truth.size();
  std::vector<std::map<long long, bool>> covered(nv);
  std::vector<double> sum_sq(nv, 0.0);
  std::vector<std::size_t> n(nv, 0);
  std::vector<std::map<std::uint32_t, int>> ids(nv);
  const auto in_field = [&](const Eigen::Vector3d& p) {
    for (const auto& q : f.sensors) {
      if ((p - q).head<2>().norm() <= 15.0) return true;
    }
    return false;
  };
  const double dt = f.truth[0][1].t_s - f.truth[0][0].t_s;
  for (const auto& [id, e] : rows) {
    ++s.rows;
    const auto k = static_cast<std::size_t>(std::llround((e.t_s - f.truth[0][0].t_s) / dt));
    std::size_t best_v = 0;
    double best = 1e300;
    for (std::size_t v = 0; v < nv; ++v) {
      const double d = (e.p_VinW - f.truth[v].at(k).p_VinW).norm();
      if (d < best) {
        best = d;
        best_v = v;
      }
    }
    if (best > 5.0) {
      ++s.false_rows;
      continue;
    }
    ++ids[best_v][id];
    if (!in_field(f.truth[best_v][k].p_VinW)) continue;
    covered[best_v][static_cast<long long>(k)] = true;
    sum_sq[best_v] += best * best;
    ++n[best_v];
  }
  for (std::size_t v = 0; v < nv; ++v) {
    std::size_t instants = 0;
    for (const auto& t : f.truth[v]) instants += in_field(t.p_VinW) ? 1 : 0;
    s.coverage.push_back(static_cast<double>(covered[v].size()) / static_cast<double>(instants));
    s.rms.push_back(n[v] > 0 ? std::sqrt(sum_sq[v] / static_cast<double>(n[v])) : 1e300);
    s.ids.push_back(ids[v].size());
  }
  return s;
}

void Report(const char* mode, const Scores& s) {
  std::printf("%s: %zu rows, %zu false; vessel A coverage %.3f RMS %.4f m ids %zu; vessel B coverage %.3f RMS %.4f m "
              "ids %zu\n",
              mode, s.rows, s.false_rows, s.coverage[0], s.rms[0], s.ids[0], s.coverage[1], s.rms[1], s.ids[1]);
}

TEST(MultiTracker, WindowFollowsTwoVesselsWithOneTrackEach) {
  const Field f = TwoVessels();
  MultiTracker tracker(f.B0, MultiTrackerOptions{});
  std::vector<std::pair<std::uint32_t, EpochEstimate>> rows;
  const auto take = [&](const std::vector<TrackOutput>& out) {
    for (const auto& o : out) rows.emplace_back(o.track_id, o.estimate);
  };
  for (const auto& s : f.samples) take(tracker.AddSample(s));
  take(tracker.Flush());
  const Scores s = Score(f, rows);
  Report("window", s);
  EXPECT_EQ(tracker.Tracks().size(), 2u);
  EXPECT_EQ(s.false_rows, 0u);
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v;
    EXPECT_GE(s.coverage[v], 0.85) << "vessel " << v;  // measured 0.903, 0.903
    EXPECT_LE(s.rms[v], 0.04) << "vessel " << v;       // measured 0.0136, 0.0245 m
  }
}

TEST(MultiTracker, BatchRefinesEveryVessel) {
  const Field f = TwoVessels();
  const MultiTrackerOptions opt;
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), f.B0, opt);
  std::vector<std::pair<std::uint32_t, EpochEstimate>> rows;
  for (const auto& t : tracks) {
    for (const auto& e : t.track.epochs) {
      if (e.usable) rows.emplace_back(t.track_id, e);
    }
  }
  const Scores s = Score(f, rows);
  Report("batch", s);
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(s.false_rows, 0u);
  for (std::size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v;
    EXPECT_GE(s.coverage[v], 0.93) << "vessel " << v;  // measured 0.987, 0.970
    EXPECT_LE(s.rms[v], 0.017) << "vessel " << v;      // measured 0.0090, 0.0109 m
  }
}

TEST(MultiTracker, OptionsAreChecked) {
  MultiTrackerOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.management.confirm_m = 11;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THROW(MultiTracker(Eigen::Vector3d::Zero(), o), InputError);
}

}  // namespace
}  // namespace magnav::tracker
