// Conversion between the IDL topic types and C++ values: the one place where
// a message's fields are read or written, used by every service and tool.
//
// Two layers, so that the DDS adapter never depends on an algorithm library:
//  1. Here, in magnav::dds (depends on core and the IDL only): every topic
//     type <-> its plain record (records.h), exactly and both ways
//     (tests/dds/convert_test.cc round-trips every topic, every enum value
//     and the appended MapFix.status); plus core's GradiometerSample and the
//     map-matching helpers below.
//  2. A library's own types <-> a topic (e.g. inversion::DipoleFix ->
//     magnav/dipole_fix, localizer::SensorEstimate -> magnav/sensor_position):
//     one small library per algorithm library, dds/src/convert_<lib>.cc with
//     header convert_<lib>.h, built as magnav::dds_<lib>, which depends on
//     magnav::dds and that library only. These map the library's meaning
//     (units, which fields it has) to a record and go through layer 1 for the
//     message, so no field is written in two places.
// Pure value copies; no validation (the libraries' gates judge samples).
#pragma once

#include "magnav/core/gradiometer.h"
#include "magnav/dds/records.h"
#include "magnav/dds/topics.h"

namespace magnav::dds {

// Layer 1: exact, both ways, for every topic type. RecordOf(m): the record
// of a message; ToMsg(r): the message of a record.
GradiometerRecord RecordOf(const msg::GradiometerSample& m);
MagnetometerRecord RecordOf(const msg::MagnetometerSample& m);
VesselNavRecord RecordOf(const msg::VesselNav& m);
DipoleFixRecord RecordOf(const msg::DipoleFix& m);
TrackRecord RecordOf(const msg::TrackEstimate& m);
SensorPositionRecord RecordOf(const msg::SensorPositionEstimate& m);
MapFixRecord RecordOf(const msg::MapFix& m);

msg::GradiometerSample ToMsg(const GradiometerRecord& r);
msg::MagnetometerSample ToMsg(const MagnetometerRecord& r);
msg::VesselNav ToMsg(const VesselNavRecord& r);
msg::DipoleFix ToMsg(const DipoleFixRecord& r);
msg::TrackEstimate ToMsg(const TrackRecord& r);
msg::SensorPositionEstimate ToMsg(const SensorPositionRecord& r);
msg::MapFix ToMsg(const MapFixRecord& r);

// core's sample (time in seconds: NanosToSeconds / SecondsToNanos of the
// stamp; the seq is the caller's).
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
