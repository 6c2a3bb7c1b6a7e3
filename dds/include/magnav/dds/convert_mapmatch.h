// Map matching's types on the wire (layer 2 of convert.h; library
// magnav::dds_mapmatch = magnav::dds + magnav::mapmatch). WGS84 degrees,
// covariance (north, east) in m².
#pragma once

#include <cstdint>

#include "magnav/dds/convert.h"
#include "magnav/mapmatch/particle_filter.h"

namespace magnav::dds {

// The method field of a fix of a sequential matcher of `kind`.
FixMethod FixMethodOf(mapmatch::ParticleFilterKind kind);

// magnav/map_fix of vehicle `vehicle_id` after a step at stamp_ns: the
// weighted mean, score = the effective sample size, the (north, east)
// covariance (CovarianceNorthEast_m2) and the status — lost outranks off the
// map (a lost filter's dead-reckoning is no better for being off the map).
MapFixRecord ToRecord(const mapmatch::StepDiagnostics& d, mapmatch::ParticleFilterKind kind, std::uint32_t vehicle_id,
                      std::uint64_t stamp_ns);
msg::MapFix ToMsg(const mapmatch::StepDiagnostics& d, mapmatch::ParticleFilterKind kind, std::uint32_t vehicle_id,
                  std::uint64_t stamp_ns);

}  // namespace magnav::dds
