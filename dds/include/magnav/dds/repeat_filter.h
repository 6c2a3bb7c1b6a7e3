// Recognises a message that arrived before. With TRANSIENT_LOCAL streams a
// reader that matches a writer late gets the writer's history, and a service
// restarted after kill -9 republishes results for samples it had already
// answered before it died (docs/RELIABILITY.md, "Crash and restart"). Every
// stream message carries what identifies it: its key (sensor, track, vehicle),
// the sequence number of the sample it belongs to (samples: `seq`, fixes:
// `sample_seq`; estimates have none: 0) and its time stamp. A consumer passes
// each message through a RepeatFilter and drops the repeats: the same
// (key, seq, stamp) within the last `depth_per_key` messages of that key
// (and of the last `max_keys` keys used).
// A restarted producer of new data (new stamps) is never taken for a repeat.
//
// Sequence gaps. For messages with a sequence number (samples and fixes,
// `MessageId::sequenced`) the filter also follows each key's next expected
// number: a message that skips numbers adds them to missing() (samples the
// producer numbered but this reader never got: lost on a best-effort path,
// older than a late joiner's history, or never sent by the sensor); one whose
// number goes back without being a repeat is counted in restarts() (a
// producer that started over, or another producer of the same key) and the
// expected number follows it. Both are logged once per key when a log name is
// given (SetLogName); later ones are only counted (the services' stats lines).
// Messages that are not first (repeats) never move the expected number.
// Thread-safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <mutex>
#include <set>
#include <string>
#include <tuple>
#include <unordered_map>

#include "magnav/dds/topics.h"

namespace magnav::dds {

struct MessageId {
  std::uint32_t key = 0;
  std::uint64_t seq = 0;
  std::uint64_t stamp_ns = 0;
  bool sequenced = false;  // seq numbers the key's messages 0, 1, 2, … (gaps are followed)
  bool operator<(const MessageId& o) const {
    return std::tie(key, seq, stamp_ns) < std::tie(o.key, o.seq, o.stamp_ns);
  }
};

inline MessageId IdOf(const msg::GradiometerSample& m) { return {m.sensor_id(), m.seq(), m.stamp_ns(), true}; }
inline MessageId IdOf(const msg::MagnetometerSample& m) { return {m.sensor_id(), m.seq(), m.stamp_ns(), true}; }
inline MessageId IdOf(const msg::DipoleFix& m) { return {m.sensor_id(), m.sample_seq(), m.stamp_ns(), true}; }
inline MessageId IdOf(const msg::VesselNav& m) { return {m.vessel_id(), 0, m.stamp_ns()}; }
inline MessageId IdOf(const msg::TrackEstimate& m) { return {m.track_id(), 0, m.stamp_ns()}; }
inline MessageId IdOf(const msg::SensorPositionEstimate& m) { return {m.sensor_id(), 0, m.stamp_ns()}; }
inline MessageId IdOf(const msg::MapFix& m) { return {m.vehicle_id(), 0, m.stamp_ns()}; }

class RepeatFilter {
 public:
  // depth_per_key: how many recent messages of each key are remembered; at
  // least the writers' history depth (1000 per sensor, PROTOCOL.md).
  // max_keys: keys remembered at once; past it, the key used least recently
  // is forgotten (track ids are never reused: a recorder running for weeks
  // must not remember every track). Memory ≈ max_keys × depth × 70 bytes.
  explicit RepeatFilter(std::size_t depth_per_key = 2048, std::size_t max_keys = 256)
      : depth_(depth_per_key), max_keys_(max_keys) {}

  // True the first time `id` is offered; false (and counted) for a repeat.
  bool First(const MessageId& id);
  template <class M>
  bool First(const M& m) {
    return First(IdOf(m));
  }
  std::uint64_t repeats() const { return repeats_.load(); }
  // Forgets `id` (not its sequence): for a message the consumer refused at
  // its door, so that a refused message cannot make a later good one with
  // the same id look like a repeat (a bad sample must not poison state).
  void Forget(const MessageId& id);
  template <class M>
  void Forget(const M& m) {
    Forget(IdOf(m));
  }
  // Sequence numbers skipped (summed over keys), and steps back that were not
  // repeats; see above.
  std::uint64_t missing() const { return missing_.load(); }
  std::uint64_t restarts() const { return restarts_.load(); }
  // "magnav-inverter: magnav/gradiometer sensor": the first gap and the first
  // step back of each key are logged (warn) with this prefix; empty: no log.
  void SetLogName(std::string name) {
    std::lock_guard<std::mutex> lk(mu_);
    log_name_ = std::move(name);
  }
  std::size_t num_keys() const {
    std::lock_guard<std::mutex> lk(mu_);
    return keys_.size();
  }

 private:
  struct PerKey {
    std::set<MessageId> seen;
    std::deque<MessageId> order;  // oldest first, for eviction
    std::uint64_t last_use = 0;
    bool has_next = false;  // a sequenced message of this key was first
    std::uint64_t next_seq = 0;
    bool gap_logged = false, restart_logged = false;
  };
  void FollowSequence(const MessageId& id, PerKey& k);  // mu_ held
  std::size_t depth_;
  std::size_t max_keys_;
  std::uint64_t uses_ = 0;
  mutable std::mutex mu_;
  std::unordered_map<std::uint32_t, PerKey> keys_;
  std::string log_name_;
  std::atomic<std::uint64_t> repeats_{0}, missing_{0}, restarts_{0};
};

}  // namespace magnav::dds
