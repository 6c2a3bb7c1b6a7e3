#include "magnav/dds/convert.h"

#include <cmath>
#include <limits>

#include "magnav/core/tensor.h"
#include "magnav/core/units.h"

namespace magnav::dds {

GradiometerSample FromMsg(const msg::GradiometerSample& m) {
  GradiometerSample s;
  s.sensor_id = m.sensor_id();
  s.t_s = NanosToSeconds(m.stamp_ns());
  for (int i = 0; i < 3; ++i) {
    s.p_SinW[i] = m.sensor_position()[i];
    s.B[i] = m.B()[i];
  }
  s.T = TensorFromRowMajor(m.T());
  s.sigma_B = m.sigma_B();
  s.sigma_T = m.sigma_T();
  return s;
}

msg::GradiometerSample ToMsg(const GradiometerSample& s, std::uint64_t seq) {
  msg::GradiometerSample m;
  m.sensor_id(s.sensor_id);
  m.stamp_ns(SecondsToNanos(s.t_s));
  m.seq(seq);
  m.sensor_position({s.p_SinW.x(), s.p_SinW.y(), s.p_SinW.z()});
  m.B({s.B.x(), s.B.y(), s.B.z()});
  m.T(TensorToRowMajor(s.T));
  m.sigma_B(s.sigma_B);
  m.sigma_T(s.sigma_T);
  return m;
}

double AnomalyOf(const msg::MagnetometerSample& m, double reference_field_nT) {
  const auto& b = m.B();
  const double norm_T = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  return std::isfinite(norm_T) ? norm_T * 1e9 - reference_field_nT : std::numeric_limits<double>::quiet_NaN();
}

msg::VesselNav InsNavMsg(std::uint32_t vehicle_id, std::uint64_t stamp_ns, double lat_deg, double lon_deg) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  msg::VesselNav m;
  m.vessel_id(vehicle_id);
  m.stamp_ns(stamp_ns);
  m.source(msg::NAV_INS);
  m.position({nan, nan, nan});  // no local frame in a map-matching run
  m.velocity({nan, nan, nan});
  m.heading(nan);
  m.sigma_position({nan, nan, nan});
  m.sigma_velocity(nan);
  m.sigma_heading(nan);
  m.geodetic({lat_deg, lon_deg, nan});
  return m;
}

msg::MagnetometerSample AnomalySampleMsg(std::uint32_t sensor_id, std::uint64_t stamp_ns, std::uint64_t seq,
                                              double anomaly_nT, double reference_field_nT) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  msg::MagnetometerSample m;
  m.sensor_id(sensor_id);
  m.stamp_ns(stamp_ns);
  m.seq(seq);
  m.sensor_position({nan, nan, nan});
  m.B({0.0, 0.0, (reference_field_nT + anomaly_nT) * 1e-9});
  m.sigma_B(0.0);
  return m;
}

}  // namespace magnav::dds
