#include "magnav/dds/delivery_filter.h"

#include <algorithm>

namespace magnav::dds {

void DeliveryFilter::Matched(bool companion, const WriterGuid& writer, int change) {
  std::lock_guard<std::mutex> lk(mu_);
  auto& set = companion ? companion_matched_ : profile_matched_;
  if (change > 0) {
    set.insert(writer);
  } else if (change < 0) {
    set.erase(writer);
  }
}

DeliveryFilter::Verdict DeliveryFilter::Offer(bool companion, const WriterGuid& writer, std::uint64_t sn) {
  std::lock_guard<std::mutex> lk(mu_);
  if (companion && profile_matched_.count(writer)) return Verdict::kServedByProfileReader;
  auto it = windows_.find(writer);
  if (it == windows_.end()) {
    if (windows_.size() >= kMaxWriters) {
      windows_.erase(std::min_element(windows_.begin(), windows_.end(), [](const auto& a, const auto& b) {
        return a.second.last_use < b.second.last_use;
      }));
    }
    it = windows_.emplace(writer, Window{}).first;
  }
  it->second.last_use = ++uses_;
  return FirstTime(it->second, sn) ? Verdict::kDeliver : Verdict::kDuplicate;
}

bool DeliveryFilter::FirstTime(Window& w, std::uint64_t sn) {
  const auto bit = [&](std::uint64_t s) -> std::uint64_t& { return w.bits[(s % kWindow) / 64]; };
  const auto mask = [](std::uint64_t s) { return std::uint64_t{1} << (s % 64); };
  if (sn > w.highest) {
    // Slide the window: the numbers between the old highest and sn were not
    // handed on (yet); clear their bits.
    if (sn - w.highest >= kWindow) {
      std::fill(w.bits.begin(), w.bits.end(), 0);
    } else {
      for (std::uint64_t s = w.highest + 1; s < sn; ++s) bit(s) &= ~mask(s);
    }
    w.highest = sn;
    bit(sn) |= mask(sn);
    return true;
  }
  if (w.highest - sn >= kWindow) return true;  // older than the window: history repair, once
  if (bit(sn) & mask(sn)) return false;
  bit(sn) |= mask(sn);
  return true;
}

int DeliveryFilter::matched_writers() const {
  std::lock_guard<std::mutex> lk(mu_);
  int n = static_cast<int>(profile_matched_.size());
  for (const auto& w : companion_matched_) n += profile_matched_.count(w) ? 0 : 1;
  return n;
}

int DeliveryFilter::companion_only_writers() const {
  std::lock_guard<std::mutex> lk(mu_);
  int n = 0;
  for (const auto& w : companion_matched_) n += profile_matched_.count(w) ? 0 : 1;
  return n;
}

}  // namespace magnav::dds
