#include "magnav/dds/convert_tracker.h"

#include "magnav/core/units.h"

namespace magnav::dds {

tracker::DipoleFix FromMsg(const msg::DipoleFix& m) {
  const DipoleFixRecord r = RecordOf(m);
  return tracker::MakeFix(NanosToSeconds(r.stamp_ns), r.sensor_id, r.p_DinW_m, r.valid);
}

TrackRecord ToRecord(const tracker::EpochEstimate& e, const Eigen::Vector3d& m_B_Am2, const Eigen::Matrix3d& cov_m_B,
                     std::uint32_t track_id, tracker::TrackState state) {
  TrackRecord r;
  r.track_id = track_id;
  r.stamp_ns = SecondsToNanos(e.t_s);
  r.p_VinW_m = e.p_VinW;
  r.v_VinW_mps = e.v_VinW();
  r.heading_rad = e.heading_rad;
  r.turn_rate_radps = e.turn_rate_radps;
  r.cov_p_m2 = e.usable && e.has_covariance ? e.cov_p_W() : Eigen::Matrix3d::Zero();
  r.m_B_Am2 = m_B_Am2;
  r.cov_m_B = cov_m_B;
  r.num_sensors = static_cast<std::uint32_t>(e.num_samples);
  r.usable = e.usable;
  r.state = state == tracker::TrackState::kCoasting ? TrackState::kCoasting : TrackState::kConfirmed;
  return r;
}

msg::TrackEstimate ToMsg(const tracker::EpochEstimate& e, const Eigen::Vector3d& m_B_Am2,
                         const Eigen::Matrix3d& cov_m_B, std::uint32_t track_id, tracker::TrackState state) {
  return ToMsg(ToRecord(e, m_B_Am2, cov_m_B, track_id, state));
}

}  // namespace magnav::dds
