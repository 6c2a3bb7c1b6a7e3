// Re-acquisition alone (reacquire.h): which ended track a newly confirmed
// one continues, from hand-made estimates (no field, no engine). The
// numbers are those of fresh_overtaking4/overtaking_ne15 (window, main
// 5555b6a): the slow vessel's track ended "missed" at 62 s, 0.8 m off with
// σ 1.2 m (its last row's), going 0.9 m/s at 0.6 rad; its new track's
// first row at 66 s, σ 0.1 m (taken here as its confirmation; it was
// confirmed at 71.8 s); the overtaker (2.1 m/s) 31 m behind.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "magnav/tracker/reacquire.h"

namespace magnav::tracker {
namespace {

// An estimate at t_s going `speed` (m/s) at `heading` (rad) through (x, y),
// with position σ `sigma_p` (m), speed σ `sigma_v` (m/s), heading σ
// `sigma_h` (rad).
EpochEstimate Estimate(double t_s, double x, double y, double speed, double heading, double sigma_p,
                       double sigma_v = 0.05, double sigma_h = 0.05) {
  EpochEstimate e;
  e.t_s = t_s;
  e.p_VinW = {x, y, 5.0};
  e.speed_mps = speed;
  e.heading_rad = heading;
  e.usable = true;
  e.has_covariance = true;
  e.cov_state = StateCovariance::Zero();
  e.cov_state.diagonal() << sigma_p * sigma_p, sigma_p * sigma_p, 0.01, sigma_v * sigma_v, sigma_h * sigma_h, 1e-6;
  return e;
}

// The defaults: on for 30 s, gate 13.28.
MultiTrackerOptions On() { return MultiTrackerOptions(); }

// The slow vessel's ended track (ne15 at 62 s) and its new one at 66 s.
const double kHeading = 0.6, kSlow = 0.9, kFast = 2.1;
EndedTrack SlowEnded() {
  EndedTrack e;
  e.track_id = 1;
  e.reason = "missed";
  e.t_end_s = 62.0;
  e.t_last_row_s = 62.0;
  e.newest = Estimate(61.6, -14.64, -15.15, kSlow, kHeading, 1.2, 0.1, 0.1);
  return e;
}
EpochEstimate SlowAgain() { return Estimate(66.0, -12.11, -12.64, kSlow, kHeading, 0.1); }

TEST(Reacquire, TheSlowVesselsNewTrackContinuesItsEndedOne) {
  const MultiTrackerOptions o = On();
  const std::vector<EndedTrack> ended{SlowEnded()};
  double chi2 = -1.0;
  const auto k = ChooseContinuation(ended, SlowAgain(), 66.0, {}, 66.0, o, &chi2);
  ASSERT_TRUE(k.has_value());
  EXPECT_EQ(*k, 0u);
  std::printf("ne15's pair: chi2 %.3f\n", chi2);
  // ne15's pair: χ² 0.42 (4 dof; 0.79 m apart, σ ≈ 1.2 m per axis);
  // the gate 13.28 — a vessel 6 m off is refused (below).
  EXPECT_LT(chi2, 1.0);
  // On by default for 30 s; off, nothing continues.
  EXPECT_EQ(o.management.reacquire_s, 30.0);
  EXPECT_EQ(TrackManagementOptions{}.reacquire_s, 0.0);
  MultiTrackerOptions off;
  off.management.reacquire_s = 0.0;
  EXPECT_FALSE(ChooseContinuation(ended, SlowAgain(), 66.0, {}, 66.0, off, nullptr).has_value());
}

TEST(Reacquire, NotAcrossTwoVessels) {
  const MultiTrackerOptions o = On();
  const std::vector<EndedTrack> ended{SlowEnded()};
  // The overtaker where the slow one was predicted, at its own speed: the
  // speed differs by 1.2 m/s (σ 0.1): refused.
  EXPECT_FALSE(ChooseContinuation(ended, Estimate(66.0, -11.3, -12.9, kFast, kHeading, 0.1), 66.0, {}, 66.0, o,
                                  nullptr)
                   .has_value());
  // A vessel 6 m beside the prediction (σ ≈ 1.3 m per axis): refused.
  EXPECT_FALSE(ChooseContinuation(ended, Estimate(66.0, -11.3 - 4.24, -12.9 + 4.24, kSlow, kHeading, 0.1), 66.0, {},
                                  66.0, o, nullptr)
                   .has_value());
  // Another live track is closer to the ended one than the newcomer is: it
  // is that track's vessel, not the newcomer's.
  const EpochEstimate live = Estimate(66.0, -11.3, -12.9, kSlow, kHeading, 0.1);
  EXPECT_FALSE(ChooseContinuation(ended, SlowAgain(), 66.0, {live}, 66.0, o, nullptr).has_value());
  // A live track far away (the overtaker 31 m behind) changes nothing.
  const EpochEstimate fast = Estimate(66.0, -12.11 - 25.4, -12.64 - 17.5, kFast, kHeading, 0.1);
  EXPECT_TRUE(ChooseContinuation(ended, SlowAgain(), 66.0, {fast}, 66.0, o, nullptr).has_value());
}

TEST(Reacquire, OnlyRecentEndsOfItsOwnAndRowsAfterTheEnd) {
  const MultiTrackerOptions o = On();
  // Ended more than reacquire_s before.
  EndedTrack old = SlowEnded();
  old.t_end_s = 35.0;  // 31 s before
  EXPECT_FALSE(ChooseContinuation({old}, SlowAgain(), 66.0, {}, 66.0, o, nullptr).has_value());
  // Its vessel another track's ("duplicate").
  EndedTrack dup = SlowEnded();
  dup.reason = "duplicate";
  EXPECT_FALSE(ChooseContinuation({dup}, SlowAgain(), 66.0, {}, 66.0, o, nullptr).has_value());
  EXPECT_TRUE(ReacquirableEnd("missed"));
  EXPECT_TRUE(ReacquirableEnd("out_of_reach"));
  EXPECT_FALSE(ReacquirableEnd("end of data"));
  // The newcomer's rows would overlap the ended track's.
  EXPECT_FALSE(ChooseContinuation({SlowEnded()}, SlowAgain(), 61.0, {}, 66.0, o, nullptr).has_value());
  // Of two ended tracks that pass, the nearer (in χ²).
  EndedTrack other = SlowEnded();
  other.track_id = 2;
  other.newest.p_VinW.x() += 1.5;
  const auto k = ChooseContinuation({other, SlowEnded()}, SlowAgain(), 66.0, {}, 66.0, o, nullptr);
  ASSERT_TRUE(k.has_value());
  EXPECT_EQ(*k, 1u);
}

TEST(Reacquire, OptionsChecked) {
  MultiTrackerOptions o = On();
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.management.reacquire_s = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
  o = On();
  o.management.reacquire_gate_chi2 = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
}

}  // namespace
}  // namespace magnav::tracker
