// The window tracker at its edges: a NaN sample, an infinite σ or a dead
// (all-zero) tensor mid-pass is refused at the door and counted, and the track
// afterwards is the clean run's; an estimate says whether it is usable.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"
#include "test_data.h"

namespace magnav::tracker {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

struct WindowRun {
  std::vector<EpochEstimate> estimates;
  Summary summary;
};

WindowRun RunWindow(const GradiometerFile& f, const std::vector<GradiometerSample>& samples) {
  WindowTracker tracker(*f.B0, TrackerOptions{});
  WindowRun run;
  for (const auto& s : samples) {
    for (auto& e : tracker.AddSample(s)) run.estimates.push_back(e);
  }
  for (auto& e : tracker.Flush()) run.estimates.push_back(e);
  run.summary = tracker.last_summary();
  return run;
}

// The review's reproduction: ship fluxgate, NaN in B_x at t = 100 s. Before
// the door the track coasted 24 m off by t = 190 s with σ 0.61 m and usable
// true. Now the bad samples are left out (4-sensor pass: the epoch keeps its
// other sensors), counted, and every later estimate equals the clean run's
// to within a small fraction of its own σ.
TEST(WindowTrackerEdges, BadSamplesMidPassDoNotPoisonTheTrack) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_4sensor_fluxgate.csv"));
  std::vector<GradiometerSample> bad = f.samples;
  int n_bad = 0;
  for (auto& s : bad) {
    if (std::abs(s.t_s - 100.0) < 1e-9 && s.sensor_id == 0) s.B.x() = kNaN, ++n_bad;
    if (std::abs(s.t_s - 100.5) < 1e-9 && s.sensor_id == 1) s.sigma_T = kInf, ++n_bad;
    if (std::abs(s.t_s - 101.0) < 1e-9 && s.sensor_id == 0) s.T.setZero(), ++n_bad;
  }
  ASSERT_EQ(n_bad, 3);
  // The clean reference: the same samples without the three bad ones.
  std::vector<GradiometerSample> clean;
  for (std::size_t i = 0; i < bad.size(); ++i) {
    if (CheckSample(bad[i]) == SampleDefect::kNone) clean.push_back(f.samples[i]);
  }
  ASSERT_EQ(clean.size() + 3, f.samples.size());
  const WindowRun got = RunWindow(f, bad), want = RunWindow(f, clean);
  EXPECT_EQ(got.summary.num_rejected_samples, 3);
  EXPECT_EQ(want.summary.num_rejected_samples, 0);
  EXPECT_EQ(got.summary.num_dropped_factors, 0);
  ASSERT_EQ(got.estimates.size(), want.estimates.size());
  int compared = 0;
  for (std::size_t k = 0; k < got.estimates.size(); ++k) {
    const EpochEstimate& a = got.estimates[k];
    const EpochEstimate& b = want.estimates[k];
    ASSERT_EQ(a.t_s, b.t_s);
    EXPECT_TRUE(a.usable) << a.t_s;
    ASSERT_TRUE(a.has_covariance);
    EXPECT_TRUE(a.p_VinW.allFinite());
    EXPECT_EQ((a.p_VinW - b.p_VinW).norm(), 0.0) << "t = " << a.t_s;  // the same samples: the same track
    if (a.t_s >= 190.0) ++compared;
  }
  EXPECT_GT(compared, 50);
}

// One NaN sample on a 1-sensor pass: its epoch is left out, and the track
// afterwards stays within its own σ of the clean run's.
TEST(WindowTrackerEdges, OneSensorNaNSampleLeavesOneEpochOut) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  std::vector<GradiometerSample> bad = f.samples;
  bad[1000].B.x() = kNaN;  // t = 100 s
  const WindowRun got = RunWindow(f, bad), want = RunWindow(f, f.samples);
  EXPECT_EQ(got.summary.num_rejected_samples, 1);
  ASSERT_EQ(got.estimates.size() + 1, want.estimates.size());
  std::size_t j = 0;
  double worst_z = 0.0;
  for (const auto& a : got.estimates) {
    while (want.estimates[j].t_s < a.t_s) ++j;
    const auto& b = want.estimates[j];
    ASSERT_TRUE(a.usable);
    ASSERT_TRUE(a.has_covariance);
    const double sigma = std::sqrt(a.cov_p_W().trace());
    worst_z = std::max(worst_z, (a.p_VinW - b.p_VinW).norm() / sigma);
  }
  EXPECT_LT(worst_z, 0.5) << "largest difference from the clean track, in its 3-D sigma";
}

// A sample whose tensor overflows (1e200: finite elements, infinite norm) is
// refused too; epochs handed in whole pass the same door.
TEST(WindowTrackerEdges, OverflowAndWholeEpochsPassTheDoor) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  WindowTracker tracker(*f.B0, TrackerOptions{});
  GradiometerSample s = f.samples[0];
  s.T(0, 0) = 1e200;
  EXPECT_TRUE(tracker.AddSample(s).empty());
  EXPECT_TRUE(tracker.AddEpoch(Epoch{s.t_s, {s}}).empty());
  EXPECT_EQ(tracker.last_summary().num_rejected_samples, 2);
  EXPECT_FALSE(tracker.initialized());
}

// Batch: the same door, counted in the summary; the track equals the one
// without the bad samples.
TEST(BatchEdges, BadSamplesAreLeftOutAndCounted) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_4sensor_fluxgate.csv"));
  std::vector<GradiometerSample> bad = f.samples, clean;
  bad[4000].B.y() = kNaN;
  bad[4001].sigma_B = -1.0;
  bad[4002].T.setZero();
  for (const auto& s : bad) {
    if (CheckSample(s) == SampleDefect::kNone) clean.push_back(s);
  }
  const TrackerOptions o;
  const TrackEstimate got = SolveBatch(GroupEpochs(bad, o.epoch_tolerance_s), *f.B0, o);
  const TrackEstimate want = SolveBatch(GroupEpochs(clean, o.epoch_tolerance_s), *f.B0, o);
  EXPECT_EQ(got.summary.num_rejected_samples, 3);
  ASSERT_TRUE(got.summary.usable);
  ASSERT_EQ(got.epochs.size(), want.epochs.size());
  for (std::size_t k = 0; k < got.epochs.size(); ++k) {
    EXPECT_TRUE(got.epochs[k].usable);
    EXPECT_EQ((got.epochs[k].p_VinW - want.epochs[k].p_VinW).norm(), 0.0);
  }
  // Same span for both costs: the final cost is below the initial one.
  EXPECT_LT(got.summary.final_cost, got.summary.initial_cost);
}

// Batch over several tracks (what `magnav track` runs): one sample whose
// tensor overflows (T00 = 1e200) is left out as in the single-track batch, and
// the tracks are those of the pass without it: refined, with covariances.
TEST(BatchEdges, OverflowingTensorInTheMultiTrackBatch) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_ship_1sensor_fluxgate.csv"));
  std::vector<GradiometerSample> bad = f.samples, clean;
  bad[1000].T(0, 0) = 1e200;
  for (const auto& s : bad) {
    if (CheckSample(s) == SampleDefect::kNone) clean.push_back(s);
  }
  ASSERT_EQ(clean.size() + 1, bad.size());
  const MultiTrackerOptions o;
  const auto got = SolveBatchMulti(GroupEpochs(bad, o.track.epoch_tolerance_s), *f.B0, o);
  const auto want = SolveBatchMulti(GroupEpochs(clean, o.track.epoch_tolerance_s), *f.B0, o);
  ASSERT_EQ(got.size(), want.size());
  ASSERT_FALSE(got.empty());
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].track.summary.message, want[i].track.summary.message);
    ASSERT_EQ(got[i].track.epochs.size(), want[i].track.epochs.size());
    for (std::size_t k = 0; k < got[i].track.epochs.size(); ++k) {
      EXPECT_EQ(got[i].track.epochs[k].has_covariance, want[i].track.epochs[k].has_covariance) << k;
      EXPECT_LT((got[i].track.epochs[k].p_VinW - want[i].track.epochs[k].p_VinW).norm(), 1e-6) << k;
    }
  }
}

// Every tolerance is checked (before, the window's and the intermediate one
// were not: a NaN tolerance made a solve that never stops on it).
TEST(TrackerOptionsEdges, EveryToleranceIsChecked) {
  const auto invalid = [](auto set) {
    TrackerOptions o;
    set(o);
    std::string why;
    return !o.IsValid(&why) && !why.empty();
  };
  EXPECT_TRUE(invalid([](TrackerOptions& o) { o.window_function_tolerance = -1.0; }));
  EXPECT_TRUE(invalid([](TrackerOptions& o) { o.window_function_tolerance = kNaN; }));
  EXPECT_TRUE(invalid([](TrackerOptions& o) { o.intermediate_function_tolerance = kNaN; }));
  EXPECT_TRUE(invalid([](TrackerOptions& o) { o.function_tolerance = kInf; }));
  EXPECT_TRUE(invalid([](TrackerOptions& o) { o.parameter_tolerance = -1e-3; }));
  EXPECT_FALSE(invalid([](TrackerOptions&) {}));
}

}  // namespace
}  // namespace magnav::tracker
