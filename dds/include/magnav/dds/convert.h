// Conversion between the IDL topic types and the core structs the libraries
// use. Pure value copies; no validation (the libraries' gates judge samples).
#pragma once

#include "magnav/core/gradiometer.h"
#include "magnav/dds/topics.h"

namespace magnav::dds {

GradiometerSample FromMsg(const msg::GradiometerSample& m);
msg::GradiometerSample ToMsg(const GradiometerSample& s, std::uint64_t seq);

// Map matching on the wire (docs/PROTOCOL.md), shared by magnav-matcher,
// `magnav replay --map-path` and the tests: the anomaly a magnetometer sample
// carries, |B| − the map's reference field (nT; NaN if B is not finite); the
// INS fix of a map-matching run (VesselNav NAV_INS, geodetic lat/lon in
// degrees, no local position); a sample whose |B| is the reference field
// plus the anomaly (B along +z, down; only |B| is used).
double AnomalyOf(const msg::MagnetometerSample& m, double reference_field_nT);
msg::VesselNav InsNavMsg(std::uint32_t vehicle_id, std::uint64_t stamp_ns, double lat_deg, double lon_deg);
msg::MagnetometerSample AnomalySampleMsg(std::uint32_t sensor_id, std::uint64_t stamp_ns, std::uint64_t seq,
                                         double anomaly_nT, double reference_field_nT);

}  // namespace magnav::dds
