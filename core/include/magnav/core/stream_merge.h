// Merging several time-stamped streams (one per sensor, the GNSS, …) into one
// time order before an estimator takes them: the one implementation the
// streaming localizer (localizer/stream.h) and magnav-tracker use.
//
// Items are pushed as they arrive (each with its sample time, its stream and
// a rank) and handed on in (time, rank, arrival) order once the merge rule
// says nothing older can still come:
//  - kReorderDelay: once an item reorder_delay_s newer (sample time) has
//    arrived on any stream. For streams that arrive merged already.
//  - kWatermark: once every live stream has sent an item at least as new
//    (per-stream watermark). A stream that has sent nothing for
//    idle_timeout_s of wall-clock time (Tick) stops holding the others (a
//    quiet or dead sensor); a declared stream not seen yet holds them for
//    idle_timeout_s from the first arrival on any stream (two topics'
//    histories that arrive one after the other after a restart). When every
//    stream is quiet, items up to the oldest stream's newest time are handed
//    on. Without a clock (Tick never called) every stream counts as live.
//    Independent of arrival pace: unpaced replays and a restart merge
//    exactly as a paced run does.
// Beyond max_pending waiting items the oldest is handed on whatever the rule
// says (memory bound).
//
// Units: sample times and wall clock in s (the wall clock from any monotonic
// origin). Header-only (a template over the item type); no DDS. Not thread-safe.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <utility>

namespace magnav {

enum class StreamMerge {
  kReorderDelay,  // see above
  kWatermark,     // see above
};

struct StreamMergeOptions {
  StreamMerge merge = StreamMerge::kWatermark;
  // kReorderDelay: sample time (s) an item waits for a newer one; infinity =
  // only at ReleaseAll.
  double reorder_delay_s = 1.0;
  // kWatermark: a stream silent this long (wall clock, s) stops holding the others.
  double idle_timeout_s = 2.0;
  // At most this many items wait.
  std::size_t max_pending = 1000000;

  bool IsValid(std::string* error) const {
    if (!(reorder_delay_s >= 0.0)) {
      if (error) *error = "reorder_delay_s must be >= 0";
      return false;
    }
    if (!(idle_timeout_s > 0.0) || !std::isfinite(idle_timeout_s)) {
      if (error) *error = "idle_timeout_s must be finite and > 0";
      return false;
    }
    if (max_pending < 1) {
      if (error) *error = "max_pending must be >= 1";
      return false;
    }
    return true;
  }
};

template <class Item>
class StreamMerger {
 public:
  // (sample time, rank, arrival number): at equal times the order does not
  // depend on how streams interleave on arrival (live = offline), only on the
  // rank the caller gives (e.g. the sensor id).
  using Key = std::tuple<double, std::int64_t, std::uint64_t>;

  explicit StreamMerger(const StreamMergeOptions& options = {}) : options_(options) {}

  // A stream expected from the start (kWatermark: it holds the others from
  // the first arrival until it is seen or idle_timeout_s has passed).
  // Streams not declared count from their first item on.
  void Declare(std::int64_t stream) { streams_.try_emplace(stream); }

  // Buffers an item of `stream` at sample time t_s.
  void Push(double t_s, std::int64_t stream, std::int64_t rank, Item item) {
    pending_.emplace(Key{t_s, rank, arrivals_++}, std::move(item));
    newest_t_ = std::max(newest_t_, t_s);
    Note(stream, t_s);
  }
  // `stream` is alive and has reached t_s without an item to merge (e.g. an
  // item a checkpoint consumed already).
  void Note(std::int64_t stream, double t_s) {
    State& st = streams_[stream];
    st.last_t = std::max(st.last_t, t_s);
    st.last_arrival = now_s_;
    if (std::isnan(first_arrival_s_)) first_arrival_s_ = now_s_;
  }
  // The wall clock (s) given to the next arrivals and used for idleness.
  void Tick(double now_s) { now_s_ = now_s; }

  // Items up to this sample time may be handed on now.
  double ReleasableUntil() const {
    if (options_.merge == StreamMerge::kReorderDelay) return newest_t_ - options_.reorder_delay_s;
    const bool clock = std::isfinite(now_s_);
    double live = kInf, all = kInf;
    bool any_live = false;
    for (const auto& [id, st] : streams_) {
      const bool seen = !std::isnan(st.last_arrival);
      const double arrival = seen ? st.last_arrival : first_arrival_s_;
      if (seen) all = std::min(all, st.last_t);
      if (clock && !std::isnan(arrival) && now_s_ - arrival > options_.idle_timeout_s) continue;  // quiet
      any_live = true;
      live = std::min(live, st.last_t);
    }
    return any_live ? live : all;
  }

  // Hands every item the rule releases (or all of them) to consume(item), in order.
  template <class F>
  void Release(F&& consume, bool all = false) {
    const double until = all ? kInf : ReleasableUntil();
    while (!pending_.empty() &&
           (all || std::get<0>(pending_.begin()->first) <= until || pending_.size() > options_.max_pending)) {
      auto node = pending_.extract(pending_.begin());
      consume(node.mapped());
    }
  }

  // The waiting items, in the order they will be handed on.
  const std::map<Key, Item>& pending() const { return pending_; }
  bool empty() const { return pending_.empty(); }
  std::size_t size() const { return pending_.size(); }
  double front_time() const { return pending_.empty() ? kInf : std::get<0>(pending_.begin()->first); }
  // Drops the oldest waiting item.
  void PopFront() { pending_.erase(pending_.begin()); }
  const StreamMergeOptions& options() const { return options_; }
  std::size_t num_streams() const { return streams_.size(); }
  // Items pushed so far.
  std::uint64_t pushed() const { return arrivals_; }

 private:
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  struct State {
    double last_t = -kInf;                                      // sample time of its newest item
    double last_arrival = std::numeric_limits<double>::quiet_NaN();  // wall clock; NaN: not seen yet
  };
  StreamMergeOptions options_;
  std::map<Key, Item> pending_;
  std::map<std::int64_t, State> streams_;
  double now_s_ = std::numeric_limits<double>::quiet_NaN();
  double first_arrival_s_ = std::numeric_limits<double>::quiet_NaN();
  std::uint64_t arrivals_ = 0;
  double newest_t_ = -kInf;
};

}  // namespace magnav
