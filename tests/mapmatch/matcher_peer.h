// A test peer of magnav-matcher over loopback DDS: writers of the topics it consumes
// (vessel_nav, magnetometer samples) and a reader that keeps every map_fix it publishes.
// The service tests (service_test.cc, service_parity_test.cc) share it.
#pragma once

#include <chrono>
#include <cmath>
#include <cstddef>
#include <memory>
#include <mutex>
#include <vector>

#include "magnav/dds/node.h"

namespace magnav::testing {

// |F0| of the crustal map (tests/data/reference/README.md §4b): the reference field the tests give
// magnav-matcher (--reference-field) to turn a map anomaly into a total-field reading and back.
inline const double kCrustalReferenceField_nT =
    std::sqrt(22838.121767602996 * 22838.121767602996 + 1452.8242542037194 * 1452.8242542037194 +
              41845.01475649571 * 41845.01475649571);

class MatcherPeer {
  // Declared first, destroyed last: the writers and the reader below need the node, the reader's
  // callback the mutex and the vector.
  dds::Node node_;
  mutable std::mutex mu_;
  std::vector<dds::msg::MapFix> fixes_;

 public:
  explicit MatcherPeer(const dds::NodeOptions& options) : node_(options) {
    fix_reader_ = node_.CreateReader<dds::msg::MapFix>([this](const dds::msg::MapFix& m, const auto&) {
      std::lock_guard<std::mutex> lk(mu_);
      fixes_.push_back(m);
    });
    navs = node_.CreateWriter<dds::msg::VesselNav>();
    samples = node_.CreateWriter<dds::msg::MagnetometerSample>();
  }
  // The service matched on all three topics within `timeout`.
  bool WaitForService(std::chrono::milliseconds timeout) {
    return navs->WaitForMatched(1, timeout) && samples->WaitForMatched(1, timeout) &&
           fix_reader_->WaitForMatched(1, timeout);
  }
  std::size_t received() const {
    std::lock_guard<std::mutex> lk(mu_);
    return fixes_.size();
  }
  std::vector<dds::msg::MapFix> fixes() const {
    std::lock_guard<std::mutex> lk(mu_);
    return fixes_;
  }

  dds::Node& node() { return node_; }
  std::unique_ptr<dds::Writer<dds::msg::VesselNav>> navs;
  std::unique_ptr<dds::Writer<dds::msg::MagnetometerSample>> samples;

 private:
  std::unique_ptr<dds::Reader<dds::msg::MapFix>> fix_reader_;
};

}  // namespace magnav::testing
