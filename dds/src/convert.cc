#include "magnav/dds/convert.h"

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

}  // namespace magnav::dds
