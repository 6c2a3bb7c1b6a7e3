// The localizer's DDS node: MagnetometerSample (magnav/magnetometer) and
// VesselNav (magnav/vessel_nav, the friendly vessel's GNSS) in,
// SensorPositionEstimate (magnav/sensor_position) out for every sensor at
// each Publish (the main calls it at a configurable period; late joiners get
// the last estimate per sensor from the TRANSIENT_LOCAL estimate profile).
// The EKF runs as localizer::StreamingLocalizer, bounded by default — the
// code `magnav localize --method ekf-bounded` runs (`--method ekf` with the
// service's --method ekf) — so on the same stream its final estimates are the
// offline ones. A publish copies the estimates and the bound's window under
// the lock (bounded) and computes the bounds outside it. Every sample passes the library's checks at the door; one that
// fails (non-finite, unknown sensor, time going backwards) is skipped,
// counted, and warned about once per sensor (once for the GNSS), never fed.
//
// With a state directory (--state-dir) the node resumes from
// DIR/magnav-localizer.state if it holds a checkpoint of this configuration
// (any other file is refused with the reason in the log, kept beside as
// .refused, and the node starts fresh), and Checkpoint() writes one
// atomically (docs/RELIABILITY.md "Delivery, crash and restart"). What the
// writers' history sends again of what the checkpoint consumed is dropped
// and counted as "already in the checkpoint", not skipped.
#pragma once

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <set>

#include "magnav/dds/convert_localizer.h"
#include "magnav/dds/node.h"
#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/stamp_guard.h"
#include "magnav/localizer/stream.h"

namespace magnav::localizer {

struct LocalizerNodeOptions {
  Vessel vessel;
  std::vector<SensorPrior> sensors;
  LocalizerOptions localizer;
  // Live streams merge by per-stream watermark (stream.h): a restart's
  // histories and unpaced replays merge exactly, a quiet stream stops
  // holding the others after idle_timeout_s.
  // Bounded (StreamOptions::bounded, `magnav localize --method
  // ekf-bounded`): memory and the cost of a sample or a publish do not grow
  // with uptime. Unbounded (--method ekf) only for comparisons.
  StreamOptions stream = [] {
    StreamOptions s;
    s.merge = StreamMerge::kWatermark;
    s.bounded = true;
    return s;
  }();
  // The friendly vessel's VesselNav: only this vessel_id, and only GNSS
  // fixes (NAV_GNSS); any other VesselNav (another vessel, an INS) is
  // ignored and counted.
  std::uint32_t vessel_id = 0;
  // Checkpoints: the directory (created if missing; "" = none) of
  // magnav-localizer.state. The main writes one every checkpoint period.
  std::string state_dir;

  bool IsValid(std::string* error) const;
};

// Samples and fixes in, estimates out: dds/convert_localizer.h (magnav::dds_localizer).
using dds::FromMsg;
using dds::ToMsg;

class LocalizerNode {
 public:
  LocalizerNode(dds::Node& node, const LocalizerNodeOptions& options);
  // Publishes the current estimate of every sensor (with the bounds); none
  // before the EKF has started.
  void Publish();
  // End of stream: hands everything buffered to the EKF, then publishes.
  void Flush();
  // The wall clock for the stream merge (call every few tens of ms).
  void Tick();
  bool WaitForAcknowledgments(std::chrono::milliseconds timeout) { return writer_->WaitForAcknowledgments(timeout); }
  // Writes the checkpoint (atomically) if there is a state directory and the
  // EKF has started; true if written. A failure is logged (once until one
  // succeeds again) and the node goes on.
  bool Checkpoint();
  // The checkpoint file ("" without a state directory), and whether the node resumed from it.
  const std::string& state_path() const { return state_path_; }
  bool resumed() const { return resumed_; }
  // Items the writers' history sent again that the checkpoint had consumed.
  std::uint64_t already_consumed() const;

  std::uint64_t samples_received() const { return mag_reader_->stats().samples.load(); }
  std::uint64_t fixes_received() const { return nav_reader_->stats().samples.load(); }
  std::uint64_t skipped() const { return skipped_; }
  // VesselNav of another vessel or source (not used).
  std::uint64_t ignored() const { return ignored_; }
  // Messages seen before (a restarted producer's history: dropped before
  // the door, so that the EKF never takes one twice) and sequence numbers
  // of magnetometer samples that never arrived.
  std::uint64_t repeated() const { return repeats_.repeats() + nav_repeats_.repeats(); }
  // Messages with a wild stamp or seq, dropped by the time rule (dds/stamp_guard.h).
  std::uint64_t wild() const { return guard_.rejected() + nav_guard_.rejected(); }
  std::uint64_t missing() const { return repeats_.missing(); }
  std::uint64_t consumed() const;
  // Updates the EKF's NIS gate refused (outliers).
  std::uint64_t outliers() const;
  std::uint64_t published() const { return writer_->stats().samples.load(); }

 private:
  void OnSample(const dds::msg::MagnetometerSample& m, const dds::fdds::SampleInfo& info);
  void TakeSample(const dds::msg::MagnetometerSample& m);
  void OnNav(const dds::msg::VesselNav& m, const dds::fdds::SampleInfo& info);
  void TakeNav(const dds::msg::VesselNav& m);
  void Resume();  // from state_path_, before the readers exist
  // True if `c` was an item the checkpoint consumed (counted, not skipped). mu_ held.
  bool AlreadyConsumed(SampleCheck c);
  void Skip(SampleCheck why, const std::string& stream, std::uint32_t key, double t_s);  // mu_ held

  mutable std::mutex mu_;
  StreamingLocalizer localizer_;
  std::set<std::uint32_t> warned_sensors_;
  bool warned_gnss_ = false;
  std::atomic<std::uint64_t> skipped_{0};
  std::atomic<std::uint64_t> ignored_{0};
  std::uint32_t vessel_id_ = 0;
  bool bounded_ = true;
  bool warned_ignored_ = false;
  std::string state_path_;
  bool resumed_ = false;
  double resumed_until_s_ = 0.0;  // the checkpoint's consumed-until time
  bool logged_already_ = false;
  bool checkpoint_failing_ = false;
  dds::RepeatFilter repeats_;      // magnetometer samples
  dds::StampGuard<dds::msg::MagnetometerSample> guard_{"magnav-localizer: magnav/magnetometer sensor"};  // wild stamps and seqs held, then dropped or confirmed
  dds::RepeatFilter nav_repeats_;  // vessel_nav
  dds::StampGuard<dds::msg::VesselNav> nav_guard_{"magnav-localizer: magnav/vessel_nav vessel"};  // wild stamps and seqs held, then dropped or confirmed
  std::unique_ptr<dds::Writer<dds::msg::SensorPositionEstimate>> writer_;
  std::unique_ptr<dds::Reader<dds::msg::MagnetometerSample>> mag_reader_;
  std::unique_ptr<dds::Reader<dds::msg::VesselNav>> nav_reader_;
};

}  // namespace magnav::localizer
