// The CSV columns and rows `magnav record` writes per topic, shared by
// `magnav export` (the CSVs of an MCAP recording are the ones record writes).
#include "record_rows.h"

#include <algorithm>
#include <cmath>

#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/units.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::tools {
namespace {

std::string N(double v) { return FormatNumber(v); }

template <std::size_t K>
void Append(std::vector<std::string>& f, const std::array<double, K>& a) {
  for (double v : a) f.push_back(N(v));
}

// Every field of the message is written (covariances as 9 row-major columns,
// with sigma_x..z = the roots of their diagonals for `magnav evaluate`).
void AppendNamed(std::vector<std::string>& h, const std::string& prefix, const char* const* names, int n) {
  for (int i = 0; i < n; ++i) h.push_back(prefix + names[i]);
}
const char* const kXyz[] = {"x", "y", "z"};
const char* const kCov[] = {"xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"};

}  // namespace

std::vector<std::string> Header(const std::string& topic) {
  std::vector<std::string> h;
  if (topic == "gradiometer") {
    h = {"t", "sensor_id", "seq"};
    for (std::string& c : GradiometerDataColumns()) h.push_back(std::move(c));
    h.push_back("sigma_B");
    h.push_back("sigma_T");
    return h;
  }
  if (topic == "dipole_fix") {
    h = {"t", "sensor_id", "seq", "method", "dipole_x", "dipole_y", "dipole_z", "valid", "reason", "cond",
         "has_moment"};
    AppendNamed(h, "m_", kXyz, 3);
    AppendNamed(h, "sigma_", kXyz, 3);
    AppendNamed(h, "cov_", kCov, 9);
    return h;
  }
  if (topic == "magnetometer") return {"t", "sensor_id", "seq", "B_x", "B_y", "B_z"};
  if (topic == "vessel_nav") return {"t", "x", "y", "sigma"};
  if (topic == "map_fix") {
    // covariance (north, east) m², row-major, and its roots.
    return {"t", "vehicle_id", "method", "lat", "lon", "score", "sigma_north_m", "sigma_east_m", "cov_nn", "cov_ne",
            "cov_en", "cov_ee", "status"};
  }
  if (topic == "sensor_position") {
    // The columns of `magnav localize`'s output, with the estimate's time first.
    return {"t", "sensor_id", "x", "y", "z", "sigma_x", "sigma_y", "crlb_x", "crlb_y"};
  }
  h = {"t", "track_id", "x", "y", "z", "vx", "vy", "vz", "heading", "turn_rate", "sigma_x", "sigma_y", "sigma_z"};
  AppendNamed(h, "cov_", kCov, 9);
  AppendNamed(h, "moment_body_", kXyz, 3);
  AppendNamed(h, "moment_cov_", kCov, 9);
  h.push_back("num_sensors");
  h.push_back("usable");
  h.push_back("state");  // confirmed | coasting | "" (unknown: a publisher older than the field)
  return h;
}

namespace {
// Roots of a row-major 3×3 covariance's diagonal; empty when it is all zero
// (unknown).
void AppendSigmas(std::vector<std::string>& f, const std::array<double, 9>& cov) {
  const bool known = std::any_of(cov.begin(), cov.end(), [](double v) { return v != 0.0; });
  for (int i = 0; i < 3; ++i) f.push_back(known ? N(std::sqrt(std::max(0.0, cov[4 * i]))) : "");
}

}  // namespace

std::vector<std::string> Row(const dds::msg::MagnetometerSample& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.sensor_id()), std::to_string(m.seq())};
  Append(f, m.B());
  return f;
}

// A GNSS file row (t,x,y,sigma) as `magnav localize --gnss` reads it.
std::vector<std::string> Row(const dds::msg::VesselNav& m) {
  return {FormatNanosAsSeconds(m.stamp_ns()), N(m.position()[0]), N(m.position()[1]),
          N(std::max(m.sigma_position()[0], m.sigma_position()[1]))};
}

std::vector<std::string> Row(const dds::msg::SensorPositionEstimate& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.sensor_id())};
  Append(f, m.position());
  f.push_back(N(std::sqrt(std::max(0.0, m.covariance()[0]))));
  f.push_back(N(std::sqrt(std::max(0.0, m.covariance()[4]))));
  f.push_back(N(std::sqrt(std::max(0.0, m.crlb()[0]))));
  f.push_back(N(std::sqrt(std::max(0.0, m.crlb()[4]))));
  return f;
}

// MapFix.status as written in the CSV ("" = unknown: a publisher older than the field).
const char* MapFixStatusName(dds::msg::MapFixStatus s) {
  switch (s) {
    case dds::msg::MAP_FIX_STATUS_OK:
      return "ok";
    case dds::msg::MAP_FIX_STATUS_LOST:
      return "lost";
    case dds::msg::MAP_FIX_STATUS_OFF_MAP:
      return "off_map";
    case dds::msg::MAP_FIX_STATUS_PARTLY_OBSERVABLE:
      return "partly_observable";
    case dds::msg::MAP_FIX_STATUS_CONVERGING:
      return "converging";
    default:
      return "";
  }
}

// TrackEstimate.state as written in the CSV: `magnav track`'s words
// (tracker::TrackStateName); "" = unknown (a publisher older than the field).
const char* TrackStateName(dds::msg::TrackState s) {
  switch (s) {
    case dds::msg::TRACK_STATE_CONFIRMED:
      return tracker::TrackStateName(tracker::TrackState::kConfirmed);
    case dds::msg::TRACK_STATE_COASTING:
      return tracker::TrackStateName(tracker::TrackState::kCoasting);
    default:
      return "";
  }
}

std::vector<std::string> Row(const dds::msg::MapFix& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.vehicle_id()), m.method_name().c_str(),
                                N(m.lat_deg()), N(m.lon_deg()), N(m.score()),
                                N(std::sqrt(std::max(0.0, m.covariance()[0]))),
                                N(std::sqrt(std::max(0.0, m.covariance()[3])))};
  Append(f, m.covariance());
  f.push_back(MapFixStatusName(m.status()));
  return f;
}

std::vector<std::string> Row(const dds::msg::GradiometerSample& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.sensor_id()), std::to_string(m.seq())};
  Append(f, m.sensor_position());
  Append(f, m.B());
  Append(f, m.T());
  f.push_back(N(m.sigma_B()));
  f.push_back(N(m.sigma_T()));
  return f;
}

std::vector<std::string> Row(const dds::msg::DipoleFix& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.sensor_id()),
                                std::to_string(m.sample_seq()), std::to_string(static_cast<int>(m.method()))};
  Append(f, m.position());
  f.push_back(m.valid() ? "1" : "0");
  f.push_back(m.reason().c_str());
  f.push_back(N(m.condition_number()));
  f.push_back(m.has_moment() ? "1" : "0");
  Append(f, m.moment());
  AppendSigmas(f, m.covariance());
  Append(f, m.covariance());
  return f;
}

std::vector<std::string> Row(const dds::msg::TrackEstimate& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.track_id())};
  Append(f, m.position());
  Append(f, m.velocity());
  f.push_back(N(m.heading()));
  f.push_back(N(m.turn_rate()));
  AppendSigmas(f, m.covariance());
  Append(f, m.covariance());
  Append(f, m.moment_body());
  Append(f, m.moment_covariance());
  f.push_back(std::to_string(m.num_sensors()));
  f.push_back(m.usable() ? "1" : "0");
  f.push_back(TrackStateName(m.state()));
  return f;
}

}  // namespace magnav::tools
