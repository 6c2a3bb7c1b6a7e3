#include "magnav/dds/repeat_filter.h"

namespace magnav::dds {

bool RepeatFilter::First(const MessageId& id) {
  std::lock_guard<std::mutex> lk(mu_);
  PerKey& k = keys_[id.key];
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
