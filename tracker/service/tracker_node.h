// The tracker's DDS node: GradiometerSample in, TrackEstimate out (one per
// confirmed track and epoch, from the multi-vessel sliding-window tracker
// magnav::tracker::MultiTracker: tracks start, are confirmed, coast and end;
// each has its own track_id, never reused in a run, and its own body moment;
// starts and ends are logged; no back-filled start rows: the node turns
// TrackManagementOptions::backfill_start off). Samples
// of several gradiometers arrive on independent streams, so they are merged
// in time first (magnav::StreamMerger, core/stream_merge.h; one stream per
// sensor id, ranked by sensor id at equal times): by default a per-stream
// watermark (a sample is handed to the tracker once every live sensor has
// sent one at least as new; a sensor silent for idle_timeout_s of wall clock
// does not hold the others; Tick every 50 ms), or a reorder delay (once a
// sample `reorder_delay_s` newer has arrived); the rest at shutdown. A sample
// older than what the tracker has already consumed is counted and dropped.
// Unless tracker.init.source is kSamples it also subscribes DipoleFix
// (magnav-inverter's fixes, rejected ones included) and hands every fix to the
// tracker's initiator (MultiTracker::AddFix); a fix that cannot be used
// (non-finite time or position) is counted, logged and skipped.
// Each sample passes the door first (SampleDoor: a bad one is counted, logged
// once per sensor and skipped) and gets its sensor's B0 from the
// RegionalFieldSource, which the node subtracts from B (the tracker runs with
// B0 = 0); a sample whose sensor has no B0 yet is counted and skipped.
// With a state directory the node checkpoints (Checkpoint: the tracker's
// whole state, the stream position — time consumed until and the sensors
// consumed at that time —, the newest fix taken per sensor, the ended tracks
// still registered, the counters; tracker/checkpoint.h) and at start resumes
// from it: what the writers' history sends again of what the checkpoint
// consumed is dropped and counted (already_consumed), the rest goes on as
// without the restart. A checkpoint is written only once the estimates made
// before it have been acknowledged by the readers, so a restart from it
// loses none. Not in it: the items waiting in the merge (they come again
// from the history) and, with --b0 estimate, the per-sensor B0 estimates.
#pragma once

#include <set>

#include <atomic>
#include <deque>
#include <map>
#include <memory>
#include <mutex>

#include "magnav/core/stream_merge.h"
#include "magnav/dds/convert_tracker.h"
#include "magnav/dds/node.h"
#include "magnav/dds/queued_writer.h"
#include "magnav/dds/regional_field_source.h"
#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/stamp_guard.h"
#include "magnav/dds/sample_door.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::tracker {

struct TrackerNodeOptions {
  MultiTrackerOptions tracker;
  // How the sensors' streams are merged (--merge, --idle-timeout,
  // --reorder-delay): watermark, idle timeout 2 s (wall clock), reorder
  // delay 0.25 s (sample time; with --merge delay).
  StreamMergeOptions merge = {StreamMerge::kWatermark, 0.25, 2.0, 1000000};
  // Non-empty: checkpoint to STATE_DIR/magnav-tracker.state (Checkpoint) and
  // resume from it at start (docs/RELIABILITY.md).
  std::string state_dir;
  // Ended tracks whose estimates stay in the writer's history (the last 1000
  // of each, track_stream profile) for consumers that start late; older ended
  // tracks are unregistered (their history freed). This bounds the writer's
  // memory: ~0.45 MB per kept track of ~700 estimates (bench/soak.sh,
  // docs/BENCHMARKS.md). At most kMaxKeptEndedTracks (the profile's 100 keys:
  // up to 50 live tracks and the kept ended ones).
  int kept_ended_tracks = 10;
  static constexpr int kMaxKeptEndedTracks = 50;

  bool IsValid(std::string* error) const;
};

// Estimate -> magnav/track and magnav/dipole_fix -> the fix the initialiser
// takes: dds/convert_tracker.h (magnav::dds_tracker).
using dds::FromMsg;
using dds::ToMsg;

class TrackerNode {
 public:
  TrackerNode(dds::Node& node, const TrackerNodeOptions& options, std::unique_ptr<dds::RegionalFieldSource> b0);
  // Feeds what is still buffered to the tracker and publishes the result.
  void Flush();
  // The wall clock for the merge's idle streams: call it often (main: every 50 ms).
  void Tick();
  // With a state directory: writes the state (tracks, stream position,
  // counters; tracker/checkpoint.h) atomically to state_path(). False if
  // nothing was written (no state directory, nothing consumed yet, the
  // estimates made so far not acknowledged by the readers within 1 s, or the
  // write failed: logged once; the old file stays).
  bool Checkpoint();
  const std::string& state_path() const { return state_path_; }
  // Started from a checkpoint.
  bool resumed() const { return resumed_; }
  // Samples and fixes the writers' history sent again that the checkpoint had consumed.
  std::uint64_t already_consumed() const { return already_consumed_; }
  // Waits until every estimate is written and the readers acknowledged it
  // (before shutdown).
  bool WaitForAcknowledgments(std::chrono::milliseconds timeout) { return writer_->WaitForAcknowledgments(timeout); }

  std::uint64_t received() const { return reader_->stats().samples.load(); }
  std::uint64_t published() const { return writer_->stats().samples.load(); }
  std::uint64_t flow_timeouts() const { return writer_->stats().flow_timeouts.load(); }
  // Estimates the middleware refused, or dropped from a full queue.
  std::uint64_t not_published() const { return writer_->refused() + writer_->dropped(); }
  std::uint64_t dropped_late() const { return dropped_late_; }
  std::uint64_t rejected() const { return rejected_; }
  std::uint64_t bad_samples() const { return door_.rejected(); }
  std::uint64_t repeated() const { return repeats_.repeats() + fix_repeats_.repeats(); }
  // Messages with a wild stamp or seq, dropped by the time rule (dds/stamp_guard.h).
  std::uint64_t wild() const { return guard_.rejected(); }
  std::uint64_t missing() const { return repeats_.missing(); }  // sequence gaps of the samples
  const dds::RegionalFieldSource& b0() const { return *b0_; }
  std::uint64_t fixes_received() const { return fix_reader_ ? fix_reader_->stats().samples.load() : 0; }
  std::uint64_t fixes_rejected() const { return fixes_rejected_; }
  int num_tracks() const;  // confirmed so far
  int num_live_tracks() const;  // confirmed or tentative now
  // The far source's activity (MultiSummary::far_source), "" when it is off.
  std::string far_source_report() const;

 private:
  void OnSample(const dds::msg::GradiometerSample& m, const dds::fdds::SampleInfo& info);
  void TakeSample(const dds::msg::GradiometerSample& m);
  void OnFix(const dds::msg::DipoleFix& m, const dds::fdds::SampleInfo& info);
  void Feed(const GradiometerSample& s);  // mu_ held
  void Resume();                          // from state_path_, at construction
  std::string ConfigBytes() const;        // what a checkpoint is made for, besides the tracker's own options
  // mu_ held; logs starts and ends, unregisters ended tracks' keys if asked.
  void Publish(const std::vector<TrackOutput>& estimates, bool unregister_ended = true);

  TrackerNodeOptions options_;
  mutable std::mutex mu_;
  dds::SampleDoor door_{"magnav-tracker"};
  dds::RepeatFilter repeats_;      // samples seen before: a restarted producer's history
  dds::StampGuard<dds::msg::GradiometerSample> guard_{"magnav-tracker: magnav/gradiometer sensor"};  // wild stamps and seqs held, then dropped or confirmed
  dds::RepeatFilter fix_repeats_;  // fixes seen before: a restarted inverter's
  std::unique_ptr<dds::RegionalFieldSource> b0_;
  std::set<std::uint32_t> no_sigma_logged_;  // sensors whose missing σ was logged
  MultiTracker tracker_;
  StreamMerger<GradiometerSample> merge_;             // streams: sensor ids
  std::deque<std::uint32_t> ended_;                   // ended tracks still registered, oldest first
  double fed_until_s_ = -1e300;
  std::set<std::uint32_t> fed_at_until_;  // sensors whose sample at fed_until_s_ the tracker took
  std::map<std::uint32_t, double> fix_until_;  // per sensor: time of the newest fix taken
  // Checkpoint.
  std::string state_path_;
  bool resumed_ = false, checkpoint_failing_ = false;
  double restored_until_s_ = -1e300;
  std::set<std::uint32_t> restored_at_until_;
  std::map<std::uint32_t, double> restored_fix_until_;
  std::atomic<std::uint64_t> already_consumed_{0};
  // Written under mu_ by the receive threads, read by the stats line without it.
  std::atomic<std::uint64_t> dropped_late_{0}, rejected_{0}, fixes_rejected_{0};
  // Estimates go out from the writer's own thread with flow control: a burst
  // (a restart rebuilding tracks from the history) is not overwritten in the
  // KEEP_LAST 10 history before the readers have it (queued_writer.h).
  std::unique_ptr<dds::QueuedWriter<dds::msg::TrackEstimate>> writer_;
  std::unique_ptr<dds::Reader<dds::msg::GradiometerSample>> reader_;
  std::unique_ptr<dds::Reader<dds::msg::DipoleFix>> fix_reader_;  // null with init source kSamples
};

}  // namespace magnav::tracker
