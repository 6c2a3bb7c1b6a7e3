#include "magnav/dds/convert_inversion.h"

namespace magnav::dds {

FixMethod FixMethodOf(inversion::Method method) {
  switch (method) {
    case inversion::Method::kTed:
      return FixMethod::kTed;
    case inversion::Method::kTedEgt:
      return FixMethod::kTedEgt;
    case inversion::Method::kEgt:
      return FixMethod::kEgt;
  }
  return FixMethod::kOther;
}

DipoleFixRecord ToRecord(const inversion::DipoleFix& fix, std::uint64_t stamp_ns, std::uint64_t sample_seq,
                         FixMethod method) {
  DipoleFixRecord r;
  r.sensor_id = fix.sensor_id;
  r.stamp_ns = stamp_ns;
  r.sample_seq = sample_seq;
  r.method = method;
  r.valid = fix.valid;
  r.reason = inversion::RejectReasonName(fix.reason);
  r.p_DinW_m = fix.p_DinW;
  r.has_moment = fix.has_moment && fix.m_W.allFinite();
  r.m_W_Am2 = r.has_moment ? fix.m_W : Eigen::Vector3d::Zero();
  r.condition_number = fix.cond;
  r.cov_p_m2 = fix.cov_p_DinW.allFinite() ? fix.cov_p_DinW : Eigen::Matrix3d::Zero();  // all 0 = unknown
  return r;
}

msg::DipoleFix ToMsg(const inversion::DipoleFix& fix, std::uint64_t stamp_ns, std::uint64_t sample_seq,
                     FixMethod method) {
  return ToMsg(ToRecord(fix, stamp_ns, sample_seq, method));
}

}  // namespace magnav::dds
