// Re-acquisition (track continuation, as in Stone Soup's and MHT practice):
// a newly confirmed track that continues a track ended a few seconds before
// takes over that track's id instead of a new one, so a vessel whose track
// ended while it coasted (an overtaker's B arriving while it crossed a
// stretch 20-27 m from every sensor) keeps one id (issue 24; ACCURACY.md
// "Re-acquisition keeps the id").
//
// The test is on the state [x, y, speed, heading] (world NED, m, m/s, rad
// from north, clockwise): both estimates are propagated to the newcomer's
// confirmation time t_s by the coordinated-turn model, their covariances by
// its Jacobian with the window's process noise (as the association's gate,
// PredictGate), and the innovation χ² (4 dof) is
//   χ² = dᵀ (P_ended + P_new)⁻¹ d,   d = [Δx, Δy, Δspeed, wrap(Δheading)].
// The ended track is continued only if
//  - it ended within TrackManagementOptions::reacquire_s before t_s, for a
//    reason that does not say its vessel is tracked by another track
//    (ReacquirableEnd: not "duplicate", not "end of data");
//  - the newcomer's first row comes after the ended track's last row;
//  - χ² ≤ reacquire_gate_chi2;
//  - no live confirmed track is closer (in the same χ²) to the ended track
//    or to the newcomer than they are to each other (the vessel is not
//    another live track's);
//  - among the ended tracks that pass, it has the smallest χ².
// No field model here: testable alone (tests/tracker/reacquire_test.cc).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

// A confirmed track that ended, as the re-acquisition needs it.
struct EndedTrack {
  std::uint32_t track_id = 0;
  std::string reason;      // its end reason (TrackEvent)
  double t_end_s = 0.0;    // when it ended
  double t_last_row_s = 0.0;  // its last output row (TrackRecord::t_end_s)
  EpochEstimate newest;    // its newest estimate (state and covariance)
};

// Whether a track ended for `reason` may be continued: not "duplicate" (its
// vessel is another track's) nor "end of data".
bool ReacquirableEnd(const std::string& reason);

// The χ² (4 dof, see above) of two estimates propagated to t_s; +inf if
// either has no usable covariance or the sum is not positive definite.
double ContinuationChi2(const EpochEstimate& a, const EpochEstimate& b, double t_s,
                        const MultiTrackerOptions& options);

// The index in `ended` of the track the newcomer continues, or nullopt (the
// rules above). `newcomer`: its newest estimate; `t_first_row_s`: its first
// row's time (its back-filled start, or its confirmation); `live`: the
// newest estimates of the other live confirmed tracks. `chi2`: the chosen
// one's χ² (may be null).
std::optional<std::size_t> ChooseContinuation(const std::vector<EndedTrack>& ended, const EpochEstimate& newcomer,
                                              double t_first_row_s, const std::vector<EpochEstimate>& live,
                                              double t_s, const MultiTrackerOptions& options, double* chi2);

}  // namespace magnav::tracker
