// The localizer's types on the wire (layer 2 of convert.h; library
// magnav::dds_localizer = magnav::dds + magnav::localizer). Frames and units
// as in magnav.idl: world NED, m, T, m²; the library's times in s are the
// stamps through NanosToSeconds / SecondsToNanos.
#pragma once

#include <cstdint>

#include "magnav/dds/convert.h"
#include "magnav/localizer/types.h"

namespace magnav::dds {

// The localizer's view of a magnav/magnetometer sample (time, sensor, B).
localizer::MagSample FromMsg(const msg::MagnetometerSample& m);
// The localizer's view of a GNSS magnav/vessel_nav: the horizontal position
// and σ = the larger of the two horizontal sigma_position entries.
localizer::GnssFix FromMsg(const msg::VesselNav& m);
// magnav/sensor_position of one sensor's estimate at time t_s: z is known,
// so the covariance's and the bound's z row and column are 0; the bound is
// crlb_joint_m2 (the vessel trajectory estimated jointly).
SensorPositionRecord ToRecord(const localizer::SensorEstimate& e, double t_s);
msg::SensorPositionEstimate ToMsg(const localizer::SensorEstimate& e, double t_s);

// The reverse of the two FromMsg above (`magnav replay --magnetometer
// --gnss`): a sample with its seq and 1-σ per axis (T; 0 = unknown), the
// sensor position unknown (NaN); a GNSS fix (NAV_GNSS) of `vessel_id` at
// depth z_m with σ on both horizontal axes, the rest unknown (NaN).
msg::MagnetometerSample ToMsg(const localizer::MagSample& s, std::uint64_t seq, double sigma_B_T);
msg::VesselNav ToMsg(const localizer::GnssFix& f, std::uint32_t vessel_id, double z_m);

}  // namespace magnav::dds
