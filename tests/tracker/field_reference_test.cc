// The multi-vessel tracker on the reference sensor field (3x3 fluxgate
// gradiometers crossed by three vessels; reference README §5): window and
// batch, scored per vessel against field_truth.csv within 15 m horizontally
// of a sensor (docs/ACCURACY.md, "Several vessels"; scripts/accuracy_field
// gives the same figures through the CLI). The 10 MB field is not in the
// repository: it is read from ../shared/reference/ beside the checkout, and
// the test is skipped, saying so, where that folder is absent. The
// management defaults were tuned on this field; tracker_multi_test and
// bench_multi_tracker are the held-out checks.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <map>

#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "magnav/tracker/multi_tracker.h"
#include "two_vessels.h"

namespace magnav::tracker {
namespace {

const std::string kDir = MAGNAV_SHARED_REFERENCE_DIR;

struct ReferenceField {
  FieldScenario scenario;  // sensors and rate only
  SimulatedField field;    // truth per vessel and the samples
  Eigen::Vector3d B0;
};

const ReferenceField* Load() {
  static std::unique_ptr<ReferenceField> cached;
  if (cached) return cached.get();
  const std::string pass = kDir + "/field_pass_9sensor_fluxgate.csv", truth = kDir + "/field_truth.csv";
  if (!std::filesystem::exists(pass) || !std::filesystem::exists(truth)) return nullptr;
  auto r = std::make_unique<ReferenceField>();
  const GradiometerFile f = ReadGradiometerFile(pass);
  r->B0 = *f.B0;
  r->field.samples = f.samples;
  std::map<std::uint32_t, Eigen::Vector3d> sensors;
  for (const auto& s : f.samples) sensors[s.sensor_id] = s.p_SinW;
  for (const auto& [id, p] : sensors) r->scenario.sensors.push_back(p);
  r->scenario.rate_hz = 10.0;
  const CsvTable t = CsvTable::Read(truth);
  std::map<long long, std::size_t> index;
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    const long long id = t.integer(i, t.column("vessel_id"));
    if (!index.count(id)) {
      index[id] = r->field.truth.size();
      r->field.truth.emplace_back();
    }
    VesselTruth v;
    v.t_s = t.number(i, t.column("t"));
    v.p_VinW = {t.number(i, t.column("x")), t.number(i, t.column("y")), t.number(i, t.column("z"))};
    r->field.truth[index[id]].push_back(v);
  }
  cached = std::move(r);
  return cached.get();
}

TEST(FieldReference, WindowTracksEveryVessel) {
  const ReferenceField* r = Load();
  if (r == nullptr) GTEST_SKIP() << kDir << " has no field_pass_9sensor_fluxgate.csv: not checked here";
  MultiTracker tracker(r->B0, MultiTrackerOptions{});
  const testing::TrackRows rows = testing::WindowRows(&tracker, r->field.samples);
  const testing::FieldScores s = testing::ScoreField(r->scenario, r->field, rows);
  testing::PrintFieldScores("window", s);
  ASSERT_EQ(s.coverage.size(), 3u);
  EXPECT_EQ(tracker.Tracks().size(), 3u);
  EXPECT_LE(s.false_rows, s.rows / 20);  // issue 13: <= 5 % (measured 0)
  // Coverage: the issue's >= 80 % (measured 0.905, 0.820, 1.000); RMS:
  // 1.5x the measured 0.0201, 0.0553, 0.0090 m (the issue asks <= 0.3 m).
  const double max_rms[] = {0.030, 0.083, 0.0135};
  for (std::size_t v = 0; v < 3; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.80) << "vessel " << v + 1;
    EXPECT_LE(s.rms[v], max_rms[v]) << "vessel " << v + 1;
  }
}

TEST(FieldReference, BatchTracksEveryVessel) {
  const ReferenceField* r = Load();
  if (r == nullptr) GTEST_SKIP() << kDir << " has no field_pass_9sensor_fluxgate.csv: not checked here";
  const MultiTrackerOptions opt;
  const auto tracks = SolveBatchMulti(GroupEpochs(r->field.samples, opt.track.epoch_tolerance_s), r->B0, opt);
  const testing::TrackRows rows = testing::BatchRows(tracks);
  const testing::FieldScores s = testing::ScoreField(r->scenario, r->field, rows);
  testing::PrintFieldScores("batch", s);
  ASSERT_EQ(s.coverage.size(), 3u);
  EXPECT_EQ(tracks.size(), 3u);
  EXPECT_LE(s.false_rows, s.rows / 20);
  // Coverage: the issue's >= 90 % (measured 0.991, 0.932, 1.000); RMS:
  // 1.5x the measured 0.0132, 0.0431, 0.0030 m.
  const double max_rms[] = {0.020, 0.065, 0.0045};
  for (std::size_t v = 0; v < 3; ++v) {
    EXPECT_EQ(s.ids[v], 1u) << "vessel " << v + 1;
    EXPECT_GE(s.coverage[v], 0.90) << "vessel " << v + 1;
    EXPECT_LE(s.rms[v], max_rms[v]) << "vessel " << v + 1;
  }
}

}  // namespace
}  // namespace magnav::tracker
