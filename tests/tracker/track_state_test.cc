// Each row's state (TrackState, multi_tracker.h; `magnav track`'s `state`
// column): a confirmed track's estimate is "coasting" at an epoch where the
// track was not detected, "confirmed" where it was. One AUV-sized vessel
// passes one fluxgate gradiometer at 8 m horizontally (5 m above it) and
// goes on 90 m past it, out of reach: its track must coast there. Judged by
// the true signal at the sensor: where its SNR is below 2 no detection is
// possible (the associator's LLR, ≈ SNR²/2 ± SNR, must reach 12.5), so every
// row there must say coasting; where it is 20 or more, confirmed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::tracker {
namespace {

FieldScenario OnePass() {
  FieldScenario sc;
  sc.sensors = {Eigen::Vector3d::Zero()};
  FieldVessel v;
  v.vessel_id = 1;
  v.moment_body = {2500.0, 300.0, 900.0};
  v.start_position = {-60.0, 8.0, -5.0};
  v.start_heading_rad = 0.0;  // north, along x, closest approach at t = 40 s
  v.speed_mps = 1.5;
  v.segments = {{100.0, 0.0}};
  sc.vessels = {v};
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 5;
  return sc;
}

// The true signal's SNR at the sensor at t: √(‖B‖²/σ_B² + ‖T‖²/σ_T²).
double TrueSnr(const FieldScenario& sc, const SimulatedField& f, double t) {
  const auto& truth = f.truth[0];
  const auto k = static_cast<std::size_t>(std::llround(t * sc.rate_hz));
  EXPECT_LT(k, truth.size());
  const VesselTruth& v = truth[std::min(k, truth.size() - 1)];
  const CtState<double> s{v.p_VinW.x(), v.p_VinW.y(), v.p_VinW.z(), sc.vessels[0].speed_mps, v.heading_rad, 0.0};
  Eigen::Vector3d B;
  Eigen::Matrix3d T;
  PredictedField(s, sc.vessels[0].moment_body, sc.sensors[0], &B, &T);
  return std::sqrt(B.squaredNorm() / (sc.sigma_B * sc.sigma_B) + T.squaredNorm() / (sc.sigma_T * sc.sigma_T));
}

struct Counts {
  int rows = 0, coasting = 0;
  int strong = 0, strong_confirmed = 0;  // true SNR >= 20
  int weak = 0, weak_coasting = 0;       // true SNR < 2
  void Add(const FieldScenario& sc, const SimulatedField& f, double t, TrackState state) {
    ++rows;
    const bool c = state == TrackState::kCoasting;
    coasting += c ? 1 : 0;
    const double snr = TrueSnr(sc, f, t);
    if (snr >= 20.0) {
      ++strong;
      strong_confirmed += c ? 0 : 1;
    }
    if (snr < 2.0) {
      ++weak;
      weak_coasting += c ? 1 : 0;
      EXPECT_TRUE(c) << "t = " << t << " s, true SNR " << snr;
    }
  }
  void Print(const char* what) const {
    std::printf("%s: %d rows, %d coasting; true SNR >= 20: %d rows, %d confirmed; < 2: %d rows, %d coasting\n", what,
                rows, coasting, strong, strong_confirmed, weak, weak_coasting);
  }
};

// The state of rows without a detection needs such rows: with the default
// end rule (TrackManagementOptions::out_of_reach_s 2 s) the track ends
// "out_of_reach" 2 s after it leaves the sensor's reach, before its B falls
// below detection, so it has none; these two tests turn the rule off (what
// they check is the row's state, not the end rule; life_cycle_test.cc and
// HarbourScenario.* test the rule).
MultiTrackerOptions WithoutEndRule() {
  MultiTrackerOptions o;
  o.management.out_of_reach_s = 0.0;
  return o;
}

TEST(TrackState, WindowRowsWithoutADetectionAreCoasting) {
  const FieldScenario sc = OnePass();
  const SimulatedField f = SimulateField(sc);
  MultiTracker tracker(sc.B0, WithoutEndRule());
  std::vector<TrackOutput> rows;
  for (const auto& s : f.samples) {
    for (auto& o : tracker.AddSample(s)) rows.push_back(o);
  }
  for (auto& o : tracker.Flush()) rows.push_back(o);
  const auto records = tracker.Tracks();
  ASSERT_EQ(records.size(), 1u);
  const double t_last = records[0].t_last_detection_s;
  Counts n;
  int after = 0;
  bool last_detection_row = false;
  for (const auto& o : rows) {
    const double t = o.estimate.t_s;
    n.Add(sc, f, t, o.state);
    if (t > t_last) {
      ++after;
      EXPECT_EQ(o.state, TrackState::kCoasting) << "t = " << t << " s, last detection " << t_last << " s";
    }
    if (t == t_last) {
      last_detection_row = true;
      EXPECT_EQ(o.state, TrackState::kConfirmed);
    }
  }
  n.Print("window");
  std::printf("window: last detection at t = %.1f s, %d rows after it; track ended: %s\n", t_last, after,
              records[0].end_reason.c_str());
  EXPECT_TRUE(last_detection_row);
  EXPECT_GE(after, 20);  // measured 92: the track goes on predicted until an end rule
  EXPECT_GE(n.weak, 5);  // measured 10
  ASSERT_GE(n.strong, 50);
  EXPECT_GE(n.strong_confirmed, 0.9 * n.strong);
}

TEST(TrackState, BatchRowsWithoutADetectionAreCoasting) {
  const FieldScenario sc = OnePass();
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions opt = WithoutEndRule();
  const auto tracks = SolveBatchMulti(GroupEpochs(f.samples, opt.track.epoch_tolerance_s), sc.B0, opt);
  ASSERT_EQ(tracks.size(), 1u);
  const MultiTrackEstimate& t = tracks[0];
  ASSERT_EQ(t.states.size(), t.track.epochs.size());
  Counts n;
  for (std::size_t k = 0; k < t.states.size(); ++k) {
    if (t.track.epochs[k].usable) n.Add(sc, f, t.track.epochs[k].t_s, t.states[k]);
  }
  n.Print("batch");
  EXPECT_GE(n.weak, 5);  // measured 10: the window track's span, where it coasted
  ASSERT_GE(n.strong, 50);
  EXPECT_GE(n.strong_confirmed, 0.9 * n.strong);
}

}  // namespace
}  // namespace magnav::tracker
