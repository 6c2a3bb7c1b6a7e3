#include "magnav/dds/convert.h"

#include <cmath>
#include <limits>

#include "magnav/core/tensor.h"
#include "magnav/core/units.h"

namespace magnav::dds {

// The record enums are the IDL's, value for value (records.h).
static_assert(static_cast<std::uint32_t>(FixMethod::kTed) == msg::METHOD_TED);
static_assert(static_cast<std::uint32_t>(FixMethod::kTedEgt) == msg::METHOD_TED_EGT);
static_assert(static_cast<std::uint32_t>(FixMethod::kEgt) == msg::METHOD_EGT);
static_assert(static_cast<std::uint32_t>(FixMethod::kMc) == msg::METHOD_MC);
static_assert(static_cast<std::uint32_t>(FixMethod::kTracker) == msg::METHOD_TRACKER);
static_assert(static_cast<std::uint32_t>(FixMethod::kOther) == msg::METHOD_OTHER);
static_assert(static_cast<std::uint32_t>(FixMethod::kPf) == msg::METHOD_PF);
static_assert(static_cast<std::uint32_t>(FixMethod::kAfpf) == msg::METHOD_AFPF);
static_assert(static_cast<std::uint32_t>(MapFixStatus::kUnknown) == msg::MAP_FIX_STATUS_UNKNOWN);
static_assert(static_cast<std::uint32_t>(MapFixStatus::kOk) == msg::MAP_FIX_STATUS_OK);
static_assert(static_cast<std::uint32_t>(MapFixStatus::kLost) == msg::MAP_FIX_STATUS_LOST);
static_assert(static_cast<std::uint32_t>(MapFixStatus::kOffMap) == msg::MAP_FIX_STATUS_OFF_MAP);
static_assert(static_cast<std::uint32_t>(MapFixStatus::kPartlyObservable) == msg::MAP_FIX_STATUS_PARTLY_OBSERVABLE);
static_assert(static_cast<std::uint32_t>(MapFixStatus::kConverging) == msg::MAP_FIX_STATUS_CONVERGING);
static_assert(static_cast<std::uint32_t>(TrackState::kUnknown) == msg::TRACK_STATE_UNKNOWN);
static_assert(static_cast<std::uint32_t>(TrackState::kConfirmed) == msg::TRACK_STATE_CONFIRMED);
static_assert(static_cast<std::uint32_t>(TrackState::kCoasting) == msg::TRACK_STATE_COASTING);
static_assert(static_cast<std::uint32_t>(NavSource::kGnss) == msg::NAV_GNSS);
static_assert(static_cast<std::uint32_t>(NavSource::kIns) == msg::NAV_INS);
static_assert(static_cast<std::uint32_t>(NavSource::kOther) == msg::NAV_OTHER);

namespace {

Eigen::Vector3d Vec(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }
std::array<double, 3> Arr(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
// Row-major 3×3 (magnav.idl): a[3 i + j] = M(i, j).
Eigen::Matrix3d Mat(const std::array<double, 9>& a) {
  Eigen::Matrix3d m;
  for (int k = 0; k < 9; ++k) m(k / 3, k % 3) = a[static_cast<std::size_t>(k)];
  return m;
}
std::array<double, 9> Arr(const Eigen::Matrix3d& m) {
  std::array<double, 9> a{};
  for (int k = 0; k < 9; ++k) a[static_cast<std::size_t>(k)] = m(k / 3, k % 3);
  return a;
}
Eigen::Matrix2d Mat(const std::array<double, 4>& a) {
  Eigen::Matrix2d m;
  m << a[0], a[1], a[2], a[3];
  return m;
}
std::array<double, 4> Arr(const Eigen::Matrix2d& m) { return {m(0, 0), m(0, 1), m(1, 0), m(1, 1)}; }

}  // namespace

GradiometerRecord RecordOf(const msg::GradiometerSample& m) {
  GradiometerRecord r;
  r.sensor_id = m.sensor_id();
  r.stamp_ns = m.stamp_ns();
  r.seq = m.seq();
  r.p_SinW_m = Vec(m.sensor_position());
  r.B_T = Vec(m.B());
  r.T_Tpm = Mat(m.T());
  r.sigma_B_T = m.sigma_B();
  r.sigma_T_Tpm = m.sigma_T();
  return r;
}

msg::GradiometerSample ToMsg(const GradiometerRecord& r) {
  msg::GradiometerSample m;
  m.sensor_id(r.sensor_id);
  m.stamp_ns(r.stamp_ns);
  m.seq(r.seq);
  m.sensor_position(Arr(r.p_SinW_m));
  m.B(Arr(r.B_T));
  m.T(Arr(r.T_Tpm));
  m.sigma_B(r.sigma_B_T);
  m.sigma_T(r.sigma_T_Tpm);
  return m;
}

MagnetometerRecord RecordOf(const msg::MagnetometerSample& m) {
  MagnetometerRecord r;
  r.sensor_id = m.sensor_id();
  r.stamp_ns = m.stamp_ns();
  r.seq = m.seq();
  r.p_SinW_m = Vec(m.sensor_position());
  r.B_T = Vec(m.B());
  r.sigma_B_T = m.sigma_B();
  return r;
}

msg::MagnetometerSample ToMsg(const MagnetometerRecord& r) {
  msg::MagnetometerSample m;
  m.sensor_id(r.sensor_id);
  m.stamp_ns(r.stamp_ns);
  m.seq(r.seq);
  m.sensor_position(Arr(r.p_SinW_m));
  m.B(Arr(r.B_T));
  m.sigma_B(r.sigma_B_T);
  return m;
}

VesselNavRecord RecordOf(const msg::VesselNav& m) {
  VesselNavRecord r;
  r.vessel_id = m.vessel_id();
  r.stamp_ns = m.stamp_ns();
  r.source = static_cast<NavSource>(m.source());
  r.p_VinW_m = Vec(m.position());
  r.v_VinW_mps = Vec(m.velocity());
  r.heading_rad = m.heading();
  r.sigma_p_m = Vec(m.sigma_position());
  r.sigma_v_mps = m.sigma_velocity();
  r.sigma_heading_rad = m.sigma_heading();
  r.geodetic = Vec(m.geodetic());
  return r;
}

msg::VesselNav ToMsg(const VesselNavRecord& r) {
  msg::VesselNav m;
  m.vessel_id(r.vessel_id);
  m.stamp_ns(r.stamp_ns);
  m.source(static_cast<msg::NavSource>(r.source));
  m.position(Arr(r.p_VinW_m));
  m.velocity(Arr(r.v_VinW_mps));
  m.heading(r.heading_rad);
  m.sigma_position(Arr(r.sigma_p_m));
  m.sigma_velocity(r.sigma_v_mps);
  m.sigma_heading(r.sigma_heading_rad);
  m.geodetic(Arr(r.geodetic));
  return m;
}

DipoleFixRecord RecordOf(const msg::DipoleFix& m) {
  DipoleFixRecord r;
  r.sensor_id = m.sensor_id();
  r.stamp_ns = m.stamp_ns();
  r.sample_seq = m.sample_seq();
  r.method = static_cast<FixMethod>(m.method());
  r.valid = m.valid();
  r.reason = m.reason().to_string();
  r.p_DinW_m = Vec(m.position());
  r.has_moment = m.has_moment();
  r.m_W_Am2 = Vec(m.moment());
  r.condition_number = m.condition_number();
  r.cov_p_m2 = Mat(m.covariance());
  return r;
}

msg::DipoleFix ToMsg(const DipoleFixRecord& r) {
  msg::DipoleFix m;
  m.sensor_id(r.sensor_id);
  m.stamp_ns(r.stamp_ns);
  m.sample_seq(r.sample_seq);
  m.method(static_cast<msg::FixMethod>(r.method));
  m.valid(r.valid);
  m.reason(r.reason);  // string<64>: longer is cut
  m.position(Arr(r.p_DinW_m));
  m.has_moment(r.has_moment);
  m.moment(Arr(r.m_W_Am2));
  m.condition_number(r.condition_number);
  m.covariance(Arr(r.cov_p_m2));
  return m;
}

TrackRecord RecordOf(const msg::TrackEstimate& m) {
  TrackRecord r;
  r.track_id = m.track_id();
  r.stamp_ns = m.stamp_ns();
  r.p_VinW_m = Vec(m.position());
  r.v_VinW_mps = Vec(m.velocity());
  r.heading_rad = m.heading();
  r.turn_rate_radps = m.turn_rate();
  r.cov_p_m2 = Mat(m.covariance());
  r.m_B_Am2 = Vec(m.moment_body());
  r.cov_m_B = Mat(m.moment_covariance());
  r.num_sensors = m.num_sensors();
  r.usable = m.usable();
  r.state = static_cast<TrackState>(m.state());  // a value this IDL does not know is carried
  return r;
}

msg::TrackEstimate ToMsg(const TrackRecord& r) {
  msg::TrackEstimate m;
  m.track_id(r.track_id);
  m.stamp_ns(r.stamp_ns);
  m.position(Arr(r.p_VinW_m));
  m.velocity(Arr(r.v_VinW_mps));
  m.heading(r.heading_rad);
  m.turn_rate(r.turn_rate_radps);
  m.covariance(Arr(r.cov_p_m2));
  m.moment_body(Arr(r.m_B_Am2));
  m.moment_covariance(Arr(r.cov_m_B));
  m.num_sensors(r.num_sensors);
  m.usable(r.usable);
  m.state(static_cast<msg::TrackState>(r.state));
  return m;
}

SensorPositionRecord RecordOf(const msg::SensorPositionEstimate& m) {
  SensorPositionRecord r;
  r.sensor_id = m.sensor_id();
  r.stamp_ns = m.stamp_ns();
  r.p_SinW_m = Vec(m.position());
  r.cov_m2 = Mat(m.covariance());
  r.crlb_m2 = Mat(m.crlb());
  return r;
}

msg::SensorPositionEstimate ToMsg(const SensorPositionRecord& r) {
  msg::SensorPositionEstimate m;
  m.sensor_id(r.sensor_id);
  m.stamp_ns(r.stamp_ns);
  m.position(Arr(r.p_SinW_m));
  m.covariance(Arr(r.cov_m2));
  m.crlb(Arr(r.crlb_m2));
  return m;
}

MapFixRecord RecordOf(const msg::MapFix& m) {
  MapFixRecord r;
  r.vehicle_id = m.vehicle_id();
  r.stamp_ns = m.stamp_ns();
  r.method = static_cast<FixMethod>(m.method());
  r.method_name = m.method_name().to_string();
  r.lat_deg = m.lat_deg();
  r.lon_deg = m.lon_deg();
  r.score = m.score();
  r.cov_ne_m2 = Mat(m.covariance());
  r.status = static_cast<MapFixStatus>(m.status());
  return r;
}

msg::MapFix ToMsg(const MapFixRecord& r) {
  msg::MapFix m;
  m.vehicle_id(r.vehicle_id);
  m.stamp_ns(r.stamp_ns);
  m.method(static_cast<msg::FixMethod>(r.method));
  m.method_name(r.method_name);  // string<32>: longer is cut
  m.lat_deg(r.lat_deg);
  m.lon_deg(r.lon_deg);
  m.score(r.score);
  m.covariance(Arr(r.cov_ne_m2));
  m.status(static_cast<msg::MapFixStatus>(r.status));
  return m;
}

GradiometerSample FromMsg(const msg::GradiometerSample& m) {
  const GradiometerRecord r = RecordOf(m);
  GradiometerSample s;
  s.sensor_id = r.sensor_id;
  s.t_s = NanosToSeconds(r.stamp_ns);
  s.p_SinW = r.p_SinW_m;
  s.B = r.B_T;
  s.T = r.T_Tpm;
  s.sigma_B = r.sigma_B_T;
  s.sigma_T = r.sigma_T_Tpm;
  return s;
}

msg::GradiometerSample ToMsg(const GradiometerSample& s, std::uint64_t seq) {
  GradiometerRecord r;
  r.sensor_id = s.sensor_id;
  r.stamp_ns = SecondsToNanos(s.t_s);
  r.seq = seq;
  r.p_SinW_m = s.p_SinW;
  r.B_T = s.B;
  r.T_Tpm = s.T;
  r.sigma_B_T = s.sigma_B;
  r.sigma_T_Tpm = s.sigma_T;
  return ToMsg(r);
}

double AnomalyOf(const msg::MagnetometerSample& m, double reference_field_nT) {
  const auto& b = m.B();
  const double norm_T = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  return std::isfinite(norm_T) ? norm_T * 1e9 - reference_field_nT : std::numeric_limits<double>::quiet_NaN();
}

msg::VesselNav InsNavMsg(std::uint32_t vehicle_id, std::uint64_t stamp_ns, double lat_deg, double lon_deg) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  VesselNavRecord r;
  r.vessel_id = vehicle_id;
  r.stamp_ns = stamp_ns;
  r.source = NavSource::kIns;
  r.p_VinW_m.setConstant(nan);  // no local frame in a map-matching run
  r.v_VinW_mps.setConstant(nan);
  r.heading_rad = nan;
  r.sigma_p_m.setConstant(nan);
  r.sigma_v_mps = nan;
  r.sigma_heading_rad = nan;
  r.geodetic = {lat_deg, lon_deg, nan};
  return ToMsg(r);
}

msg::MagnetometerSample AnomalySampleMsg(std::uint32_t sensor_id, std::uint64_t stamp_ns, std::uint64_t seq,
                                         double anomaly_nT, double reference_field_nT) {
  MagnetometerRecord r;
  r.sensor_id = sensor_id;
  r.stamp_ns = stamp_ns;
  r.seq = seq;
  r.p_SinW_m.setConstant(std::numeric_limits<double>::quiet_NaN());
  r.B_T = {0.0, 0.0, (reference_field_nT + anomaly_nT) * 1e-9};
  r.sigma_B_T = 0.0;
  return ToMsg(r);
}

}  // namespace magnav::dds
