// The wire's time rule, in front of every estimator (issue 25 item 1). A
// stamp or seq that passes the door's finite-and-in-range checks can still be
// wild: 2^64-1 ns, a stamp in another clock, seq 10^18. Time has no absolute
// scale on the wire (a driver's clock may start anywhere), so the rule is
// relative to each stream (key), with the limits of core/limits.h:
//  - a stamp beyond kLimitTime (1e10 s, 317 years) is refused outright;
//  - a message whose stamp is more than kLimitTimeStep (1 h) from its
//    stream's last one, or whose seq is more than kLimitSeqStep (1e6) ahead
//    of it, is held as suspect: nothing is handed on;
//  - the next message decides: if it fits the stream's last one, the suspect
//    was wild and is dropped (counted in rejected(), logged once per key); if
//    it fits the suspect instead (within the step of it, seq not behind it),
//    the stream really moved (a clock reset, a new epoch): both are handed on
//    and the stream goes on from there (counted in jumps());
//  - a new suspect replaces an unconfirmed one (which is dropped and counted).
// The first message of a stream is taken as its start. A suspect that no
// message ever follows is never handed on. Unsequenced messages (VesselNav)
// are judged by their stamp only. Memory: one message per key held at most.
// Thread-safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <spdlog/spdlog.h>

#include "magnav/core/limits.h"
#include "magnav/dds/repeat_filter.h"

namespace magnav::dds {

template <class M>
class StampGuard {
 public:
  // `log_name` prefixes the log lines ("magnav-inverter: magnav/gradiometer sensor").
  explicit StampGuard(std::string log_name, double max_step_s = MaxAbs(kLimitTimeStep),
                      double max_seq_step = MaxAbs(kLimitSeqStep))
      : log_name_(std::move(log_name)),
        max_step_ns_(static_cast<std::uint64_t>(max_step_s * 1e9)),
        max_seq_step_(static_cast<std::uint64_t>(max_seq_step)) {}

  // The messages to hand on now, in order: none, `m`, or a confirmed suspect and `m`.
  std::vector<M> Admit(const M& m) {
    const MessageId id = IdOf(m);
    std::lock_guard<std::mutex> lk(mu_);
    if (static_cast<double>(id.stamp_ns) * 1e-9 > MaxAbs(kLimitTime)) {
      ++rejected_;
      Log(id.key, "time stamp " + std::to_string(id.stamp_ns) + " ns is beyond " +
                      std::to_string(static_cast<long long>(MaxAbs(kLimitTime))) + " s (" + LimitWhy(kLimitTime) + ")");
      return {};
    }
    PerKey& k = keys_[id.key];
    if (!k.last) {
      k.last = id;
      return {m};
    }
    if (Fits(*k.last, id)) {
      if (k.suspect) {
        ++rejected_;
        Log(id.key, Describe(IdOf(*k.suspect), *k.last) + ": dropped, the stream went on from before it");
        k.suspect.reset();
      }
      k.last = id;
      return {m};
    }
    if (k.suspect && Fits(IdOf(*k.suspect), id)) {
      ++jumps_;
      spdlog::warn("{} {}: {}, confirmed by the next message: the stream goes on from there", log_name_, id.key,
                   Describe(IdOf(*k.suspect), *k.last));
      std::vector<M> out = {*k.suspect, m};
      k.suspect.reset();
      k.last = id;
      return out;
    }
    if (k.suspect) {
      ++rejected_;
      Log(id.key, Describe(IdOf(*k.suspect), *k.last) + ": dropped, not confirmed");
    }
    k.suspect = m;
    ++held_;
    return {};
  }

  std::uint64_t rejected() const { return rejected_.load(); }  // wild stamps or seqs dropped
  std::uint64_t jumps() const { return jumps_.load(); }        // confirmed moves of a stream
  std::uint64_t held() const { return held_.load(); }          // messages held as suspect (so far)

 private:
  struct PerKey {
    std::optional<MessageId> last;  // the last message handed on
    std::optional<M> suspect;
    bool logged = false;
  };
  // Whether `next` continues the stream whose last message was `prev`.
  bool Fits(const MessageId& prev, const MessageId& next) const {
    const std::uint64_t step = next.stamp_ns > prev.stamp_ns ? next.stamp_ns - prev.stamp_ns
                                                              : prev.stamp_ns - next.stamp_ns;
    if (step > max_step_ns_) return false;
    if (next.sequenced && next.seq > prev.seq && next.seq - prev.seq > max_seq_step_) return false;
    return true;
  }
  std::string Describe(const MessageId& suspect, const MessageId& last) const {
    return "a message at stamp " + std::to_string(suspect.stamp_ns) + " ns, seq " + std::to_string(suspect.seq) +
           " after stamp " + std::to_string(last.stamp_ns) + " ns, seq " + std::to_string(last.seq) +
           " (more than the limits: " + std::to_string(max_step_ns_ / 1000000000ULL) + " s, seq step " +
           std::to_string(max_seq_step_) + ")";
  }
  void Log(std::uint32_t key, const std::string& what) {  // mu_ held
    PerKey& k = keys_[key];
    if (std::exchange(k.logged, true)) return;
    spdlog::warn("{} {}: {} (further ones of this key are only counted)", log_name_, key, what);
  }

  std::string log_name_;
  std::uint64_t max_step_ns_;
  std::uint64_t max_seq_step_;
  std::mutex mu_;
  std::map<std::uint32_t, PerKey> keys_;
  std::atomic<std::uint64_t> rejected_{0}, jumps_{0}, held_{0};
};

}  // namespace magnav::dds
