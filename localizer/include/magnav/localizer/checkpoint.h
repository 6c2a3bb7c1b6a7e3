// Checkpoints: the localizer's state in a small binary file that survives a
// crash (docs/RELIABILITY.md "Delivery, crash and restart";
// StreamingLocalizer::SaveState / RestoreState). The container (header,
// checksum, field writer/reader, atomic write) is core/checkpoint.h's; this
// is the localizer's kind of it:
//
//   magic "MAGNAVLC", format version 1 (kCheckpointVersion), payload
//   StreamingLocalizer::SaveState (configuration, stream position, counters,
//   EKF, bound).
//
// Not thread-safe.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "magnav/core/checkpoint.h"

namespace magnav::localizer {

inline constexpr std::uint32_t kCheckpointVersion = 1;
inline constexpr CheckpointKind kCheckpointKind{"MAGNAVLC", kCheckpointVersion, "magnav-localizer"};

using magnav::CheckpointError;
using magnav::Fnv1a64;
using magnav::ReadWholeFile;
using magnav::StateReader;
using magnav::StateWriter;
using magnav::WriteFileAtomically;

// Header + payload + checksum (core/checkpoint.h's format, the localizer's magic and version).
inline std::string EncodeCheckpoint(std::string_view payload) {
  return magnav::EncodeCheckpoint(kCheckpointKind, payload);
}
// The payload; throws CheckpointError if the file is not a version-1 localizer checkpoint.
inline std::string DecodeCheckpoint(std::string_view file) { return magnav::DecodeCheckpoint(kCheckpointKind, file); }

}  // namespace magnav::localizer
