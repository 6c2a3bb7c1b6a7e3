#include "matcher_node.h"

#include <spdlog/spdlog.h>

#include <cmath>

#include "magnav/core/error.h"
#include "magnav/core/option_check.h"
#include "magnav/core/units.h"
#include "magnav/mapmatch/match.h"

namespace magnav::mapmatch {

bool MatcherNodeOptions::IsValid(std::string* error) const {
  if (!(std::isfinite(fix_every_m) && fix_every_m >= 0.0)) return Fail(error, "fix_every_m must be finite and >= 0");
  if (!(std::isfinite(max_correction_deg) && max_correction_deg >= 0.0)) {
    return Fail(error, "max_correction_deg must be finite and >= 0 (0 = 2 x the prior half-width)");
  }
  if (max_buffered < 1) return Fail(error, "max_buffered must be >= 1");
  if (!PositiveFinite(reference_field_nT)) {
    return Fail(error, "reference_field_nT (the map's reference field, nT) must be given, finite and > 0");
  }
  if (!observability.IsValid(error)) return false;
  return filter.IsValid(error);
}

namespace {
const MatcherNodeOptions& Checked(const MatcherNodeOptions& o) {
  std::string why;
  if (!o.IsValid(&why)) throw InputError("matcher options: " + why);
  return o;
}

InsErrorPrior PriorOf(const MatcherNodeOptions& o) {
  return o.observability.prior.given() ? o.observability.prior : ParticleFilterInsPrior(o.filter);
}
}  // namespace

MatcherNode::MatcherNode(dds::Node& node, const GeoGrid& grid, std::size_t layer, const MatcherNodeOptions& options)
    : options_(Checked(options)),
      filter_(MakeParticleFilter(options.kind, grid, layer, options.filter)),
      status_(options.kind, options.filter, options.max_correction_deg, RunStatusMemory::kRecent),
      observe_(grid, layer, PriorOf(options_), options_.observability),
      schedule_(options.fix_every_m, options.filter.max_step_deg) {
  repeats_.SetLogName("magnav-matcher: magnav/magnetometer sensor");
  writer_ = node.CreateWriter<dds::msg::MapFix>();
  nav_reader_ = node.CreateReader<dds::msg::VesselNav>([this](const dds::msg::VesselNav& m, const auto& info) { OnNav(m, info); });
  mag_reader_ = node.CreateReader<dds::msg::MagnetometerSample>(
      [this](const dds::msg::MagnetometerSample& m, const auto& info) { OnSample(m, info); });
}

FilterCounters MatcherNode::filter_counters() const {
  std::lock_guard<std::mutex> lk(mu_);
  return filter_->counters();
}

RunVerdict MatcherNode::run_verdict() const {
  std::lock_guard<std::mutex> lk(mu_);
  return status_.verdict();
}

std::string MatcherNode::run_reason() const {
  std::lock_guard<std::mutex> lk(mu_);
  return status_.reason();
}

void MatcherNode::Skip(const std::string& why, double t_s) {
  ++skipped_;
  if (warned_.insert(why).second) {
    spdlog::warn("magnav-matcher: sample at t = {} s skipped: {} (further ones are only counted)", t_s, why);
  }
}

std::size_t MatcherNode::buffered() const {
  std::lock_guard<std::mutex> lk(mu_);
  return navs_.size() + pending_.size();
}

void MatcherNode::Ignore(const std::string& what) {
  ++ignored_;
  std::lock_guard<std::mutex> lk(ignore_mu_);
  if (warned_ignored_.insert(what).second) {
    spdlog::warn("magnav-matcher: {} ignored: this matcher follows vehicle {} (--vehicle-id) and sensor {} "
                 "(--sensor-id) (further ones are only counted)",
                 what, options_.vehicle_id, options_.sensor_id);
  }
}

void MatcherNode::OnNav(const dds::msg::VesselNav& m, const dds::fdds::SampleInfo& info) {
  if (m.vessel_id() != options_.vehicle_id) return Ignore("vessel_nav of vehicle " + std::to_string(m.vessel_id()));
  if (m.source() == dds::msg::NAV_GNSS) return Ignore("a GNSS vessel_nav (the matcher corrects an INS/DR path)");
  if (!nav_repeats_.First(m, info)) return;
  for (const auto& admitted : nav_guard_.Admit(m)) TakeNav(admitted);
}

// A message the time rule admitted (dds/stamp_guard.h).
void MatcherNode::TakeNav(const dds::msg::VesselNav& m) {
  std::lock_guard<std::mutex> lk(mu_);
  const double lat = m.geodetic()[0], lon = m.geodetic()[1];
  if (!std::isfinite(lat) || !std::isfinite(lon)) {
    nav_repeats_.Forget(m);
    return Skip("vessel_nav without a finite geodetic lat/lon", NanosToSeconds(m.stamp_ns()));
  }
  navs_[m.stamp_ns()] = {lat, lon};
  if (navs_.size() > options_.max_buffered) {
    navs_.erase(navs_.begin());
    Skip("vessel_nav dropped unpaired: " + std::to_string(options_.max_buffered) +
             " wait for a magnetometer sample of sensor " + std::to_string(options_.sensor_id) +
             " (does that sensor send?)",
         NanosToSeconds(m.stamp_ns()));
  }
  Drain();
}

void MatcherNode::OnSample(const dds::msg::MagnetometerSample& m, const dds::fdds::SampleInfo& info) {
  if (m.sensor_id() != options_.sensor_id) {
    return Ignore("magnetometer sample of sensor " + std::to_string(m.sensor_id()));
  }
  if (!repeats_.First(m, info)) return;
  for (const auto& admitted : guard_.Admit(m)) TakeSample(admitted);
}

// A message the time rule admitted (dds/stamp_guard.h).
void MatcherNode::TakeSample(const dds::msg::MagnetometerSample& m) {
  std::lock_guard<std::mutex> lk(mu_);
  if (stepped_ && m.stamp_ns() <= last_step_ns_) {
    return Skip("magnetometer sample not later than the last step", NanosToSeconds(m.stamp_ns()));
  }
  pending_[m.stamp_ns()] = AnomalyOf(m, options_.reference_field_nT);
  if (pending_.size() > options_.max_buffered) {
    pending_.erase(pending_.begin());
    Skip("magnetometer sample dropped unpaired: " + std::to_string(options_.max_buffered) +
             " wait for a vessel_nav of vehicle " + std::to_string(options_.vehicle_id) + " (does it send?)",
         NanosToSeconds(m.stamp_ns()));
  }
  Drain();
}

void MatcherNode::Drain() {
  while (!pending_.empty() && !navs_.empty()) {
    const auto [stamp, anomaly] = *pending_.begin();
    if (navs_.rbegin()->first < stamp) return;  // its position is not known yet
    auto nav = navs_.upper_bound(stamp);        // first nav after the sample
    pending_.erase(pending_.begin());
    if (nav == navs_.begin()) {
      Skip("magnetometer sample before the first vessel_nav", NanosToSeconds(stamp));
      continue;
    }
    --nav;  // the latest at or before it
    const auto [lat, lon] = nav->second;
    navs_.erase(navs_.begin(), nav);  // keep the one used
    const StepDiagnostics& d = filter_->Step(lat, lon, anomaly);
    observe_.Step(d.lat_deg, d.lon_deg, anomaly);
    status_.Add(lat, lon, d, filter_->counters(), static_cast<long long>(steps_.load()));
    stepped_ = true;
    last_step_ns_ = stamp;
    ++steps_;
    if (schedule_.Step(lat, lon)) {
      StepDiagnostics fix = d;
      fix.run_status = status_.verdict();
      // Not converged by the run's rules (`magnav match` would say so): LOST on the wire (off_map
      // is the step's own OFF_MAP; the filter's own lost is LOST already; converging is the step's
      // own CONVERGING, not an alarm).
      if (fix.run_status != RunVerdict::kConverged && fix.run_status != RunVerdict::kOffMap &&
          fix.run_status != RunVerdict::kConverging) {
        fix.lost = true;
      }
      fix.partly_observable = observe_.partly_observable();
      if (fix.partly_observable) {
        Cov2 c{fix.cov_lat_lat, fix.cov_lat_lon, fix.cov_lon_lon};  // deg², floored before ToMsg's m² north/east
        if (observe_.Floor(&c)) {
          fix.cov_lat_lat = c.lat_lat;
          fix.cov_lat_lon = c.lat_lon;
          fix.cov_lon_lon = c.lon_lon;
        }
      }
      writer_->Write(ToMsg(fix, options_.kind, options_.vehicle_id, stamp));
    }
  }
}

}  // namespace magnav::mapmatch
