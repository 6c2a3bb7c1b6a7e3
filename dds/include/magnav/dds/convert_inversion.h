// The inversion library's types on the wire (layer 2 of convert.h; library
// magnav::dds_inversion = magnav::dds + magnav::inversion). Frames and units
// as in magnav.idl: world NED, m, A·m², m².
#pragma once

#include <cstdint>

#include "magnav/dds/convert.h"
#include "magnav/inversion/inverter.h"

namespace magnav::dds {

// The method field of a fix the inverter computed with `method`.
FixMethod FixMethodOf(inversion::Method method);

// magnav/dipole_fix of a single-sample fix of the sample (stamp_ns,
// sample_seq): the reason's stable name (RejectReasonName), the moment only
// when it has one and it is finite (else 0), the position covariance all 0
// (= unknown) unless every entry is finite.
DipoleFixRecord ToRecord(const inversion::DipoleFix& fix, std::uint64_t stamp_ns, std::uint64_t sample_seq,
                         FixMethod method);
msg::DipoleFix ToMsg(const inversion::DipoleFix& fix, std::uint64_t stamp_ns, std::uint64_t sample_seq,
                     FixMethod method);

}  // namespace magnav::dds
