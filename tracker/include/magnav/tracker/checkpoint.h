// Checkpoints of magnav-tracker: its state in a small binary file that
// survives a crash (docs/RELIABILITY.md "Delivery, crash and restart"). The
// container (header, checksum, field writer/reader, atomic write) is
// core/checkpoint.h's; this is the tracker's kind of it:
//
//   magic "MAGNAVTC", format version 9 (kTrackerCheckpointVersion), payload
//   written by the service node: its stream position and counters around
//   MultiTracker::SaveState (configuration, tracks, records, initiator).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "magnav/core/checkpoint.h"

namespace magnav::tracker {

// Version 2 (2026-11-26): each live track also carries the associator's
// verdicts of the epochs its engine has not estimated yet (the rows'
// TrackState); a version-1 file is refused ("format version 1").
// Version 3 (2026-11-26): the cluster background (cluster_background.h):
// its options in the configuration, its raw span and offsets, and the
// summary's cluster counters; a version-2 file is refused.
// Version 4 (2026-11-26): per live track the time of its last poor fit (the
// start beside a track) and of its start (the joint start), and the options
// of the joint start, the start beside a track and the batch restarts from
// the window; a version-3 file is refused.
// Version 5 (2026-11-26): per live track its pending back-filled start
// (TrackManagementOptions::backfill_start, also in the configuration) and
// since when it is out of the sensors' reach (the "out_of_reach" end rule),
// and the options of the tensor evidence for confirmation and of that end
// rule; a version-4 file is refused.
// Version 6 (2026-11-26): per live track whether its pair was started beside
// it (the pair's refit then uses that start's options); a version-5 file is
// refused.
// Version 7 (2026-11-27): per live track whether the lone start started it
// (its start's rows back-filled), and the lone start's options
// (ResidualStartOptions::lone_min_fixes, lone_min_span_s); a version-6 file
// is refused.
// Version 8 (2026-11-27): the ghost fields of tracks ended out of reach
// (TrackManagementOptions::ghost_field_s, ghost_b_snr, also in the
// configuration): each one's track id, end time, newest estimate and moment;
// a version-7 file is refused.
// Version 9 (2026-11-27): the tracks ended within reacquire_s that a new
// track may continue (reacquire.h; TrackManagementOptions::reacquire_s,
// reacquire_gate_chi2, also in the configuration): each one's id, end
// reason and time, last row's time and newest estimate; and the summary's
// count of re-acquired tracks; a version-8 file is refused.
// Version 10 (2026-11-27, session 20): the far source's whole state
// (FarSourceEstimator::SaveState: its kept samples with the live tracks'
// positions when each was kept, the drift's samples and lines, the last fit,
// its refusal, back-off interval and counters); before, a restored tracker
// fitted it again from the samples after the restart and removed nothing for
// its first 10 s; a version-9 file is refused.
inline constexpr std::uint32_t kTrackerCheckpointVersion = 10;
inline constexpr CheckpointKind kTrackerCheckpointKind{"MAGNAVTC", kTrackerCheckpointVersion, "magnav-tracker"};

// Header + payload + checksum (core/checkpoint.h's format, the tracker's magic and version).
inline std::string EncodeTrackerCheckpoint(std::string_view payload) {
  return EncodeCheckpoint(kTrackerCheckpointKind, payload);
}
// The payload; throws CheckpointError if the file is not a tracker checkpoint of this version.
inline std::string DecodeTrackerCheckpoint(std::string_view file) {
  return DecodeCheckpoint(kTrackerCheckpointKind, file);
}

}  // namespace magnav::tracker
