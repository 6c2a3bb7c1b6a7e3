// The inverter's DDS node: GradiometerSample in, DipoleFix out (one per
// sample, rejected ones too, with the gate's reason). All inversion logic is
// in the magnav::inversion library; this only wires it to topics.
#pragma once

#include <memory>
#include <mutex>
#include <variant>

#include "magnav/dds/node.h"
#include "magnav/inversion/inverter.h"
#include "magnav/inversion/particle_filter.h"

namespace magnav::inversion {

// Library fix -> topic message (NED m, A·m², the sample's time stamp and seq).
dds::msg::DipoleFix ToMsg(const DipoleFix& fix, std::uint64_t stamp_ns, std::uint64_t sample_seq,
                          dds::msg::FixMethod method);

class InverterNode {
 public:
  // Single-sample methods (TED, TED+EGT, EGT) with the speed gate's per-sensor state.
  InverterNode(dds::Node& node, const InverterOptions& options);
  // Monte-Carlo inversion, one particle filter per sensor.
  InverterNode(dds::Node& node, const MonteCarloTrackerOptions& options);

  std::uint64_t processed() const { return reader_->stats().samples.load(); }
  std::uint64_t published() const { return writer_->stats().samples.load(); }
  const dds::EndpointStats& input_stats() const { return reader_->stats(); }

 private:
  void Start(dds::Node& node);
  void OnSample(const dds::msg::GradiometerSample& m);

  std::mutex mu_;  // the middleware may call the listener from several receive threads
  std::variant<Inverter, MonteCarloTracker> engine_;
  dds::msg::FixMethod method_;
  std::unique_ptr<dds::Writer<dds::msg::DipoleFix>> writer_;
  std::unique_ptr<dds::Reader<dds::msg::GradiometerSample>> reader_;
};

}  // namespace magnav::inversion
