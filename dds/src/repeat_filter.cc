#include "magnav/dds/repeat_filter.h"

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
  k.order.push_back(id);
  if (k.order.size() > depth_) {
    k.seen.erase(k.order.front());
    k.order.pop_front();
  }
  return true;
}

}  // namespace magnav::dds
