// The multi-tracker's track life cycle alone (track_life_cycle.h): M-of-N
// confirmation and each end rule, driven by hand-made verdicts (no field,
// no engine). Defaults: confirm 8 of 10, max_miss 2 s, max_coast 10 s,
// max σ_h 5 m; epochs every 0.125 s (exact in binary: no rounding at the rules' edges).
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "magnav/tracker/track_life_cycle.h"

namespace magnav::tracker {
namespace {

using Decision = TrackLifeCycle::Decision;

constexpr double kDt = 0.125;

// Feeds `pattern` ('d' detected, 'm' missed, 'u' unobserved with samples,
// '-' no sample) from t0; returns the first decision other than kKeep and
// the epoch index where it came (-1: none).
std::pair<Decision, int> Feed(TrackLifeCycle* life, const std::string& pattern, double t0, std::string* reason) {
  for (std::size_t k = 0; k < pattern.size(); ++k) {
    const double t = t0 + kDt * static_cast<double>(k + 1);
    const char c = pattern[k];
    life->OnAssociation(t, c == 'd', c == 'm', c != '-');
    life->OnEstimate(t, true, 0.5);
    const Decision d = life->Decide(t, reason);
    if (d != Decision::kKeep) return {d, static_cast<int>(k)};
  }
  return {Decision::kKeep, -1};
}

TEST(TrackLifeCycle, ConfirmedByMOfN) {
  const TrackManagementOptions opt;
  ASSERT_EQ(opt.confirm_m, 8);
  ASSERT_EQ(opt.confirm_n, 10);
  // Two misses among the first ten: confirmed at the 8th detection.
  TrackLifeCycle a(0.0, opt);
  std::string why;
  const auto [d, k] = Feed(&a, "dmdddmdddd", 0.0, &why);
  EXPECT_EQ(d, Decision::kConfirm);
  EXPECT_EQ(k, 9);
  // Epochs without a sample do not count.
  TrackLifeCycle b(0.0, opt);
  const auto [d2, k2] = Feed(&b, "dd--dd--dddd", 0.0, &why);
  EXPECT_EQ(d2, Decision::kConfirm);
  EXPECT_EQ(k2, 11);
  EXPECT_FALSE(b.confirmed());
  b.Confirm();
  EXPECT_TRUE(b.confirmed());
}

TEST(TrackLifeCycle, TentativeDroppedWhenMOfNCannotBeReached) {
  const TrackManagementOptions opt;
  // Three epochs without a detection among its first: 8 of 10 is out of reach.
  TrackLifeCycle a(0.0, opt);
  std::string why;
  const auto [d, k] = Feed(&a, "dumdudddd", 0.0, &why);
  EXPECT_EQ(d, Decision::kEnd);
  EXPECT_EQ(k, 4);
  EXPECT_EQ(why, "not confirmed");
  // Never seen for max_coast_s: dropped too.
  TrackLifeCycle b(0.0, opt);
  const auto [d2, k2] = Feed(&b, std::string(120, '-'), 0.0, &why);
  EXPECT_EQ(d2, Decision::kEnd);
  EXPECT_EQ(k2, 80);  // t = 10.125 s > 10 s
  EXPECT_EQ(why, "not confirmed");
}

TrackLifeCycle Confirmed(const TrackManagementOptions& opt) {
  TrackLifeCycle life(0.0, opt);
  std::string why;
  EXPECT_EQ(Feed(&life, "dddddddd", 0.0, &why).first, Decision::kConfirm);
  life.Confirm();
  return life;
}

TEST(TrackLifeCycle, EndsWhenMissedForMaxMiss) {
  const TrackManagementOptions opt;
  TrackLifeCycle life = Confirmed(opt);
  std::string why;
  // Confirmed at 1 s; misses from t = 1.125 s: ends at 3.125 s.
  const auto [d, k] = Feed(&life, std::string(40, 'm'), 1.0, &why);
  EXPECT_EQ(d, Decision::kEnd);
  EXPECT_EQ(k, 16);
  EXPECT_EQ(why, "missed");
  // A detection in between restarts the count.
  TrackLifeCycle again = Confirmed(opt);
  const auto [d2, k2] = Feed(&again, std::string(15, 'm') + "d" + std::string(40, 'm'), 1.0, &why);
  EXPECT_EQ(d2, Decision::kEnd);
  EXPECT_EQ(k2, 32);  // misses again from 3.125 s: ends at 5.125 s
  EXPECT_EQ(why, "missed");
}

// Misses excused once a second (a fit beside the track explains them:
// pair_beside.h `waiting`) never make 2 s in a row; the "lost" rule still
// ends the track 10 s after its last detection.
TEST(TrackLifeCycle, ExcusedMissesDoNotEndItButLostStillDoes) {
  const TrackManagementOptions opt;
  TrackLifeCycle life = Confirmed(opt);
  std::string why;
  int k_end = -1;
  for (int k = 0; k < 200 && k_end < 0; ++k) {
    const double t = 1.0 + kDt * (k + 1);
    if (k % 8 == 7) life.ExcuseMisses();  // once per second
    life.OnAssociation(t, false, true, true);
    life.OnEstimate(t, true, 0.5);
    if (life.Decide(t, &why) == Decision::kEnd) k_end = k;
  }
  EXPECT_EQ(why, "lost");
  EXPECT_EQ(k_end, 79);  // 11 s: 10 s after the last detection at 1 s
  // Not excused: "missed" at 3.125 s (EndsWhenMissedForMaxMiss).
}

TEST(TrackLifeCycle, EndsWhenLostForMaxCoast) {
  const TrackManagementOptions opt;
  TrackLifeCycle life = Confirmed(opt);
  std::string why;
  // Last detection at 1 s, then unobserved: ends at 11 s.
  const auto [d, k] = Feed(&life, std::string(150, 'u'), 1.0, &why);
  EXPECT_EQ(d, Decision::kEnd);
  EXPECT_EQ(k, 79);
  EXPECT_EQ(why, "lost");
  EXPECT_DOUBLE_EQ(life.t_last_detection_s(), 1.0);
}

TEST(TrackLifeCycle, EndsWhenUncertainOrUnusable) {
  const TrackManagementOptions opt;
  std::string why;
  TrackLifeCycle a = Confirmed(opt);
  a.OnAssociation(1.0, true, false, true);
  a.OnEstimate(1.0, true, 4.9);
  EXPECT_EQ(a.Decide(1.0, &why), Decision::kKeep);
  a.OnEstimate(1.1, true, 5.1);
  EXPECT_EQ(a.Decide(1.1, &why), Decision::kEnd);
  EXPECT_EQ(why, "uncertain");
  // Unusable solves for max_miss_s in a row.
  TrackLifeCycle b = Confirmed(opt);
  for (int k = 0; k <= 16; ++k) {
    const double t = 1.0 + kDt * k;
    b.OnAssociation(t, true, false, true);
    b.OnEstimate(t, false, 1.0);
    const Decision d = b.Decide(t, &why);
    if (k < 16) {
      EXPECT_EQ(d, Decision::kKeep) << k;
    } else {
      EXPECT_EQ(d, Decision::kEnd);
      EXPECT_EQ(why, "unusable");
    }
  }
}

TEST(TrackLifeCycle, DuplicateEndsATentativeAtOnceAndAConfirmedAfterMaxMiss) {
  const TrackManagementOptions opt;
  TrackLifeCycle tentative(0.0, opt);
  EXPECT_FALSE(tentative.OnDuplicateCheck(0.1, false));
  EXPECT_TRUE(tentative.OnDuplicateCheck(0.2, true));
  TrackLifeCycle life = Confirmed(opt);
  EXPECT_FALSE(life.OnDuplicateCheck(1.0, true));
  EXPECT_FALSE(life.OnDuplicateCheck(2.875, true));
  EXPECT_FALSE(life.OnDuplicateCheck(3.0, false));  // apart again: the count restarts
  EXPECT_FALSE(life.OnDuplicateCheck(3.25, true));
  EXPECT_FALSE(life.OnDuplicateCheck(5.0, true));
  EXPECT_TRUE(life.OnDuplicateCheck(5.25, true));
}

// Tensor evidence (confirm_tensor_snr): detections seen in B alone (a far
// ship's or a drift's B that a far dipole explains) never confirm; the same
// detections with tensor evidence do, at the 8th.
TEST(TrackLifeCycle, DetectionsWithoutTensorEvidenceDoNotConfirm) {
  const TrackManagementOptions opt;
  ASSERT_EQ(opt.confirm_tensor_snr, 3.0);
  std::string why;
  TrackLifeCycle b_only(0.0, opt);
  Decision d = Decision::kKeep;
  int k = 0;
  for (; k < 40 && d == Decision::kKeep; ++k) {
    const double t = kDt * (k + 1);
    b_only.OnAssociation(t, true, false, true, false);
    d = b_only.Decide(t, &why);
  }
  EXPECT_EQ(d, Decision::kEnd);  // more than N − M epochs without a counted detection
  EXPECT_EQ(k, 3);
  EXPECT_EQ(why, "not confirmed");
  // Two of the first ten without tensor evidence: confirmed at the tenth.
  TrackLifeCycle mixed(0.0, opt);
  for (k = 0; k < 10; ++k) {
    const double t = kDt * (k + 1);
    mixed.OnAssociation(t, true, false, true, k != 2 && k != 5);
    d = mixed.Decide(t, &why);
    if (d != Decision::kKeep) break;
  }
  EXPECT_EQ(d, Decision::kConfirm);
  EXPECT_EQ(k, 9);
}

// Out of reach (out_of_reach_s; the default, 2 s): ends after 2 s
// out of reach in a row, before the 10 s coast of "lost"; a return within
// reach restarts the count; 0 turns the rule off (then "lost", as before
// 2026-11-26).
TEST(TrackLifeCycle, EndsOutOfReachAfterOutOfReachS) {
  TrackManagementOptions opt;
  ASSERT_EQ(opt.out_of_reach_s, 2.0);
  std::string why;
  const auto run = [&](const TrackManagementOptions& o, const std::string& reach, int* at) {
    TrackLifeCycle life = Confirmed(o);
    for (std::size_t k = 0; k < reach.size(); ++k) {
      const double t = 1.0 + kDt * static_cast<double>(k + 1);
      life.OnAssociation(t, true, false, true);  // still "detected" on B alone
      life.OnReach(t, reach[k] == 'r');
      life.OnEstimate(t, true, 0.5);
      if (life.Decide(t, &why) == Decision::kEnd) {
        *at = static_cast<int>(k);
        return why;
      }
    }
    *at = -1;
    return std::string("kept");
  };
  int at = 0;
  // Out of reach from t = 1.125 s: ends at 3.125 s (16 epochs later).
  EXPECT_EQ(run(opt, std::string(100, 'o'), &at), "out_of_reach");
  EXPECT_EQ(at, 16);
  // Back within reach after 1.875 s: the count restarts.
  EXPECT_EQ(run(opt, std::string(15, 'o') + "r" + std::string(100, 'o'), &at), "out_of_reach");
  EXPECT_EQ(at, 32);
  // Within reach throughout: kept.
  EXPECT_EQ(run(opt, std::string(100, 'r'), &at), "kept");
  // Off: a B-only detection keeps it.
  opt.out_of_reach_s = 0.0;
  EXPECT_EQ(run(opt, std::string(100, 'o'), &at), "kept");
}

TEST(TrackLifeCycle, GhostRuleOptionsAreChecked) {
  std::string err;
  TrackManagementOptions o;
  EXPECT_TRUE(o.IsValid(&err)) << err;
  o.confirm_tensor_snr = 0.0;  // off
  EXPECT_TRUE(o.IsValid(&err)) << err;
  o.confirm_tensor_snr = -1.0;
  EXPECT_FALSE(o.IsValid(&err));
  EXPECT_NE(err.find("confirm_tensor_snr"), std::string::npos);
  o = TrackManagementOptions{};
  o.reach_tensor_snr = 0.0;
  EXPECT_FALSE(o.IsValid(&err));
  EXPECT_NE(err.find("reach_tensor_snr"), std::string::npos);
  o = TrackManagementOptions{};
  o.out_of_reach_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(o.IsValid(&err));
  EXPECT_NE(err.find("out_of_reach_s"), std::string::npos);
  o.out_of_reach_s = 0.0;  // off
  EXPECT_TRUE(o.IsValid(&err)) << err;
}

}  // namespace
}  // namespace magnav::tracker
