// Checkpoints of the multi-vessel tracker (MultiTracker::SaveState /
// RestoreState, tracker/checkpoint.h): a tracker restored from a checkpoint
// taken with two live tracks goes on bit for bit as the uninterrupted one;
// a checkpoint that is corrupt, truncated, of another version, another kind
// or made for other options is refused with the reason and changes nothing.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "magnav/cli/scenario_file.h"
#include "magnav/core/checkpoint.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/simulate.h"
#include "magnav/tracker/checkpoint.h"
#include "magnav/tracker/multi_tracker.h"
#include "test_data.h"
#include "short_overtaking.h"
#include "two_vessels.h"

namespace magnav::tracker {
namespace {

struct Outputs {
  std::vector<TrackOutput> out;  // every output, in order
  std::vector<TrackEvent> events;
};

void Take(MultiTracker& t, const std::vector<TrackOutput>& out, Outputs* run) {
  run->out.insert(run->out.end(), out.begin(), out.end());
  for (auto& e : t.TakeEvents()) run->events.push_back(e);
}

void ExpectSame(const TrackOutput& a, const TrackOutput& b) {
  EXPECT_EQ(a.track_id, b.track_id);
  EXPECT_EQ(a.estimate.t_s, b.estimate.t_s);
  EXPECT_EQ(a.estimate.usable, b.estimate.usable);
  EXPECT_EQ(a.state, b.state) << a.estimate.t_s;
  EXPECT_TRUE((a.estimate.p_VinW.array() == b.estimate.p_VinW.array()).all()) << a.estimate.t_s;
  EXPECT_EQ(a.estimate.heading_rad, b.estimate.heading_rad);
  EXPECT_EQ(a.estimate.turn_rate_radps, b.estimate.turn_rate_radps);
  EXPECT_TRUE((a.estimate.cov_state.array() == b.estimate.cov_state.array()).all()) << a.estimate.t_s;
  EXPECT_TRUE((a.m_B_Am2.array() == b.m_B_Am2.array()).all()) << a.estimate.t_s;
  EXPECT_TRUE((a.cov_m_B.array() == b.cov_m_B.array()).all()) << a.estimate.t_s;
}

// A run cut by a checkpoint: the uninterrupted tracker and its outputs, and
// the state it saved at the first epoch boundary where the test's rule said so.
struct CutRun {
  std::unique_ptr<MultiTracker> tracker;  // uninterrupted, at its end
  Outputs whole;
  std::size_t cut = 0;  // the first sample after the checkpoint (0: never cut)
  std::size_t outputs_before_cut = 0;
  std::string payload;
};

// Runs `samples` through a tracker with `options`; before each sample, until
// the cut, `cut_here(tracker, whole, t_s)` is asked (it may note what it waits
// for), and the state is saved at the first epoch boundary where it says yes.
template <class CutHere>
CutRun RunAndCut(const std::vector<GradiometerSample>& samples, const Eigen::Vector3d& B0,
                 const MultiTrackerOptions& options, CutHere cut_here) {
  CutRun r;
  r.tracker = std::make_unique<MultiTracker>(B0, options);
  MultiTracker& t = *r.tracker;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const bool boundary = i > 0 && samples[i].t_s != samples[i - 1].t_s;
    if (r.cut == 0 && cut_here(t, r.whole, samples[i].t_s) && boundary) {
      r.cut = i;
      r.payload = t.SaveState();
      r.outputs_before_cut = r.whole.out.size();
    }
    Take(t, t.AddSample(samples[i]), &r.whole);
  }
  Take(t, t.Flush(), &r.whole);
  return r;
}

// The samples from the cut on through `restored`, flushed.
Outputs Resume(MultiTracker& restored, const std::vector<GradiometerSample>& samples, std::size_t cut) {
  Outputs after;
  for (std::size_t i = cut; i < samples.size(); ++i) Take(restored, restored.AddSample(samples[i]), &after);
  Take(restored, restored.Flush(), &after);
  return after;
}

// The restored run's outputs are the uninterrupted run's after the cut, bit for bit.
void ExpectSameAfterCut(const Outputs& after, const CutRun& r) {
  ASSERT_EQ(after.out.size(), r.whole.out.size() - r.outputs_before_cut);
  for (std::size_t k = 0; k < after.out.size(); ++k) {
    SCOPED_TRACE(k);
    ExpectSame(after.out[k], r.whole.out[r.outputs_before_cut + k]);
    if (::testing::Test::HasFailure()) break;
  }
}

struct Fixture {
  FieldScenario sc = testing::TwoVesselScenario();
  SimulatedField f = SimulateField(sc);
  MultiTrackerOptions options;
  // The index of the first sample after the checkpoint: both vessels have a
  // confirmed track and the first is in the middle of the field.
  std::size_t cut = 0;
  std::string payload;
  Outputs whole;  // uninterrupted
  std::size_t outputs_before_cut = 0, events_before_cut = 0;
  std::vector<TrackRecord> records;  // of the uninterrupted run, at its end
  MultiSummary summary;

  Fixture() {
    MultiTracker t(sc.B0, options);
    for (std::size_t i = 0; i < f.samples.size(); ++i) {
      if (cut == 0 && t.summary().num_confirmed == 2 && i > 0 && f.samples[i].t_s != f.samples[i - 1].t_s &&
          f.samples[i].t_s > f.samples.front().t_s + 45.0) {
        // At an epoch boundary with a pending epoch: the epoch being filled is in the state too.
        cut = i;
        payload = t.SaveState();
        outputs_before_cut = whole.out.size();
        events_before_cut = whole.events.size();  // (Take drains them after every call)
      }
      Take(t, t.AddSample(f.samples[i]), &whole);
    }
    Take(t, t.Flush(), &whole);
    records = t.Tracks();
    summary = t.summary();
  }
};

const Fixture& Shared() {
  static const Fixture* fx = new Fixture();
  return *fx;
}

TEST(TrackerCheckpoint, RestoredTrackerGoesOnBitForBit) {
  const Fixture& fx = Shared();
  ASSERT_GT(fx.cut, 0u) << "no instant with both tracks confirmed";
  ASSERT_LT(fx.cut, fx.f.samples.size());
  const std::string file = EncodeTrackerCheckpoint(fx.payload);
  MultiTracker t(fx.sc.B0, fx.options);
  t.RestoreState(DecodeTrackerCheckpoint(file));
  EXPECT_EQ(t.num_live_tracks(), 2);
  EXPECT_EQ(t.summary().num_confirmed, 2);
  Outputs after;
  for (std::size_t i = fx.cut; i < fx.f.samples.size(); ++i) Take(t, t.AddSample(fx.f.samples[i]), &after);
  Take(t, t.Flush(), &after);
  ASSERT_EQ(after.out.size(), fx.whole.out.size() - fx.outputs_before_cut);
  ASSERT_GT(after.out.size(), 100u);
  std::printf("checkpoint at t = %.1f s (sample %zu of %zu, 2 live tracks, %zu bytes): the %zu outputs after it "
              "compared\n",
              fx.f.samples[fx.cut].t_s, fx.cut, fx.f.samples.size(), file.size(), after.out.size());
  for (std::size_t k = 0; k < after.out.size(); ++k) {
    SCOPED_TRACE(k);
    ExpectSame(after.out[k], fx.whole.out[fx.outputs_before_cut + k]);
    if (HasFailure()) break;
  }
  // The same ends, records and counters.
  ASSERT_EQ(after.events.size(), fx.whole.events.size() - fx.events_before_cut);
  for (std::size_t k = 0; k < after.events.size(); ++k) {
    const TrackEvent& a = after.events[k];
    const TrackEvent& b = fx.whole.events[fx.events_before_cut + k];
    EXPECT_EQ(a.track_id, b.track_id);
    EXPECT_EQ(a.t_s, b.t_s);
    EXPECT_EQ(a.reason, b.reason);
  }
  const std::vector<TrackRecord> a = t.Tracks();
  ASSERT_EQ(a.size(), fx.records.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].track_id, fx.records[k].track_id);
    EXPECT_EQ(a[k].t_start_s, fx.records[k].t_start_s);
    EXPECT_EQ(a[k].t_end_s, fx.records[k].t_end_s);
    EXPECT_EQ(a[k].end_reason, fx.records[k].end_reason);
    EXPECT_EQ(a[k].num_estimates, fx.records[k].num_estimates);
    EXPECT_TRUE((a[k].m_B_Am2.array() == fx.records[k].m_B_Am2.array()).all());
  }
  EXPECT_EQ(t.summary().num_epochs, fx.summary.num_epochs);
  EXPECT_EQ(t.summary().num_confirmed, fx.summary.num_confirmed);
  EXPECT_EQ(t.summary().num_tentative_dropped, fx.summary.num_tentative_dropped);
}

// Two vessels abreast (held-out abreast): a checkpoint taken after the
// two-dipole start has confirmed both tracks and before their pair refit
// (TrackManagementOptions::pair_refit_s, 5 s after the start) holds the
// recent epochs and the pending refit; the restored tracker refits the pair
// and goes on bit for bit.
TEST(TrackerCheckpoint, PairRestoredBeforeItsRefitGoesOnBitForBit) {
  const FieldScenario sc =
      cli::ReadScenarioFile(testing::TestDataDir() + "/generated/scenarios/heldout/abreast.toml");
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions options;
  double t_confirmed = -1.0;
  const CutRun r = RunAndCut(f.samples, sc.B0, options, [&](const MultiTracker& t, const Outputs&, double t_s) {
    if (t_confirmed < 0.0 && t.summary().num_confirmed == 2) t_confirmed = t_s;
    return t_confirmed > 0.0 && t_s > t_confirmed + 1.0;
  });
  ASSERT_GT(r.cut, 0u) << "the pair was never confirmed";
  MultiTracker restored(sc.B0, options);
  restored.RestoreState(DecodeTrackerCheckpoint(EncodeTrackerCheckpoint(r.payload)));
  EXPECT_EQ(restored.num_live_tracks(), 2);
  const Outputs after = Resume(restored, f.samples, r.cut);
  std::printf("pair confirmed at %.1f s, checkpoint at %.1f s: the %zu outputs after it compared\n", t_confirmed,
              f.samples[r.cut].t_s, after.out.size());
  ExpectSameAfterCut(after, r);
}

// One vessel overtaking another (the short overtaking of
// HarbourScenario.*Overtaking*: heldout/overtaking.toml's geometry over
// 100 s): a checkpoint taken 0.5 s before the pair start beside the slow
// vessel's track (pair_beside.h; the second live track appears then) holds
// what that start rests on (the recent epochs, the track's engine); the
// restored tracker makes the same start and goes on bit for bit. (Dropping
// the saved time of the track's last poor fit does not fail it: the fit
// stays poor until the start, so the restored tracker sees it again.)
TEST(TrackerCheckpoint, OvertakingRestoredBeforeTheStartBesideATrackGoesOnBitForBit) {
  const FieldScenario sc = testing::ShortOvertaking();
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions options;
  // When the second live track appears (a confirmed one is there already).
  double t_beside = -1.0;
  {
    MultiTracker probe(sc.B0, options);
    for (std::size_t i = 0; i < f.samples.size() && t_beside < 0.0; ++i) {
      probe.AddSample(f.samples[i]);
      if (probe.summary().num_confirmed >= 1 && probe.num_live_tracks() == 2) t_beside = f.samples[i].t_s;
    }
  }
  ASSERT_GT(t_beside, 0.0) << "no second track beside the first";
  const CutRun r = RunAndCut(f.samples, sc.B0, options,
                             [&](const MultiTracker&, const Outputs&, double t_s) { return t_s >= t_beside - 0.5; });
  ASSERT_EQ(r.tracker->Tracks().size(), 2u);  // one id per vessel
  MultiTracker restored(sc.B0, options);
  restored.RestoreState(DecodeTrackerCheckpoint(EncodeTrackerCheckpoint(r.payload)));
  EXPECT_EQ(restored.num_live_tracks(), 1);
  const Outputs after = Resume(restored, f.samples, r.cut);
  std::printf("second track at %.1f s, checkpoint at %.1f s: the %zu outputs after it compared\n", t_beside,
              f.samples[r.cut].t_s, after.out.size());
  EXPECT_EQ(restored.Tracks().size(), 2u);
  ExpectSameAfterCut(after, r);
}

// The ghost field of a track ended out of reach (TrackManagementOptions::ghost_field_s) is in the checkpoint:
// cut 1 s after the fast vessel's track ends on an overtaking field, its ghost still subtracted, the restored
// tracker goes on bit for bit.
TEST(TrackerCheckpoint, GhostFieldRestoredGoesOnBitForBit) {
  FieldScenario sc = cli::ReadScenarioFile(testing::TestDataDir() + "/generated/scenarios/heldout/overtaking.toml");
  sc.vessels[0].start_position.x() = -20.0;
  sc.vessels[0].segments = {{85.0, 0.0}};
  sc.vessels[1].start_position.x() = -65.0;
  sc.vessels[1].segments = {{85.0, 0.0}};
  const SimulatedField f = SimulateField(sc);
  MultiTrackerOptions options;
  options.management.ghost_field_s = 30.0;
  double t_end = -1.0;
  const CutRun r = RunAndCut(f.samples, sc.B0, options, [&](const MultiTracker&, const Outputs& whole, double t_s) {
    for (const TrackEvent& e : whole.events) {
      if (t_end < 0.0 && e.kind == TrackEvent::Kind::kEnded && e.reason == "out_of_reach") t_end = e.t_s;
    }
    return t_end > 0.0 && t_s >= t_end + 1.0;
  });
  ASSERT_GT(r.cut, 0u) << "no track ended out of reach";
  MultiTracker restored(sc.B0, options);
  restored.RestoreState(DecodeTrackerCheckpoint(EncodeTrackerCheckpoint(r.payload)));
  EXPECT_EQ(restored.num_ghost_fields(), 1);  // the saved tracker's ghost, 1 s after the track ended
  const Outputs after = Resume(restored, f.samples, r.cut);
  std::printf("track ended out of reach at %.1f s, checkpoint at %.1f s: the %zu outputs after it compared\n", t_end,
              f.samples[r.cut].t_s, after.out.size());
  EXPECT_EQ(restored.summary().num_ghosts, r.tracker->summary().num_ghosts);
  ASSERT_GT(after.out.size(), 0u);
  ExpectSameAfterCut(after, r);
}

// The held-out drift with `options`: a checkpoint taken 30 s after its
// track is confirmed, restored into a new tracker, goes on bit for bit; the
// checkpoint's payload is returned.
std::string ExpectDriftRunGoesOnBitForBit(const MultiTrackerOptions& options, const char* what) {
  const FieldScenario sc = cli::ReadScenarioFile(testing::TestDataDir() + "/generated/scenarios/heldout/drift.toml");
  const SimulatedField f = SimulateField(sc);
  double t_confirmed = -1.0;
  const CutRun r = RunAndCut(f.samples, sc.B0, options, [&](const MultiTracker& t, const Outputs&, double t_s) {
    if (t_confirmed < 0.0 && t.summary().num_confirmed > 0) t_confirmed = t_s;
    return t_confirmed >= 0.0 && t_s >= t_confirmed + 30.0;
  });
  EXPECT_GT(r.cut, 0u) << "no track confirmed 30 s before the end";
  if (r.cut == 0) return {};
  MultiTracker restored(sc.B0, options);
  restored.RestoreState(DecodeTrackerCheckpoint(EncodeTrackerCheckpoint(r.payload)));
  const Outputs after = Resume(restored, f.samples, r.cut);
  std::printf("%s: checkpoint at %.1f s (%zu bytes): the %zu outputs after it compared\n", what,
              f.samples[r.cut].t_s, r.payload.size(), after.out.size());
  EXPECT_GT(after.out.size(), 100u);
  ExpectSameAfterCut(after, r);
  return r.payload;
}

// The window's sensor offsets carried between windows
// (SensorOffsetOptions::carry, with the tensor gate): a checkpoint taken 30 s
// after the held-out drift's track is confirmed (its window has marginalised
// samples, so carried offsets) holds them; the restored tracker goes on bit
// for bit.
TEST(TrackerCheckpoint, CarriedSensorOffsetsRestoredGoOnBitForBit) {
  MultiTrackerOptions options;
  options.track.sensor_offset.window = true;
  options.track.sensor_offset.carry = true;
  options.track.sensor_offset.min_tensor_snr = 20.0;
  ExpectDriftRunGoesOnBitForBit(options, "carried sensor offsets");
}

// The window's offsets as lines in time (SensorOffsetOptions::window_lines,
// with the batch's `enabled` off): a checkpoint taken 30 s after the
// held-out drift's track is confirmed holds each sensor's level and rate and
// their time; the restored tracker goes on bit for bit.
TEST(TrackerCheckpoint, WindowOffsetLinesRestoredGoOnBitForBit) {
  MultiTrackerOptions options;
  options.track.sensor_offset.window_lines = true;
  const std::string payload = ExpectDriftRunGoesOnBitForBit(options, "window offset lines");
  ASSERT_FALSE(payload.empty());
  // A tracker without the lines refuses that checkpoint (its options differ).
  const FieldScenario sc = cli::ReadScenarioFile(testing::TestDataDir() + "/generated/scenarios/heldout/drift.toml");
  MultiTracker other(sc.B0, MultiTrackerOptions{});
  EXPECT_THROW(other.RestoreState(DecodeTrackerCheckpoint(EncodeTrackerCheckpoint(payload))), CheckpointError);
}

// The window's offsets behind the score test (SensorOffsetOptions::
// window_score_test, with the lines): a checkpoint taken 30 s after the
// held-out drift's track is confirmed holds that the test has fired (and the
// track's record its time); the restored tracker goes on bit for bit, and one
// without the test refuses it.
TEST(TrackerCheckpoint, WindowOffsetsBehindTheScoreTestRestoredGoOnBitForBit) {
  MultiTrackerOptions options;
  options.track.sensor_offset.window_lines = true;
  options.track.sensor_offset.window_score_test = true;
  const std::string payload = ExpectDriftRunGoesOnBitForBit(options, "window offsets behind the score test");
  ASSERT_FALSE(payload.empty());
  const FieldScenario sc = cli::ReadScenarioFile(testing::TestDataDir() + "/generated/scenarios/heldout/drift.toml");
  MultiTrackerOptions lines_only;
  lines_only.track.sensor_offset.window_lines = true;
  MultiTracker other(sc.B0, lines_only);
  EXPECT_THROW(other.RestoreState(DecodeTrackerCheckpoint(EncodeTrackerCheckpoint(payload))), CheckpointError);
}

// The score test latched after it persists (SensorOffsetOptions::
// window_score_persist_s), here 40 s: the checkpoint, 30 s after the held-out
// drift's track is confirmed, falls while the test fires but before it
// latches, so it holds the time it began to fire and the window's second,
// tensor-only prior; the restored tracker goes on bit for bit through the
// latch, and one that latches at the first firing refuses the checkpoint.
TEST(TrackerCheckpoint, ScoreTestPersistenceAndTheTensorPriorRestoredGoOnBitForBit) {
  MultiTrackerOptions options;
  options.track.sensor_offset.window_lines = true;
  options.track.sensor_offset.window_score_test = true;
  options.track.sensor_offset.line_rate_sigma_T_per_s = 1e-10;
  options.track.sensor_offset.window_score_persist_s = 40.0;
  const std::string payload = ExpectDriftRunGoesOnBitForBit(options, "score test persistence, tensor prior");
  ASSERT_FALSE(payload.empty());
  const FieldScenario sc = cli::ReadScenarioFile(testing::TestDataDir() + "/generated/scenarios/heldout/drift.toml");
  MultiTrackerOptions at_once = options;
  at_once.track.sensor_offset.window_score_persist_s = 0.0;
  MultiTracker other(sc.B0, at_once);
  EXPECT_THROW(other.RestoreState(DecodeTrackerCheckpoint(EncodeTrackerCheckpoint(payload))), CheckpointError);
}

// The far source in the checkpoint (version 10): on the held-out far-ship
// field (a 4.2e5 A·m² ship 150 m off while an AUV crosses), a checkpoint
// taken while its fit is accepted and the AUV's track is live holds its kept
// samples, fit and back-off, so the restored tracker removes the same B from
// the first sample on and goes on bit for bit (before version 10 the far
// source started empty after a restart and removed nothing for 10 s: the
// AUV's estimates then differ). Its counters go on too.
TEST(TrackerCheckpoint, FarSourceRestoredGoesOnBitForBit) {
  const FieldScenario sc = cli::ReadScenarioFile(testing::TestDataDir() + "/generated/scenarios/heldout/far_ship.toml");
  const SimulatedField f = SimulateField(sc);
  const MultiTrackerOptions options;  // the defaults: the far source on
  ASSERT_TRUE(options.far_source.enabled);
  const CutRun r = RunAndCut(f.samples, sc.B0, options, [&](const MultiTracker& t, const Outputs&, double t_s) {
    return t.summary().num_confirmed > 0 && t.num_live_tracks() > 0 && t.summary().far_source.num_accepted > 20 &&
           t_s > 90.0;
  });
  ASSERT_GT(r.cut, 0u) << "no checkpoint with a live track and an accepted far source";
  MultiTracker restored(sc.B0, options);
  restored.RestoreState(DecodeTrackerCheckpoint(EncodeTrackerCheckpoint(r.payload)));
  const FarSourceStats at_cut = restored.summary().far_source;
  EXPECT_GT(at_cut.num_accepted, 20);
  EXPECT_TRUE(at_cut.has_accepted);
  const Outputs after = Resume(restored, f.samples, r.cut);
  std::printf("far source: checkpoint at %.1f s (%zu bytes, %d fits accepted so far): the %zu outputs after it "
              "compared\n",
              f.samples[r.cut].t_s, r.payload.size(), at_cut.num_accepted, after.out.size());
  EXPECT_GT(after.out.size(), 100u);
  ExpectSameAfterCut(after, r);
  const FarSourceStats& a = restored.summary().far_source;
  const FarSourceStats& b = r.tracker->summary().far_source;
  EXPECT_EQ(a.num_fits, b.num_fits);
  EXPECT_EQ(a.num_accepted, b.num_accepted);
  EXPECT_EQ(a.num_pre_track_corrected, b.num_pre_track_corrected);
  EXPECT_EQ(a.active_s, b.active_s);
  EXPECT_EQ(a.BriefReport(), b.BriefReport());
  // A corrupt refusal code inside the far source's state is refused, not taken.
  MultiTracker fresh(sc.B0, options);
  std::string bad = r.payload;
  // The refusal byte sits before the interval (F64), the 8 counters, the 3
  // pre-track counts (I64 each), active_s (F64), has_accepted (U8), last_t_s,
  // last_p_W (a 3 × 1 matrix: rows and columns as U64, then 3 F64), last_range_m and last_moment_Am2 (F64):
  // 8 + 64 + 24 + 8 + 1 + 8 + 40 + 16 bytes from the end.
  const std::size_t refusal_at = bad.size() - (8 + 64 + 24 + 8 + 1 + 8 + 40 + 16) - 1;
  bad[refusal_at] = static_cast<char>(200);
  EXPECT_THROW(fresh.RestoreState(bad), CheckpointError);
}

// RestoreState(DecodeTrackerCheckpoint(file)) into a new tracker with `options`:
// the CheckpointError's message, or "" if it was taken.
std::string Refusal(const std::string& file, const MultiTrackerOptions& options, const Eigen::Vector3d& B0) {
  MultiTracker t(B0, options);
  try {
    t.RestoreState(DecodeTrackerCheckpoint(file));
  } catch (const CheckpointError& e) {
    // Refused: the tracker is as new.
    EXPECT_EQ(t.num_live_tracks(), 0);
    EXPECT_EQ(t.summary().num_confirmed, 0);
    return e.what();
  }
  return "";
}

// A payload of the AUV pass (1 sensor, B0 removed) taken at 85.4 s with the track live: cheap to make.
struct PassPayload {
  Eigen::Vector3d B0 = Eigen::Vector3d::Zero();
  MultiTrackerOptions options;
  std::string payload;
  GradiometerSample first;
  PassPayload() {
    const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv"));
    MultiTracker t(B0, options);
    first = file.samples.front();
    for (GradiometerSample s : file.samples) {
      s.B -= *file.B0;
      if (s.t_s > 85.4) break;
      t.AddSample(s);
    }
    EXPECT_EQ(t.num_live_tracks(), 1);
    payload = t.SaveState();
  }
};

TEST(TrackerCheckpoint, BadFilesAreRefusedWithTheReason) {
  const PassPayload fx;
  const std::string good = EncodeTrackerCheckpoint(fx.payload);
  EXPECT_EQ(Refusal(good, fx.options, fx.B0), "");

  std::string flipped = good;
  flipped[good.size() / 2] ^= 0x10;
  EXPECT_NE(Refusal(flipped, fx.options, fx.B0).find("checksum"), std::string::npos);
  EXPECT_NE(Refusal(good.substr(0, good.size() - 3), fx.options, fx.B0).find("truncated"), std::string::npos);
  std::string version = good;
  version[8] = static_cast<char>(kTrackerCheckpointVersion + 1);  // u32 version at offset 8
  EXPECT_NE(Refusal(version, fx.options, fx.B0).find("version " + std::to_string(kTrackerCheckpointVersion + 1)),
            std::string::npos);
  // A localizer's checkpoint (another magic) is not a tracker's.
  const std::string other = EncodeCheckpoint({"MAGNAVLC", 1, "magnav-localizer"}, fx.payload);
  EXPECT_NE(Refusal(other, fx.options, fx.B0).find("not a magnav-tracker checkpoint"), std::string::npos);
  // Made for other options, or another B0.
  MultiTrackerOptions changed = fx.options;
  changed.management.max_coast_s = 9.0;
  EXPECT_NE(Refusal(good, changed, fx.B0).find("other tracker options"), std::string::npos);
  // The options of session 16 (the window's turn-onset model, the far field's allowance, the batch's
  // other-field covariance) and of session 17 (the far source's fits at the bound with a ship's
  // moment accepted) and of session 18 (the far source's samples given a later track's back-predicted
  // field, its cap on the moment) are part of the configuration too.
  for (int k = 0; k < 6; ++k) {
    MultiTrackerOptions other_model = fx.options;
    if (k == 0) other_model.track.window_turn_onset_model = !other_model.track.window_turn_onset_model;
    if (k == 1) other_model.far_source.unexplained_sigma_T += 1e-9;
    if (k == 2) other_model.batch_other_field_covariance = !other_model.batch_other_field_covariance;
    if (k == 3) other_model.far_source.bound_accept_moment_Am2 = 2e5;
    if (k == 4) other_model.far_source.back_predict_new_tracks = !other_model.far_source.back_predict_new_tracks;
    if (k == 5) other_model.far_source.max_moment_Am2 = 2e6;
    EXPECT_NE(Refusal(good, other_model, fx.B0).find("other tracker options"), std::string::npos) << k;
  }
  EXPECT_NE(Refusal(good, fx.options, Eigen::Vector3d(1e-9, 0.0, 0.0)).find("another B0"), std::string::npos);
  // A payload cut inside the state (re-sealed, so the checksum passes).
  const std::string cut = EncodeTrackerCheckpoint(fx.payload.substr(0, fx.payload.size() - 100));
  EXPECT_NE(Refusal(cut, fx.options, fx.B0).find("truncated"), std::string::npos);
  // Only into a new tracker.
  MultiTracker used(fx.B0, fx.options);
  used.AddSample(fx.first);
  EXPECT_THROW(used.RestoreState(fx.payload), std::logic_error);
}

}  // namespace
}  // namespace magnav::tracker

namespace magnav::tracker {
namespace {
// The service's path: one sensor (the AUV fluxgate pass of Dds.RestartAfterKill_tracker), B0 removed
// from the samples, the tracker run with B0 = 0; the checkpoint with the track live, its window
// solved half a second before (epochs still unsolved are in the state).
TEST(TrackerCheckpoint, ServicePassRestoredGoesOnBitForBit) {
  const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv"));
  std::vector<GradiometerSample> samples = file.samples;
  for (auto& s : samples) s.B -= *file.B0;
  const double cut_t = 85.4;  // in the middle of the track (67 s to 135 s)
  const MultiTrackerOptions options;
  MultiTracker a(Eigen::Vector3d::Zero(), options);
  std::vector<TrackOutput> whole;
  std::string payload;
  std::size_t cut = 0, before = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (payload.empty() && samples[i].t_s > cut_t) {
      payload = a.SaveState();
      cut = i;
      before = whole.size();
    }
    for (auto& o : a.AddSample(samples[i])) whole.push_back(o);
  }
  for (auto& o : a.Flush()) whole.push_back(o);
  MultiTracker b(Eigen::Vector3d::Zero(), options);
  b.RestoreState(payload);
  std::vector<TrackOutput> after;
  for (std::size_t i = cut; i < samples.size(); ++i) {
    for (auto& o : b.AddSample(samples[i])) after.push_back(o);
  }
  for (auto& o : b.Flush()) after.push_back(o);
  std::printf("cut at t = %.1f s: %zu outputs before, %zu after\n", samples[cut].t_s, before, after.size());
  ASSERT_EQ(after.size(), whole.size() - before);
  for (std::size_t k = 0; k < after.size(); ++k) {
    SCOPED_TRACE(k);
    ExpectSame(after[k], whole[before + k]);
    if (HasFailure()) break;
  }
}
// Runs `whole_run` over the first 70 s of `f`, saves it at the
// first new epoch after 50 s, restores the payload into a fresh tracker
// (`*restored`) and runs it over the rest: its estimates must be those of the
// tracker that was never stopped, bit for bit. Returns the time of the last
// sample (both trackers are there).
double SaveAtFiftySecondsAndRestore(const SimulatedField& f, MultiTracker* whole_run, MultiTracker* restored) {
  std::vector<TrackOutput> whole;
  std::string payload;
  std::size_t cut = 0, before = 0, end = 0;
  const double t0 = f.samples.front().t_s;
  for (std::size_t i = 0; i < f.samples.size() && f.samples[i].t_s < t0 + 70.0; ++i) {
    if (payload.empty() && f.samples[i].t_s > t0 + 50.0 && f.samples[i].t_s != f.samples[i - 1].t_s) {
      payload = whole_run->SaveState();
      cut = i;
      before = whole.size();
    }
    for (auto& o : whole_run->AddSample(f.samples[i])) whole.push_back(o);
    end = i + 1;
  }
  EXPECT_FALSE(payload.empty());
  EXPECT_GT(whole_run->num_live_tracks(), 0);
  restored->RestoreState(payload);
  std::vector<TrackOutput> after;
  for (std::size_t i = cut; i < end; ++i) {
    for (auto& o : restored->AddSample(f.samples[i])) after.push_back(o);
  }
  EXPECT_EQ(after.size(), whole.size() - before);
  EXPECT_GT(after.size(), 0u);
  for (std::size_t k = 0; k < after.size() && before + k < whole.size(); ++k) {
    SCOPED_TRACE(k);
    ExpectSame(after[k], whole[before + k]);
    if (::testing::Test::HasFailure()) break;
  }
  return f.samples[end - 1].t_s;
}

// With the cluster background on (cluster_background.h), its raw span and
// offsets are in the checkpoint and the restored windows take the offsets
// again: restored, the tracker gives the same estimates, bit for bit.
TEST(TrackerCheckpoint, ClusterBackgroundIsInTheCheckpoint) {
  const FieldScenario sc = testing::TwoVesselScenario();
  const SimulatedField f = SimulateField(sc);
  MultiTrackerOptions options;
  options.cluster_background.enabled = true;
  options.far_source.enabled = false;  // on by default; exclusive with a background model
  MultiTracker a(sc.B0, options), b(sc.B0, options);
  SaveAtFiftySecondsAndRestore(f, &a, &b);
  // Made without it: refused (other options).
  MultiTracker c(sc.B0, MultiTrackerOptions{});
  EXPECT_THROW(c.RestoreState(a.SaveState()), CheckpointError);
}

// With the per-sensor background on (background.h), its filters are in the
// checkpoint: restored, the tracker gives the same estimates and the same
// background at every sensor, bit for bit.
TEST(TrackerCheckpoint, BackgroundIsInTheCheckpoint) {
  const FieldScenario sc = testing::TwoVesselScenario();
  const SimulatedField f = SimulateField(sc);
  MultiTrackerOptions options;
  options.background.enabled = true;
  options.far_source.enabled = false;  // on by default; exclusive with a background model
  MultiTracker a(sc.B0, options), b(sc.B0, options);
  const double t = SaveAtFiftySecondsAndRestore(f, &a, &b);
  for (std::uint32_t id = 0; id < sc.sensors.size(); ++id) {
    const BackgroundEstimate x = a.Background(id, t), y = b.Background(id, t);
    EXPECT_TRUE((x.B_W.array() == y.B_W.array()).all()) << id;
    EXPECT_EQ(x.sigma_T, y.sigma_T) << id;
    EXPECT_FALSE((x.B_W.array() == sc.B0.array()).all()) << "the background never moved at " << id;
  }
  // A checkpoint made with the background off is refused by one with it on.
  MultiTracker off(sc.B0, MultiTrackerOptions{});
  MultiTracker on(sc.B0, options);
  EXPECT_THROW(on.RestoreState(off.SaveState()), CheckpointError);
}
}  // namespace
}  // namespace magnav::tracker
