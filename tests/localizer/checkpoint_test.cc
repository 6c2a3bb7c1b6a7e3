// Checkpoints of the streaming localizer (checkpoint.h, StreamingLocalizer::
// SaveState/RestoreState; issue 22 item 3): half a pass, saved, restored into
// a new localizer and fed the rest (with the older items again, as a
// writer's history sends them) ends bit for bit where the uninterrupted run
// ends; a checkpoint that is corrupt, truncated, of another version or of
// another configuration is refused with the reason and changes nothing.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "localize_data.h"
#include "magnav/localizer/checkpoint.h"
#include "magnav/localizer/stream.h"

namespace magnav::localizer {
namespace {

using test::ReferencePass;

struct Feed {
  const Pass& pass;
  // Feeds samples [from, to) with the fixes up to each sample's time (fixes
  // from the first one at or after sample `from`'s time).
  void Run(StreamingLocalizer& s, std::size_t from, std::size_t to, std::uint64_t* refused = nullptr) const {
    std::size_t g = 0;
    while (g < pass.gnss.size() && from < pass.samples.size() && pass.gnss[g].t_s < pass.samples[from].t_s) ++g;
    for (std::size_t i = from; i < to; ++i) {
      const MagSample& m = pass.samples[i];
      while (g < pass.gnss.size() && pass.gnss[g].t_s <= m.t_s) Count(s.Add(pass.gnss[g++]), refused);
      Count(s.Add(m), refused);
    }
    if (to == pass.samples.size()) {
      while (g < pass.gnss.size()) Count(s.Add(pass.gnss[g++]), refused);
    }
  }
  static void Count(SampleCheck c, std::uint64_t* refused) {
    if (c == SampleCheck::kAlreadyConsumed) {
      if (refused) ++*refused;
    } else {
      EXPECT_EQ(c, SampleCheck::kOk) << SampleCheckName(c);
    }
  }
};

struct Mode {
  const char* name;
  bool bounded;
  StreamMerge merge;
};

class CheckpointRoundTrip : public ::testing::TestWithParam<Mode> {};

TEST_P(CheckpointRoundTrip, HalfAPassSavedAndRestoredEndsBitForBitAsUninterrupted) {
  const PassFile d = ReferencePass();
  const Pass& pass = d.pass;
  StreamOptions so;
  so.bounded = GetParam().bounded;
  so.merge = GetParam().merge;
  const LocalizerOptions opt;
  const Feed feed{pass};
  const std::size_t n = pass.samples.size(), half = n / 2;

  StreamingLocalizer whole(pass.vessel, pass.sensors, opt, so);
  feed.Run(whole, 0, n);
  whole.Flush();
  const Localization want = whole.Result();

  StreamingLocalizer first(pass.vessel, pass.sensors, opt, so);
  feed.Run(first, 0, half);
  // Items still wait in the merge buffer: they are not in the checkpoint and
  // come again below (from the "writers' history").
  ASSERT_LT(first.consumed_until(), pass.samples[half - 1].t_s);
  const std::string file = EncodeCheckpoint(first.SaveState());

  StreamingLocalizer second(pass.vessel, pass.sensors, opt, so);
  second.RestoreState(DecodeCheckpoint(file));
  ASSERT_TRUE(second.restored());
  EXPECT_EQ(second.consumed(), first.consumed());
  // The history: the last 1000 samples per sensor before the kill, again.
  const std::size_t history = half - std::min<std::size_t>(half, 1000 * pass.sensors.size());
  std::uint64_t already = 0;
  feed.Run(second, history, n, &already);
  second.Flush();
  const Localization got = second.Result();

  std::size_t older = 0;
  for (std::size_t i = history; i < half; ++i) older += pass.samples[i].t_s <= first.consumed_until();
  EXPECT_GT(already, older / 2) << "the history older than the checkpoint is refused as consumed";
  EXPECT_EQ(second.already_consumed(), already);
  EXPECT_EQ(second.late(), 0u) << "no 'time goes backwards' for the history";
  EXPECT_EQ(second.consumed(), whole.consumed());
  EXPECT_EQ(got.summary.magnetometer_updates, want.summary.magnetometer_updates);
  EXPECT_EQ(got.summary.gnss_updates, want.summary.gnss_updates);
  ASSERT_EQ(got.sensors.size(), want.sensors.size());
  for (std::size_t j = 0; j < want.sensors.size(); ++j) {
    EXPECT_TRUE(got.sensors[j].p_SinW_m == want.sensors[j].p_SinW_m) << "sensor " << j;
    EXPECT_TRUE(got.sensors[j].cov_xy_m2 == want.sensors[j].cov_xy_m2) << "sensor " << j;
    EXPECT_TRUE(got.sensors[j].crlb_joint_m2 == want.sensors[j].crlb_joint_m2) << "sensor " << j;
    EXPECT_TRUE(got.sensors[j].crlb_known_trajectory_m2 == want.sensors[j].crlb_known_trajectory_m2) << "sensor " << j;
  }
  EXPECT_TRUE(got.cov_sensors_m2 == want.cov_sensors_m2);
}

INSTANTIATE_TEST_SUITE_P(Modes, CheckpointRoundTrip,
                         ::testing::Values(Mode{"BoundedWatermark", true, StreamMerge::kWatermark},
                                           Mode{"BoundedDelay", true, StreamMerge::kReorderDelay},
                                           Mode{"UnboundedDelay", false, StreamMerge::kReorderDelay}),
                         [](const auto& info) { return std::string(info.param.name); });

// A checkpoint of the first quarter of the reference pass, bounded.
std::string QuarterCheckpoint(const Pass& pass) {
  StreamOptions so;
  so.bounded = true;
  StreamingLocalizer s(pass.vessel, pass.sensors, LocalizerOptions{}, so);
  Feed{pass}.Run(s, 0, pass.samples.size() / 4);
  return EncodeCheckpoint(s.SaveState());
}

// RestoreState(DecodeCheckpoint(file)) into a new bounded localizer of
// `pass`: the CheckpointError's message, or "" if it was taken. A refused
// one leaves the localizer new (it then runs as if started fresh).
std::string Refusal(const Pass& pass, const std::string& file) {
  StreamOptions so;
  so.bounded = true;
  StreamingLocalizer s(pass.vessel, pass.sensors, LocalizerOptions{}, so);
  try {
    s.RestoreState(DecodeCheckpoint(file));
    return "";
  } catch (const CheckpointError& e) {
    EXPECT_FALSE(s.restored());
    EXPECT_FALSE(s.initialized());
    EXPECT_EQ(s.consumed(), 0u);
    std::size_t g = 0;  // (a pass with fewer sensors refuses the others' samples)
    for (std::size_t i = 0; i < 2000; ++i) {
      while (g < pass.gnss.size() && pass.gnss[g].t_s <= pass.samples[i].t_s) s.Add(pass.gnss[g++]);
      s.Add(pass.samples[i]);
    }
    s.Flush();
    EXPECT_TRUE(s.initialized()) << "a refused checkpoint leaves a localizer that starts fresh";
    return e.what();
  }
}

TEST(Checkpoint, RefusesCorruptTruncatedOtherVersionAndOtherConfiguration) {
  const PassFile d = ReferencePass();
  const std::string good = QuarterCheckpoint(d.pass);
  EXPECT_EQ(Refusal(d.pass, good), "");

  std::string flipped = good;
  flipped[flipped.size() / 2] ^= 0x10;
  EXPECT_EQ(Refusal(d.pass, flipped), "corrupt: checksum mismatch");

  EXPECT_NE(Refusal(d.pass, good.substr(0, good.size() - 100)).find("truncated"), std::string::npos);
  EXPECT_NE(Refusal(d.pass, good.substr(0, 10)).find("truncated"), std::string::npos);
  EXPECT_NE(Refusal(d.pass, "").find("no MAGNAVLC magic"), std::string::npos);
  EXPECT_NE(Refusal(d.pass, "sensor_id,x,y\n1,2,3\n").find("no MAGNAVLC magic"), std::string::npos);
  EXPECT_NE(Refusal(d.pass, good + "x").find("corrupt"), std::string::npos);

  std::string v2 = good;
  v2[8] = 2;  // the version field
  EXPECT_EQ(Refusal(d.pass, v2), "format version 2, this program reads version 1");

  // A payload cut short behind a valid header and checksum.
  const std::string payload = DecodeCheckpoint(good);
  EXPECT_NE(Refusal(d.pass, EncodeCheckpoint(payload.substr(0, payload.size() / 2))).find("truncated"),
            std::string::npos);

  Pass moved = d.pass;
  moved.sensors[3].p_SinW_m.x() += 1.0;
  EXPECT_NE(Refusal(moved, good).find("another deployment"), std::string::npos);
  Pass fewer = d.pass;
  fewer.sensors.pop_back();
  EXPECT_NE(Refusal(fewer, good).find("another deployment"), std::string::npos);
  Pass other_moment = d.pass;
  other_moment.vessel.m_B_Am2.z() *= 1.5;
  EXPECT_NE(Refusal(other_moment, good).find("another vessel"), std::string::npos);

  StreamingLocalizer unbounded(d.pass.vessel, d.pass.sensors, LocalizerOptions{}, StreamOptions{});
  EXPECT_THROW(unbounded.RestoreState(payload), CheckpointError);
  LocalizerOptions noisier;
  noisier.sigma_B_T = 2e-9;
  StreamOptions so;
  so.bounded = true;
  StreamingLocalizer other_options(d.pass.vessel, d.pass.sensors, noisier, so);
  try {
    other_options.RestoreState(payload);
    ADD_FAILURE() << "other options taken";
  } catch (const CheckpointError& e) {
    EXPECT_NE(std::string(e.what()).find("other estimator options"), std::string::npos) << e.what();
  }

  // Only into a new localizer.
  StreamingLocalizer used(d.pass.vessel, d.pass.sensors, LocalizerOptions{}, so);
  used.Add(d.pass.samples[0]);
  EXPECT_THROW(used.RestoreState(payload), std::logic_error);
}

TEST(Checkpoint, FileIsWrittenAtomicallyAndReadBack) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("magnav_ckpt_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                                     "_" + std::to_string(reinterpret_cast<std::uintptr_t>(&dir)));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "magnav-localizer.state").string();
  std::string bytes;
  EXPECT_FALSE(ReadWholeFile(path, &bytes));
  WriteFileAtomically(path, "first");
  WriteFileAtomically(path, std::string("sec\0nd", 6));
  ASSERT_TRUE(ReadWholeFile(path, &bytes));
  EXPECT_EQ(bytes, std::string("sec\0nd", 6));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()), 1)
      << "no temporary file left";
  EXPECT_THROW(WriteFileAtomically((dir / "no" / "such" / "dir").string(), "x"), std::runtime_error);
  std::filesystem::remove_all(dir);
}

TEST(Checkpoint, DoublesRoundTripBitForBit) {
  StateWriter w;
  const double values[] = {0.1, -0.0, 1e-308, 4.9e-324, std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity(), 1.0 / 3.0};
  for (double v : values) w.F64(v);
  w.F64(std::numeric_limits<double>::quiet_NaN());
  StateReader r(w.bytes());
  for (double v : values) {
    const double got = r.F64();
    EXPECT_EQ(std::memcmp(&got, &v, sizeof v), 0) << v;
  }
  EXPECT_TRUE(std::isnan(r.F64()));
  EXPECT_TRUE(r.at_end());
  EXPECT_THROW(r.U8(), CheckpointError);
}

}  // namespace
}  // namespace magnav::localizer
