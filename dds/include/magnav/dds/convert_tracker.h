// The tracker's types on the wire (layer 2 of convert.h; library
// magnav::dds_tracker = magnav::dds + magnav::tracker). Frames and units as
// in magnav.idl: world NED, m, m/s, rad, A·m² (body axes), m².
#pragma once

#include <cstdint>

#include "magnav/dds/convert.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"

namespace magnav::dds {

// A magnav/dipole_fix as the tracker reads it (tracker::MakeFix: time,
// sensor, position, valid; the rest the inverter's defaults).
tracker::DipoleFix FromMsg(const msg::DipoleFix& m);

// magnav/track of one epoch of track `track_id` with the track's body moment
// and its covariance: the position covariance only when the estimate is
// usable and has one (else all 0); `state` what the epoch's estimate rests on
// (multi_tracker.h).
TrackRecord ToRecord(const tracker::EpochEstimate& e, const Eigen::Vector3d& m_B_Am2, const Eigen::Matrix3d& cov_m_B,
                     std::uint32_t track_id, tracker::TrackState state);
msg::TrackEstimate ToMsg(const tracker::EpochEstimate& e, const Eigen::Vector3d& m_B_Am2,
                         const Eigen::Matrix3d& cov_m_B, std::uint32_t track_id, tracker::TrackState state);

}  // namespace magnav::dds
