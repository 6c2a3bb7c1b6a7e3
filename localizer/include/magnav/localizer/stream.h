// The EKF fed as a stream (what magnav-localizer runs, and what RunEkf runs
// over a whole file): samples and fixes arrive one by one, possibly a little
// out of order across sensors and the GNSS; each is checked at the door
// (InputGate), held in a short reorder buffer, and handed to the EKF in time
// order (fixes before samples at equal times, then by sensor id, then arrival
// order). The vessel
// is started from the GNSS fixes of the first `init_window_s` (ekf.h
// InitialVesselFromGnss). Nothing that fails a check reaches the EKF.
//
// Frames and units: types.h. Not thread-safe.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <variant>
#include <vector>

#include "magnav/core/stream_merge.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/ekf.h"
#include "magnav/localizer/input.h"
#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer {

// How the streams (each sensor's samples, the GNSS fixes) are merged in time
// before the EKF takes them: magnav::StreamMerger (core/stream_merge.h), the
// streams being the GNSS (declared first) and each sensor (declared), the
// rank −1 for fixes and the sensor id for samples. kReorderDelay suits
// streams that arrive merged already (a file; RunEkf hands everything on at
// Flush); kWatermark (what magnav-localizer runs) merges restarts and
// unpaced replays exactly.
using magnav::StreamMerge;

struct StreamOptions {
  StreamMerge merge = StreamMerge::kReorderDelay;
  // kReorderDelay: an item is handed to the EKF once an item this much newer
  // (sample time, s) has arrived, or at Flush. Infinity = only at Flush.
  double reorder_delay_s = 1.0;
  // kWatermark: a stream silent this long (wall clock, s) stops holding the others.
  double idle_timeout_s = 2.0;
  // At most this many items wait (memory bound); beyond it the oldest is
  // handed on whatever the merge rule says.
  std::size_t max_pending = 1000000;
  // The vessel is started from the fixes within this many s of the first
  // item; the stream is held until that window (plus the reorder delay) has
  // passed.
  double init_window_s = 10.0;
  // Bounded (`magnav localize --method ekf-bounded`, what magnav-localizer
  // runs): the same EKF, but nothing is kept per consumed item; the bounds
  // come from IncrementalCrlb (crlb.h: its window of `bound.lag_s`, at most
  // `bound.max_window_items` items, plus a (5 + 2M)² information) instead of
  // a solve over every item consumed. Memory and the cost of an item or of
  // Estimates(true) do not grow with uptime. Unbounded (`--method ekf`):
  // keeps the whole pass and its filtered trajectory, and Estimates(true)
  // solves over all of it (the reference the bounded bound is measured
  // against, docs/ACCURACY.md).
  bool bounded = false;
  IncrementalCrlbOptions bound;

  bool IsValid(std::string* error) const;
  // The merge part of these options.
  StreamMergeOptions Merge() const { return {merge, reorder_delay_s, idle_timeout_s, max_pending}; }
};

class StreamingLocalizer {
 public:
  // Throws InputError if the options are invalid or no sensor is given.
  StreamingLocalizer(const Vessel& vessel, const std::vector<SensorPrior>& sensors, const LocalizerOptions& options,
                     const StreamOptions& stream = {});
  ~StreamingLocalizer();

  // kOk: accepted (buffered). Anything else: refused, state untouched:
  // non-finite, unknown sensor, older than the same stream's last sample, or
  // older than what the EKF has already consumed (kTimeBackwards), or, after
  // RestoreState, consumed already by the checkpoint (kAlreadyConsumed:
  // older than its consumed-until time, or at that time from a stream whose
  // item of that time it consumed; counted in already_consumed()).
  SampleCheck Add(const MagSample& sample);
  SampleCheck Add(const GnssFix& fix);
  // Hands everything buffered to the EKF (end of stream).
  void Flush();
  // kWatermark: the wall clock (s, any monotonic origin) for idle streams;
  // items arriving get this time. Call it often (the service: every 50 ms
  // and before every Add); it hands on what a newly idle stream held.
  void Tick(double now_s);

  bool initialized() const { return ekf_ != nullptr; }
  // Time of the EKF (s); −inf before it starts.
  double time() const;
  // Current sensor estimates with covariance; with `bounds`, the Cramér–Rao
  // bounds along the filtered trajectory of everything consumed so far
  // (costs a sparse solve over that trajectory). Empty before the start.
  std::vector<SensorEstimate> Estimates(bool bounds) const;
  // Everything as RunEkf returns it (estimates, bounds, trajectory, summary).
  // Bounded: the trajectory is the bound's window (its last lag_s).
  Localization Result() const;

  // What Estimates(true) needs, copied (bounded: O(window), never more), so
  // that the bounds can be computed outside the caller's lock.
  struct Snapshot {
    std::vector<SensorEstimate> sensors;           // without the bounds
    std::optional<IncrementalCrlb> bound;          // bounded mode
    // The sensors with their bounds (Estimates(true)).
    std::vector<SensorEstimate> WithBounds() const;
  };
  // Bounded mode only (throws std::logic_error otherwise: the unbounded bound
  // needs the whole pass). Empty sensors before the start.
  Snapshot TakeSnapshot() const;

  // Checkpoint (checkpoint.h; docs/RELIABILITY.md): the payload of a
  // checkpoint file (EncodeCheckpoint) with everything the estimator needs to
  // go on: the configuration it was made for (vessel, sensors, estimator
  // options), the consumed-until time, the counters, the EKF's state and
  // covariance, the bound's folded information and window (bounded) or the
  // pass consumed so far (unbounded), every double bit for bit. Not saved:
  // the items waiting in the merge buffer (newer than consumed-until; a
  // restarted service gets them again from the writers' history, a caller
  // of the library feeds them again) and the door's and merge's arrival
  // state (wall clock of another process).
  std::string SaveState() const;
  // Into a localizer made with the same vessel, sensors and estimator
  // options, before anything was added (std::logic_error otherwise). Throws
  // CheckpointError with the reason (corrupt, truncated, made for another
  // configuration) and leaves the localizer as it was. Afterwards, items the
  // checkpoint consumed are refused as kAlreadyConsumed and the rest are
  // merged and consumed as they would have been without the restart: the
  // final estimates are those of an uninterrupted run, bit for bit, when the
  // same items arrive.
  void RestoreState(const std::string& payload);
  bool restored() const { return restored_; }
  // Consumed-until time (s) of the EKF: every item older than this is in the state.
  double consumed_until() const { return consumed_until_; }

  // Items kept in memory now: the reorder buffer (≤ max_pending), the
  // bound's window (bounded) or the whole pass and trajectory (unbounded).
  // For tests that nothing grows with uptime.
  std::size_t retained_items() const;

  std::uint64_t consumed() const { return consumed_; }   // items the EKF took
  std::uint64_t late() const { return late_; }           // refused: older than consumed
  std::uint64_t failed() const { return failed_; }       // EKF refused (e.g. singular, time 1e300 s ahead)
  std::uint64_t rejected() const { return rejected_; }   // refused by the EKF's NIS gate (outliers)
  std::uint64_t dropped_before_start() const { return dropped_before_start_; }
  // Refused after RestoreState as consumed by the checkpoint already (kAlreadyConsumed).
  std::uint64_t already_consumed() const { return already_consumed_; }

 private:
  using Item = std::variant<MagSample, GnssFix>;
  SampleCheck Buffer(double t_s, int kind, std::int64_t stream, Item item);
  void Release(bool all);
  bool TryStart(bool final);
  void Consume(const Item& item);
  // The configuration a checkpoint is made for: vessel, sensors, estimator options.
  std::string ConfigBytes(int part) const;

  Vessel vessel_;
  std::vector<SensorPrior> sensors_;
  LocalizerOptions options_;
  StreamOptions stream_;
  InputGate gate_;
  // Streams: −1 the GNSS, else the sensor id.
  StreamMerger<Item> merge_;
  double consumed_until_ = -std::numeric_limits<double>::infinity();
  std::unique_ptr<LocalizerEkf> ekf_;
  // Bounded: the bound's recursion and window.
  std::optional<IncrementalCrlb> crlb_;
  // Unbounded: what the EKF consumed, for the bounds: a pass and the state per epoch.
  Pass pass_;
  std::vector<double> epoch_t_;
  std::vector<VesselVector> trajectory_;
  std::uint64_t magnetometer_used_ = 0, gnss_used_ = 0;
  std::uint64_t consumed_ = 0, late_ = 0, failed_ = 0, rejected_ = 0, dropped_before_start_ = 0;
  // The streams (0 = fix / 1 = sample, sensor id; 0 for the GNSS) whose
  // item at consumed_until_ the EKF has taken.
  std::set<std::pair<int, std::int64_t>> consumed_at_until_;
  // After RestoreState: the checkpoint's consumed-until time and streams.
  bool restored_ = false;
  double restored_until_ = -std::numeric_limits<double>::infinity();
  std::set<std::pair<int, std::int64_t>> restored_at_until_;
  std::uint64_t already_consumed_ = 0;
};

}  // namespace magnav::localizer
