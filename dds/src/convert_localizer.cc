#include "magnav/dds/convert_localizer.h"

#include <algorithm>
#include <limits>

#include "magnav/core/units.h"

namespace magnav::dds {

localizer::MagSample FromMsg(const msg::MagnetometerSample& m) {
  const MagnetometerRecord r = RecordOf(m);
  localizer::MagSample s;
  s.t_s = NanosToSeconds(r.stamp_ns);
  s.sensor_id = r.sensor_id;
  s.B_T = r.B_T;
  return s;
}

localizer::GnssFix FromMsg(const msg::VesselNav& m) {
  const VesselNavRecord r = RecordOf(m);
  localizer::GnssFix f;
  f.t_s = NanosToSeconds(r.stamp_ns);
  f.p_xy_m = r.p_VinW_m.head<2>();
  f.sigma_m = std::max(r.sigma_p_m.x(), r.sigma_p_m.y());
  return f;
}

SensorPositionRecord ToRecord(const localizer::SensorEstimate& e, double t_s) {
  SensorPositionRecord r;
  r.sensor_id = e.sensor_id;
  r.stamp_ns = SecondsToNanos(t_s);
  r.p_SinW_m = e.p_SinW_m;
  r.cov_m2.setZero();  // z is known: its row and column stay 0
  r.crlb_m2.setZero();
  r.cov_m2.topLeftCorner<2, 2>() = e.cov_xy_m2;
  r.crlb_m2.topLeftCorner<2, 2>() = e.crlb_joint_m2;
  return r;
}

msg::SensorPositionEstimate ToMsg(const localizer::SensorEstimate& e, double t_s) {
  return ToMsg(ToRecord(e, t_s));
}

msg::MagnetometerSample ToMsg(const localizer::MagSample& s, std::uint64_t seq, double sigma_B_T) {
  MagnetometerRecord r;
  r.sensor_id = s.sensor_id;
  r.stamp_ns = SecondsToNanos(s.t_s);
  r.seq = seq;
  r.p_SinW_m.setConstant(std::numeric_limits<double>::quiet_NaN());  // not known here
  r.B_T = s.B_T;
  r.sigma_B_T = sigma_B_T;
  return ToMsg(r);
}

msg::VesselNav ToMsg(const localizer::GnssFix& f, std::uint32_t vessel_id, double z_m) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  VesselNavRecord r;
  r.vessel_id = vessel_id;
  r.stamp_ns = SecondsToNanos(f.t_s);
  r.source = NavSource::kGnss;
  r.p_VinW_m = {f.p_xy_m.x(), f.p_xy_m.y(), z_m};
  r.v_VinW_mps.setConstant(nan);
  r.heading_rad = nan;
  r.sigma_p_m = {f.sigma_m, f.sigma_m, nan};
  r.sigma_v_mps = nan;
  r.sigma_heading_rad = nan;
  r.geodetic.setConstant(nan);
  return ToMsg(r);
}

}  // namespace magnav::dds
