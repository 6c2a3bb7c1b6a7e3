#include "magnav/dds/repeat_filter.h"

#include <utility>

#include <spdlog/spdlog.h>

namespace magnav::dds {

std::uint64_t WriterHash(const eprosima::fastdds::dds::SampleInfo& info) {
  const auto& g = info.sample_identity.writer_guid();
  std::string_view bytes[2] = {
      std::string_view(reinterpret_cast<const char*>(g.guidPrefix.value), sizeof g.guidPrefix.value),
      std::string_view(reinterpret_cast<const char*>(g.entityId.value), sizeof g.entityId.value)};
  std::uint64_t h = std::hash<std::string_view>{}(bytes[0]);
  h ^= std::hash<std::string_view>{}(bytes[1]) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
  return h == 0 ? 1 : h;  // 0 means "unknown writer"
}

bool RepeatFilter::First(const MessageId& id, const MessageOrigin& origin) {
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
  const auto [it, inserted] = k.seen.emplace(id, origin);
  if (!inserted) {
    const MessageOrigin& first = it->second;
    if (first.payload == origin.payload) {
      ++repeats_;
      return false;
    }
    if (first.writer == origin.writer && origin.writer != 0) return true;  // the same writer's next message
    ++conflicts_;
    if (!std::exchange(k.conflict_logged, true)) {
      spdlog::error("{} {}: two producers send different messages with the same seq {} and time stamp {} ns: "
                    "the first is kept, the other dropped (two drivers or replays with one id? further conflicts "
                    "of this key are only counted)",
                    log_name_.empty() ? std::string("key") : log_name_, id.key, id.seq, id.stamp_ns);
    }
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
  if (k.unsequenced) return;
  if (id.seq == 0 && k.has_next && k.next_seq == 1) {
    // Its seq stayed 0 for two messages: a producer that does not number them.
    k.unsequenced = true;
    if (!log_name_.empty()) {
      spdlog::info("{} {}: seq stays 0 (the producer does not number its samples): no gaps are counted for it",
                   log_name_, id.key);
    }
    return;
  }
  if (k.has_next && id.seq > k.next_seq && id.seq - k.next_seq > kMaxSeqStep) {
    ++wild_steps_;
    if (!log_name_.empty() && !std::exchange(k.gap_logged, true)) {
      spdlog::warn("{} {}: seq jumped from {} to {} (more than {}: not counted as missing)", log_name_, id.key,
                   k.next_seq - 1, id.seq, kMaxSeqStep);
    }
    k.next_seq = id.seq + 1;
    return;
  }
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
