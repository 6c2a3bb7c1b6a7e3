// A track's life cycle in the multi-tracker (Stone Soup's initiator/deleter
// rules, STYLE §13): M-of-N confirmation of a tentative track and the end
// rules of a confirmed one, from the associator's per-epoch verdicts and the
// engine's estimates. One object per track; no field model in it, so each
// rule is testable alone (tests/tracker/life_cycle_test.cc).
//
// Times in s; σ in m. Options: TrackManagementOptions (multi_tracker.h).
//  - Tentative: confirmed once confirm_m of its epochs with a sensor are
//    detections with tensor evidence (confirm_tensor_snr); dropped ("not
//    confirmed") once more than confirm_n − confirm_m of them are not, or
//    max_coast_s after it was created.
//  - Confirmed, ends (first rule that holds, in this order): "missed" (missed
//    for max_miss_s in a row, not counting misses excused by ExcuseMisses), "out_of_reach" (out of the sensors' reach,
//    OnReach, for out_of_reach_s in a row; 0 = off), "lost" (not detected
//    for max_coast_s),
//    "uncertain" (horizontal 1-σ above max_sigma_horizontal_m), "unusable"
//    (its window solve unusable for max_miss_s).
//  - Duplicate: within min_separation_m of an older track (the caller says
//    so each epoch): a tentative one ends at once, a confirmed one after
//    max_miss_s of it in a row.
#pragma once

#include <string>

#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

class TrackLifeCycle {
 public:
  enum class Decision { kKeep, kConfirm, kEnd };

  // A tentative track created at t_created_s (its last detection then).
  TrackLifeCycle(double t_created_s, const TrackManagementOptions& options);

  // The associator's verdict of the epoch at t_s; `had_samples`: the track
  // took at least one sample (only such epochs count toward M-of-N).
  // `tensor_evidence`: the detection is also seen in the tensor
  // (TrackAssociation::tensor_evidence); a detection without it does not
  // count toward confirmation (it does for the end rules).
  void OnAssociation(double t_s, bool detected, bool missed, bool had_samples, bool tensor_evidence = true);
  // Whether the track is within the sensors' reach at t_s (its predicted
  // tensor SNR ≥ reach_tensor_snr at a sensor, or it is inside the
  // sensors' horizontal bounding box).
  void OnReach(double t_s, bool in_reach);
  // The newest estimate of the track's engine: its time, whether its window
  // solve was usable, its horizontal 1-σ (m).
  void OnEstimate(double t_s, bool usable, double sigma_horizontal_m);
  // After this epoch's association and estimates: confirm, end (with the
  // reason) or keep. A kConfirm must be followed by Confirm().
  Decision Decide(double t_s, std::string* reason) const;
  void Confirm() { confirmed_ = true; }
  // The misses up to now are explained by a vessel beside the track that
  // is too weak yet to be started (pair_beside.h, `waiting`): the "missed"
  // streak starts again from the next miss. The "lost" rule (no detection
  // for max_coast_s) still holds.
  void ExcuseMisses();
  // Whether the track is within min_separation_m of an older live track at
  // t_s; true if it ends for it ("duplicate").
  bool OnDuplicateCheck(double t_s, bool close_to_older);

  bool confirmed() const { return confirmed_; }
  double t_last_detection_s() const { return t_last_detection_; }
  double sigma_horizontal_m() const { return sigma_h_; }

  // Checkpoint (tracker/checkpoint.h; MultiTracker::SaveState): the whole
  // state, doubles bit for bit; RestoreState into one made with the same
  // options. Throws CheckpointError if the bytes do not fit.
  void SaveState(StateWriter& w) const;
  void RestoreState(StateReader& r);

 private:
  TrackManagementOptions options_;
  bool confirmed_ = false;
  double t_created_;
  int seen_ = 0, detections_ = 0;  // while tentative
  double t_last_detection_;
  double miss_since_, unusable_since_, duplicate_since_, out_of_reach_since_;  // NaN: not now
  double sigma_h_ = 0.0;
};

}  // namespace magnav::tracker
