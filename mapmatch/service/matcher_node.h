// The matcher's DDS node: VesselNav (magnav/vessel_nav, the vehicle's INS/DR
// with geodetic lat/lon) and MagnetometerSample (magnav/magnetometer) in,
// MapFix (magnav/map_fix) out on a schedule (every N metres travelled, or
// every step). The filter is the library's (mapmatch/particle_filter.h, what
// `magnav match --method pf|afpf` runs), so on the same stream and seed its
// fixes are the offline ones.
//
// Pairing: a magnetometer sample is matched with the latest VesselNav whose
// stamp is at or before its own, once a VesselNav at or after it has arrived
// (the position then is known); `magnav replay --map-path` sends both with the
// same stamp. Measurement: anomaly = |B| (nT) − reference field (nT)
// (docs/PROTOCOL.md). At the door (counted, warned once per kind): a
// VesselNav of another vehicle or of source NAV_GNSS is ignored; one with a
// non-finite geodetic lat/lon is skipped; a magnetometer sample of another
// sensor is ignored; one not later than the last step, or before the first
// VesselNav, is skipped. A non-finite B goes to the filter as a missing
// reading (it predicts and counts it), an INS jump is the filter's to handle.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "magnav/dds/convert_mapmatch.h"
#include "magnav/dds/node.h"
#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/stamp_guard.h"
#include "magnav/mapmatch/fix_schedule.h"
#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/observability.h"
#include "magnav/mapmatch/particle_filter.h"
#include "magnav/mapmatch/run_status.h"

namespace magnav::mapmatch {

struct MatcherNodeOptions {
  ParticleFilterKind kind = ParticleFilterKind::kAfpf;
  ParticleFilterOptions filter;
  // A MapFix every this many metres travelled (the paper: once per km); 0 = every step.
  double fix_every_m = 1000.0;
  // The map's reference field (nT): anomaly = |B| − this. No default.
  double reference_field_nT = std::numeric_limits<double>::quiet_NaN();
  std::uint32_t vehicle_id = 0;  // VesselNav.vessel_id followed, MapFix.vehicle_id
  std::uint32_t sensor_id = 0;   // MagnetometerSample.sensor_id used
  // At most this many VesselNav and magnetometer samples wait to be paired
  // (memory bound: a matcher whose sensor never sends must not grow); beyond
  // it the oldest is dropped, counted and warned about once.
  std::size_t max_buffered = 10000;
  // "Partly observable" at each fix (observability.h, StepObservability; the
  // review `magnav match` makes at a path's end): the prior not given = the
  // filter's own (ParticleFilterInsPrior: its prior square and drift);
  // min_information_ratio 1 by default, 0 = never.
  ObservabilityOptions observability;
  // The status review's plausible correction (deg; RunStatus, run_status.h; `--max-correction`, as
  // `magnav match`'s): 0 = 2 × the filter's prior half-width.
  double max_correction_deg = 0.0;

  bool IsValid(std::string* error) const;
};

// The map-matching messages (anomaly, INS fix, anomaly sample) are in
// dds/convert.h, shared with `magnav replay`.
using dds::AnomalyOf;
using dds::AnomalySampleMsg;
using dds::InsNavMsg;

// The fix (dds/convert_mapmatch.h, magnav::dds_mapmatch): method METHOD_PF / METHOD_AFPF, method_name
// "pf"/"afpf", score = ESS, covariance (north, east) m², status LOST while the filter's lost-track detector
// is raised (StepDiagnostics::lost), OFF_MAP when every particle was off the map at this step, else
// PARTLY_OBSERVABLE when the map knows less than the prior along its least observed direction at this step
// (MatcherNodeOptions::observability; the published covariance then raised along that direction to what the
// map and the prior can know, FloorAlongLeastKnown in deg² before the conversion to m² north/east), else
// CONVERGING while the filter has not settled (StepDiagnostics::converging, settle_updates), else OK.
// The run's status (RunStatus, run_status.h: the rules `magnav match` applies to a whole path, here at
// every step: the AFPF's σ at its cap or the estimate sliding against the INS on dense readings, a lost
// episode not yet settled, a correction beyond --max-correction, a non-finite estimate) makes a fix
// that would otherwise be OK, CONVERGING or PARTLY_OBSERVABLE LOST ("not converged" offline: do not use
// the position; the position and covariance published are the filter's, as offline); its verdict
// "converging" (the filter not settled) does not: that fix is CONVERGING.
using dds::ToMsg;

class MatcherNode {
 public:
  // `grid` must outlive the node.
  MatcherNode(dds::Node& node, const GeoGrid& grid, std::size_t layer, const MatcherNodeOptions& options);
  bool WaitForAcknowledgments(std::chrono::milliseconds timeout) { return writer_->WaitForAcknowledgments(timeout); }

  std::uint64_t navs_received() const { return nav_reader_->stats().samples.load(); }
  std::uint64_t samples_received() const { return mag_reader_->stats().samples.load(); }
  std::uint64_t steps() const { return steps_; }
  std::uint64_t skipped() const { return skipped_; }
  // Messages of another vehicle, sensor or source (not this matcher's).
  std::uint64_t ignored() const { return ignored_; }
  // Messages waiting to be paired now (bounded by max_buffered each).
  std::size_t buffered() const;
  // Messages seen before (dropped), magnetometer sequence numbers never received.
  std::uint64_t repeated() const { return repeats_.repeats() + nav_repeats_.repeats(); }
  // Messages with a wild stamp or seq, dropped by the time rule (dds/stamp_guard.h).
  std::uint64_t wild() const { return guard_.rejected() + nav_guard_.rejected(); }
  std::uint64_t missing() const { return repeats_.missing(); }
  std::uint64_t published() const { return writer_->stats().samples.load(); }
  FilterCounters filter_counters() const;
  // The run's status after the last step (what `magnav match` would say of the stream so far).
  RunVerdict run_verdict() const;
  std::string run_reason() const;

 private:
  void OnNav(const dds::msg::VesselNav& m, const dds::fdds::SampleInfo& info);
  void TakeNav(const dds::msg::VesselNav& m);
  void OnSample(const dds::msg::MagnetometerSample& m, const dds::fdds::SampleInfo& info);
  void TakeSample(const dds::msg::MagnetometerSample& m);
  void Drain();                                // mu_ held
  void Skip(const std::string& why, double t_s);  // mu_ held
  void Ignore(const std::string& what);           // once per kind, then counted

  MatcherNodeOptions options_;
  mutable std::mutex mu_;
  std::unique_ptr<SequentialMatcher> filter_;
  RunStatus status_;  // mu_ held
  StepObservability observe_;  // mu_ held
  FixSchedule schedule_;
  std::map<std::uint64_t, std::pair<double, double>> navs_;  // stamp -> INS lat, lon
  std::map<std::uint64_t, double> pending_;                  // stamp -> anomaly, nT
  bool stepped_ = false;
  std::uint64_t last_step_ns_ = 0;
  std::set<std::string> warned_;
  std::atomic<std::uint64_t> steps_{0}, skipped_{0}, ignored_{0};
  std::mutex ignore_mu_;
  std::set<std::string> warned_ignored_;
  dds::RepeatFilter repeats_;      // magnetometer samples of our sensor
  dds::StampGuard<dds::msg::MagnetometerSample> guard_{"magnav-matcher: magnav/magnetometer sensor"};  // wild stamps and seqs held, then dropped or confirmed
  dds::RepeatFilter nav_repeats_;  // vessel_nav of our vehicle
  dds::StampGuard<dds::msg::VesselNav> nav_guard_{"magnav-matcher: magnav/vessel_nav vehicle"};  // wild stamps and seqs held, then dropped or confirmed
  std::unique_ptr<dds::Writer<dds::msg::MapFix>> writer_;
  std::unique_ptr<dds::Reader<dds::msg::VesselNav>> nav_reader_;
  std::unique_ptr<dds::Reader<dds::msg::MagnetometerSample>> mag_reader_;
};

}  // namespace magnav::mapmatch
