// Recognises a message that arrived before, from the same or another writer.
// With TRANSIENT_LOCAL streams a reader that matches a writer late gets the
// writer's history, and a service restarted after kill -9 republishes results
// for samples it had already answered before it died (docs/RELIABILITY.md,
// "Crash and restart"): a new writer (GUID) with the same messages. Every
// stream message carries what identifies it: its key (sensor, track,
// vehicle), the sequence number of the sample it belongs to (samples: `seq`,
// fixes: `sample_seq`; estimates have none: 0) and its time stamp. A
// consumer passes each message through a RepeatFilter with its origin (the
// writer and a hash of the whole payload):
//  - first time this (key, seq, stamp): handed on;
//  - again with the same payload (any writer): a repeat, dropped, counted;
//  - again with another payload from ANOTHER writer: a conflict (two
//    producers of one sensor id, e.g. two replays at once): the first is
//    kept, the other dropped, counted in conflicts() and logged as an error
//    (once per key; later ones only counted);
//  - again with another payload from the SAME writer: a new message (a driver
//    whose seq stays 0 and whose clock ticks coarsely): handed on.
// The same DDS sample reaching a reader twice (its two DataReaders) never
// gets here: Reader drops it by writer GUID and RTPS sequence number.
// Remembered: the last `depth_per_key` messages of each key, of the last
// `max_keys` keys used. A restarted producer of new data (new stamps) is never
// taken for a repeat.
//
// Sequence gaps. For messages with a sequence number (samples and fixes,
// `MessageId::sequenced`) the filter also follows each key's next expected
// number: a message that skips numbers adds them to missing() (samples the
// producer numbered but this reader never got: lost on a best-effort path,
// older than a late joiner's history, or never sent by the sensor); one whose
// number goes back without being a repeat is counted in restarts() (a
// producer that started over, or another producer of the same key) and the
// expected number follows it. A key whose seq stays 0 (a driver that does not
// number its samples) is not followed: no gaps or restarts are counted for
// it. A jump of more than kMaxSeqStep is not counted as missing either (a
// wild seq, e.g. 10^18: counted in wild_steps()). The payload seq decides
// nothing else. Gaps and steps back are logged once per key when a log name
// is given (SetLogName); later ones are only counted (the services' stats
// lines). Messages that are not first never move the expected number.
// Thread-safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string_view>
#include <vector>
#include <string>
#include <tuple>
#include <unordered_map>

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastdds/dds/subscriber/SampleInfo.hpp>

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

// Where a message came from: its writer and a hash of its whole payload.
struct MessageOrigin {
  std::uint64_t writer = 0;   // hash of the writer's GUID (0 = unknown)
  std::uint64_t payload = 0;  // hash of the message's CDR serialisation
};

// A hash of everything a message says (its CDR serialisation). Computed for
// every first message: a later message with the same id is compared with the
// first one's hash, and the first message itself is not kept. Cost ≈ 39 ns
// per gradiometer sample, a fifth to a third of First() (docs/BENCHMARKS.md,
// "The repeat filter on the hot path").
template <class M>
std::uint64_t PayloadHash(const M& m) {
  thread_local std::vector<char> buffer;
  return std::hash<std::string_view>{}(SerializeCdr(m, &buffer));
}

std::uint64_t WriterHash(const eprosima::fastdds::dds::SampleInfo& info);

template <class M>
MessageOrigin OriginOf(const M& m, const eprosima::fastdds::dds::SampleInfo& info) {
  return {WriterHash(info), PayloadHash(m)};
}

class RepeatFilter {
 public:
  // depth_per_key: how many recent messages of each key are remembered; at
  // least the writers' history depth (1000 per sensor, PROTOCOL.md).
  // max_keys: keys remembered at once; past it, the key used least recently
  // is forgotten (track ids are never reused: a recorder running for weeks
  // must not remember every track). Memory ≈ max_keys × depth × 70 bytes.
  explicit RepeatFilter(std::size_t depth_per_key = 2048, std::size_t max_keys = 256)
      : depth_(depth_per_key), max_keys_(max_keys) {}

  // A seq step beyond this is not counted as missing samples (a wild seq).
  static constexpr std::uint64_t kMaxSeqStep = 1000000;

  // True the first time `id` is offered (or a new payload from the same
  // writer); false for a repeat or a conflict (counted).
  bool First(const MessageId& id, const MessageOrigin& origin);
  template <class M>
  bool First(const M& m, const eprosima::fastdds::dds::SampleInfo& info) {
    return First(IdOf(m), OriginOf(m, info));
  }
  // Without an origin: every repeat of the id is taken for the same message.
  bool First(const MessageId& id) { return First(id, MessageOrigin{}); }
  // Without a DDS sample (tests, files): the writer unknown (0).
  template <class M>
  bool First(const M& m) {
    return First(IdOf(m), MessageOrigin{0, PayloadHash(m)});
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
  // Same (key, seq, stamp), another payload, another writer: the later one dropped.
  std::uint64_t conflicts() const { return conflicts_.load(); }
  // Seq steps beyond kMaxSeqStep (not counted as missing).
  std::uint64_t wild_steps() const { return wild_steps_.load(); }
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
    std::map<MessageId, MessageOrigin> seen;
    std::deque<MessageId> order;  // oldest first, for eviction
    std::uint64_t last_use = 0;
    bool has_next = false;  // a sequenced message of this key was first
    std::uint64_t next_seq = 0;
    bool unsequenced = false;  // its seq stayed 0: not followed
    bool gap_logged = false, restart_logged = false, conflict_logged = false;
  };
  void FollowSequence(const MessageId& id, PerKey& k);  // mu_ held
  std::size_t depth_;
  std::size_t max_keys_;
  std::uint64_t uses_ = 0;
  mutable std::mutex mu_;
  std::unordered_map<std::uint32_t, PerKey> keys_;
  std::string log_name_;
  std::atomic<std::uint64_t> repeats_{0}, missing_{0}, restarts_{0}, conflicts_{0}, wild_steps_{0};
};

}  // namespace magnav::dds
