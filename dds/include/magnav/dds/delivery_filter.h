// Which samples a magnav Reader hands on when it listens with two DataReaders
// (node.h): its profile's reader (RELIABLE, TRANSIENT_LOCAL: repairs losses
// and gets a transient-local writer's history after a restart) and an
// "any writer" companion (BEST_EFFORT, VOLATILE), which matches every writer
// whatever its reliability and durability, as a stock sensor driver's
// (Cyclone DDS's default RELIABLE/VOLATILE, ROS 2's sensor-data
// BEST_EFFORT/VOLATILE). A writer both match sends each sample to both.
//
// Rules (docs/PROTOCOL.md, "Any writer's QoS"):
//  - A writer matched by the profile's reader is served by it alone: the
//    companion drops its samples (they come reliably, in order, with history).
//  - Every sample is identified by its writer's GUID and RTPS sequence
//    number (SampleInfo::sample_identity), never by the payload: a driver
//    that leaves the payload's seq at 0 or restarts it is not dropped. A
//    sample of an identity already handed on (the companion got it before the
//    profile's reader had matched that writer) is dropped and counted.
//  - Per writer a window of the last kWindow sequence numbers is remembered;
//    a number below the window is older than anything both readers could have
//    handed on twice (history repair delivers old numbers once) and passes.
//    At most kMaxWriters writers are remembered (least recently heard first
//    out): memory is bounded by kMaxWriters × kWindow / 8 bytes.
// Thread-safe (the two DataReaders call from their own threads).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <set>
#include <vector>

namespace magnav::dds {

using WriterGuid = std::array<std::uint8_t, 16>;

class DeliveryFilter {
 public:
  static constexpr std::uint64_t kWindow = 8192;
  static constexpr std::size_t kMaxWriters = 256;

  enum class Verdict { kDeliver, kServedByProfileReader, kDuplicate };

  // on_subscription_matched of either reader: `change` +1 matched, -1 gone.
  void Matched(bool companion, const WriterGuid& writer, int change);
  // A sample that reader `companion` took from `writer` with RTPS sequence
  // number `sn`: hand it on, or drop it (and why).
  Verdict Offer(bool companion, const WriterGuid& writer, std::uint64_t sn);
  // Writers currently matched by either reader (each counted once).
  int matched_writers() const;
  // Writers currently matched by the companion only (their QoS is not the
  // profile's: best-effort or volatile writers).
  int companion_only_writers() const;

 private:
  struct Window {
    std::uint64_t highest = 0;  // highest sequence number handed on (0 = none yet)
    std::vector<std::uint64_t> bits = std::vector<std::uint64_t>(kWindow / 64, 0);
    std::uint64_t last_use = 0;
  };
  bool FirstTime(Window& w, std::uint64_t sn);  // mu_ held
  mutable std::mutex mu_;
  std::set<WriterGuid> profile_matched_, companion_matched_;
  std::map<WriterGuid, Window> windows_;
  std::uint64_t uses_ = 0;
};

}  // namespace magnav::dds
