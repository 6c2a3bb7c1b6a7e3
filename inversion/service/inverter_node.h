// The inverter's DDS node: GradiometerSample in, DipoleFix out (one per
// sample, rejected ones too, with the gate's reason). All inversion logic is
// in the magnav::inversion library; this only wires it to topics. Each sample
// passes the door (SampleDoor: a bad one is counted, logged once per sensor
// and answered with a rejected fix, "non_finite" or "zero_tensor"), then gets
// its sensor's B0 from the RegionalFieldSource ("no_b0" while unknown), which
// the node subtracts from B: the library runs with B0_W = 0.
#pragma once

#include <chrono>
#include <memory>
#include <mutex>
#include <variant>

#include "magnav/dds/convert_inversion.h"
#include "magnav/dds/node.h"
#include "magnav/dds/regional_field_source.h"
#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/stamp_guard.h"
#include "magnav/dds/sample_door.h"
#include "magnav/inversion/inverter.h"
#include "magnav/inversion/particle_filter.h"

namespace magnav::inversion {

// Library fix -> topic message: dds/convert_inversion.h (magnav::dds_inversion).
using dds::ToMsg;

class InverterNode {
 public:
  // Single-sample methods (TED, TED+EGT, EGT) with the speed gate's per-sensor
  // state. Throws InputError if options.B0_W is not zero (B0 comes from `b0`).
  InverterNode(dds::Node& node, const InverterOptions& options, std::unique_ptr<dds::RegionalFieldSource> b0);
  // Monte-Carlo inversion, one particle filter per sensor (B0 for the
  // initialising fixes only; the filter itself uses only T).
  InverterNode(dds::Node& node, const MonteCarloTrackerOptions& options,
               std::unique_ptr<dds::RegionalFieldSource> b0);

  std::uint64_t processed() const { return reader_->stats().samples.load(); }
  std::uint64_t published() const { return writer_->stats().samples.load(); }
  // At stop: until every matched reader has acknowledged every fix (bounded).
  bool WaitForAcknowledgments(std::chrono::milliseconds timeout) { return writer_->WaitForAcknowledgments(timeout); }
  const dds::EndpointStats& input_stats() const { return reader_->stats(); }
  std::uint64_t bad_samples() const { return door_.rejected(); }
  std::uint64_t repeated() const { return repeats_.repeats(); }
  // Messages with a wild stamp or seq, dropped by the time rule (dds/stamp_guard.h).
  std::uint64_t wild() const { return guard_.rejected(); }
  std::uint64_t missing() const { return repeats_.missing(); }  // sequence gaps of the samples
  const dds::RegionalFieldSource& b0() const { return *b0_; }

 private:
  void Start(dds::Node& node);
  void OnSample(const dds::msg::GradiometerSample& m, const dds::fdds::SampleInfo& info);
  void TakeSample(const dds::msg::GradiometerSample& m);

  std::mutex mu_;  // the middleware may call the listener from several receive threads
  dds::SampleDoor door_{"magnav-inverter"};
  dds::RepeatFilter repeats_;  // samples seen before: a restarted producer's history
  dds::StampGuard<dds::msg::GradiometerSample> guard_{"magnav-inverter: magnav/gradiometer sensor"};  // wild stamps and seqs held, then dropped or confirmed
  std::unique_ptr<dds::RegionalFieldSource> b0_;
  std::variant<Inverter, MonteCarloTracker> engine_;
  dds::FixMethod method_;
  std::unique_ptr<dds::Writer<dds::msg::DipoleFix>> writer_;
  std::unique_ptr<dds::Reader<dds::msg::GradiometerSample>> reader_;
};

}  // namespace magnav::inversion
