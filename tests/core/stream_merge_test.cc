// The per-stream watermark merge (core/stream_merge.h) alone: a quiet stream,
// a late stream, unpaced arrival, the reorder-delay rule, the memory bound.
#include "magnav/core/stream_merge.h"

#include <algorithm>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace magnav {
namespace {

// An item: (stream, sample time).
using Item = std::pair<int, double>;

struct Harness {
  explicit Harness(StreamMergeOptions o) : merge(o) {}
  void Push(int stream, double t) {
    merge.Push(t, stream, stream, Item{stream, t});
    Release();
  }
  void Release(bool all = false) {
    merge.Release([this](const Item& x) { out.push_back(x); }, all);
  }
  StreamMerger<Item> merge;
  std::vector<Item> out;
};

StreamMergeOptions Watermark(double idle_s = 2.0) {
  StreamMergeOptions o;
  o.merge = StreamMerge::kWatermark;
  o.idle_timeout_s = idle_s;
  return o;
}

// Sorted by (time, stream): what a merge of everything gives.
std::vector<Item> Sorted(std::vector<Item> v) {
  std::sort(v.begin(), v.end(), [](const Item& a, const Item& b) {
    return a.second != b.second ? a.second < b.second : a.first < b.first;
  });
  return v;
}

TEST(StreamMerge, UnpacedStreamsOneAfterTheOtherMergeExactly) {
  // Three streams' whole histories arrive one after the other with no clock
  // (an unpaced replay, a restart's history): nothing may be handed on before
  // the slowest stream has reached it, so the output is the exact merge.
  Harness h(Watermark());
  for (int s = 0; s < 3; ++s) h.merge.Declare(s);
  std::vector<Item> all;
  for (int s = 0; s < 3; ++s) {
    for (int k = 0; k < 100; ++k) {
      const double t = 0.1 * k + 0.01 * s;
      h.Push(s, t);
      all.push_back({s, t});
    }
    // Nothing released until every declared stream has sent something.
    if (s < 2) {
      EXPECT_TRUE(h.out.empty()) << "after stream " << s;
    }
  }
  EXPECT_EQ(h.out.size(), 298u);  // all up to the slowest stream's newest time (9.90 s)
  h.Release(true);
  EXPECT_EQ(h.out, Sorted(all));
}

TEST(StreamMerge, EqualTimesAreOrderedByRankNotArrival) {
  Harness h(Watermark());
  h.merge.Declare(1);
  h.merge.Declare(2);
  h.Push(2, 1.0);
  h.Push(1, 1.0);
  h.Push(2, 2.0);
  h.Push(1, 2.0);
  h.Release(true);
  EXPECT_EQ(h.out, (std::vector<Item>{{1, 1.0}, {2, 1.0}, {1, 2.0}, {2, 2.0}}));
}

TEST(StreamMerge, AQuietStreamStopsHoldingTheOthersAfterTheIdleTimeout) {
  Harness h(Watermark(2.0));
  h.merge.Declare(0);
  h.merge.Declare(1);
  h.merge.Tick(100.0);
  h.Push(0, 0.0);
  h.Push(1, 0.0);
  // Stream 1 goes quiet; stream 0 goes on for 1.9 s of wall clock: held.
  for (int k = 1; k <= 19; ++k) {
    h.merge.Tick(100.0 + 0.1 * k);
    h.Push(0, 0.1 * k);
  }
  EXPECT_EQ(h.out.size(), 2u);  // the two items at t = 0 only
  // At 2.1 s of silence stream 1 no longer holds: everything of stream 0 up to its newest goes.
  h.merge.Tick(102.1);
  h.Release();
  EXPECT_EQ(h.out.size(), 21u);
  EXPECT_EQ(h.out.back(), (Item{0, 0.1 * 19}));
  // Stream 0 goes on alone, item by item.
  h.merge.Tick(102.2);
  h.Push(0, 2.0);
  EXPECT_EQ(h.out.back(), (Item{0, 2.0}));
}

TEST(StreamMerge, ADeclaredStreamNotSeenYetHoldsTheOthersForTheIdleTimeout) {
  // After a restart two topics' histories arrive one after the other: the
  // second's items must still be merged in, not refused as late.
  Harness h(Watermark(2.0));
  h.merge.Declare(0);
  h.merge.Declare(1);
  h.merge.Tick(0.0);
  for (int k = 0; k < 50; ++k) h.Push(0, 0.1 * k);
  h.merge.Tick(1.5);  // stream 1 not seen, within the timeout
  h.Release();
  EXPECT_TRUE(h.out.empty());
  for (int k = 0; k < 50; ++k) h.Push(1, 0.1 * k + 0.05);
  h.Release(true);
  std::vector<Item> want;
  for (int k = 0; k < 50; ++k) {
    want.push_back({0, 0.1 * k});
    want.push_back({1, 0.1 * k + 0.05});
  }
  EXPECT_EQ(h.out, Sorted(want));
}

TEST(StreamMerge, ADeclaredStreamNeverSeenIsGivenUpAfterTheIdleTimeout) {
  Harness h(Watermark(2.0));
  h.merge.Declare(0);
  h.merge.Declare(1);
  h.merge.Tick(0.0);
  h.Push(0, 0.0);
  h.Push(0, 1.0);
  h.merge.Tick(1.9);
  h.Release();
  EXPECT_TRUE(h.out.empty());
  h.merge.Tick(2.1);
  h.Release();
  EXPECT_EQ(h.out.size(), 2u);
}

TEST(StreamMerge, ALateStreamThatComesBackHoldsAgain) {
  Harness h(Watermark(1.0));
  h.merge.Tick(0.0);
  h.Push(0, 0.0);
  h.Push(1, 0.0);
  h.merge.Tick(5.0);  // both quiet: released up to the oldest stream's newest time
  h.Release();
  EXPECT_EQ(h.out.size(), 2u);
  h.Push(0, 1.0);  // stream 0 is live again, stream 1 still quiet
  EXPECT_EQ(h.out.size(), 3u);
  h.Push(1, 2.0);  // stream 1 back: now it is live and behind nothing
  h.Push(0, 3.0);  // held: stream 1 is only at 2.0
  EXPECT_EQ(h.out.back(), (Item{1, 2.0}));
  EXPECT_EQ(h.merge.size(), 1u);
}

TEST(StreamMerge, ReorderDelayHandsOnOnceANewerItemArrived) {
  StreamMergeOptions o;
  o.merge = StreamMerge::kReorderDelay;
  o.reorder_delay_s = 0.5;
  Harness h(o);
  h.Push(0, 1.0);
  h.Push(1, 0.8);
  h.Push(0, 1.2);
  EXPECT_TRUE(h.out.empty());
  h.Push(0, 1.5);  // releases up to 1.0
  EXPECT_EQ(h.out, (std::vector<Item>{{1, 0.8}, {0, 1.0}}));
  // A newer item releases everything older than the delay, whatever the other streams.
  h.Push(0, 10.0);
  EXPECT_EQ(h.out.size(), 4u);
}

TEST(StreamMerge, AtMostMaxPendingItemsWait) {
  StreamMergeOptions o = Watermark();
  o.max_pending = 10;
  Harness h(o);
  h.merge.Declare(1);  // never seen, no clock: holds everything
  for (int k = 0; k < 100; ++k) h.Push(0, k);
  EXPECT_EQ(h.merge.size(), 10u);
  EXPECT_EQ(h.out.size(), 90u);
  EXPECT_EQ(h.out.back(), (Item{0, 89.0}));
}

TEST(StreamMerge, OptionsAreChecked) {
  StreamMergeOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why));
  o.idle_timeout_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  o = {};
  o.reorder_delay_s = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
  o = {};
  o.max_pending = 0;
  EXPECT_FALSE(o.IsValid(&why));
}

}  // namespace
}  // namespace magnav
