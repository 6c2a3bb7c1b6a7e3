#include "magnav/dds/repeat_filter.h"

#include <utility>

#include <spdlog/spdlog.h>

namespace magnav::dds {

bool RepeatFilter::First(const MessageId& id) {
  std::lock_guard<std::mutex> lk(mu_);
  if (keys_.size() >= max_keys_ && !keys_.count(id.key)) {
    auto oldest = keys_.begin();
    for (auto it = keys_.begin(); it != keys_.end(); ++it) {
      if (it->second.last_use < oldest->second.last_use) oldest = it;
    }
    keys_.erase(oldest);
  }
  PerKey& k = keys_[id.key];
  k.last_use = ++uses_;
  if (!k.seen.insert(id).second) {
    ++repeats_;
    return false;
  }
  if (id.sequenced) FollowSequence(id, k);
  k.order.push_back(id);
  if (k.order.size() > depth_) {
    k.seen.erase(k.order.front());
    k.order.pop_front();
  }
  return true;
}

void RepeatFilter::Forget(const MessageId& id) {
  std::lock_guard<std::mutex> lk(mu_);
  const auto it = keys_.find(id.key);
  if (it != keys_.end()) it->second.seen.erase(id);  // its place in `order` goes when evicted
}

void RepeatFilter::FollowSequence(const MessageId& id, PerKey& k) {
  if (k.has_next && id.seq > k.next_seq) {
    const std::uint64_t skipped = id.seq - k.next_seq;
    missing_ += skipped;
    if (!log_name_.empty() && !std::exchange(k.gap_logged, true)) {
      spdlog::warn("{} {}: {} message(s) missing before seq {} (seq {}..{} never arrived; further gaps of this key "
                   "are only counted)",
                   log_name_, id.key, skipped, id.seq, k.next_seq, id.seq - 1);
    }
  } else if (k.has_next && id.seq < k.next_seq) {
    ++restarts_;
    if (!log_name_.empty() && !std::exchange(k.restart_logged, true)) {
      spdlog::warn("{} {}: seq went back from {} to {} with a new time stamp (a producer that started over; further "
                   "ones of this key are only counted)",
                   log_name_, id.key, k.next_seq - 1, id.seq);
    }
  }
  k.has_next = true;
  k.next_seq = id.seq + 1;
}

}  // namespace magnav::dds
