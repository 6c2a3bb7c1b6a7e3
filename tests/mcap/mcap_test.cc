// The MCAP writer and reader (tools/mcap): what is written is read back
// whole, with every compression; a file cut anywhere is read up to its last
// complete chunk with a warning; invalid content is an InputError naming the
// file.
#include "magnav/mcap/mcap.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "magnav/core/error.h"

namespace magnav::mcap {
namespace {

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("mcap_test_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::string Payload(int i) {
  std::string p = "\x00\x01\x00\x00";
  p.resize(4);
  p[1] = 1;
  for (int k = 0; k < 40; ++k) p.push_back(static_cast<char>((i * 7 + k) % 13));
  return p;
}

// Writes 3 chunks of 100 messages on two channels (a Flush after each 100).
std::string WriteSample(const std::string& path, Compression c) {
  WriterOptions o;
  o.compression = c;
  o.library = "test";
  Writer w(path, o);
  w.AddMetadata("magnav_recording", {{"domain_id", "7"}, {"command_line", "magnav record"}});
  const std::uint16_t s = w.AddSchema("magnav::msg::GradiometerSample", "omgidl", "module magnav { };");
  const std::uint16_t a = w.AddChannel(s, "magnav/gradiometer", "cdr", {{"reliability", "reliable"}});
  const std::uint16_t b = w.AddChannel(s, "magnav/other", "cdr", {});
  for (int i = 0; i < 300; ++i) {
    w.Write(i % 3 ? a : b, static_cast<std::uint32_t>(i), 1000 + 10 * static_cast<std::uint64_t>(i),
            500 + static_cast<std::uint64_t>(i), Payload(i).data(), Payload(i).size());
    if (i % 100 == 99) w.Flush();
  }
  EXPECT_FALSE(std::filesystem::exists(path));  // the temporary until Close
  w.Close();
  return Slurp(path);
}

TEST(Mcap, RoundTripEveryCompression) {
  for (Compression c : {Compression::kNone, Compression::kZstd, Compression::kLz4}) {
    const std::string path = TempPath("rt.mcap");
    const std::string bytes = WriteSample(path, c);
    std::vector<Message> got;
    const ReadSummary s = Read(path, [&](const Message& m, const ReadSummary&) { got.push_back(m); });
    EXPECT_TRUE(s.truncated.empty()) << s.truncated;
    ASSERT_EQ(got.size(), 300u);
    for (int i = 0; i < 300; ++i) {
      EXPECT_EQ(got[i].sequence, static_cast<std::uint32_t>(i));
      EXPECT_EQ(got[i].log_time, 1000 + 10 * static_cast<std::uint64_t>(i));
      EXPECT_EQ(got[i].publish_time, 500 + static_cast<std::uint64_t>(i));
      EXPECT_EQ(got[i].data, Payload(i));
      EXPECT_EQ(got[i].channel_id, i % 3 ? 0 : 1);
    }
    EXPECT_EQ(s.chunks, 3u);
    ASSERT_EQ(s.channels.size(), 2u);
    EXPECT_EQ(s.channels[0].metadata.at(0).second, "reliable");
    ASSERT_EQ(s.schemas.size(), 1u);
    EXPECT_EQ(s.schemas[0].encoding, "omgidl");
    ASSERT_TRUE(s.statistics.has_value());
    EXPECT_EQ(s.statistics->message_count, 300u);
    EXPECT_EQ(s.statistics->chunk_count, 3u);
    EXPECT_EQ(s.statistics->message_start_time, 1000u);
    EXPECT_EQ(s.statistics->channel_message_counts.at(1), 100u);
    ASSERT_EQ(s.metadata.size(), 1u);
    EXPECT_EQ(s.metadata[0].values.at(0).second, "7");
    EXPECT_EQ(s.library, "test");
    // The same from memory.
    EXPECT_EQ(ReadBytes("mem", bytes, nullptr).messages, 300u);
    std::filesystem::remove(path);
  }
}

TEST(Mcap, WriterWithoutCloseLeavesNothing) {
  const std::string path = TempPath("abandoned.mcap");
  std::string temp;
  {
    Writer w(path, {});
    temp = w.temp_path();
    EXPECT_TRUE(std::filesystem::exists(temp));
  }
  EXPECT_FALSE(std::filesystem::exists(temp));
  EXPECT_FALSE(std::filesystem::exists(path));
}

// Cut at every offset of a compressed file: never an error, never a message
// of an incomplete chunk, the count is a whole number of chunks, and a
// warning says what is missing.
TEST(Mcap, TruncatedFilesAreReadUpToTheLastCompleteChunk) {
  const std::string path = TempPath("cut.mcap");
  const std::string bytes = WriteSample(path, Compression::kZstd);
  std::filesystem::remove(path);
  std::size_t checked = 0;
  for (std::size_t cut = 1; cut < bytes.size(); cut += (cut < 200 ? 1 : 7)) {
    const std::string part = bytes.substr(0, cut);
    ReadSummary s;
    ASSERT_NO_THROW(s = ReadBytes("cut.mcap", part, nullptr)) << "cut at " << cut;
    EXPECT_FALSE(s.truncated.empty()) << "cut at " << cut;
    EXPECT_EQ(s.messages % 100, 0u) << "cut at " << cut;
    EXPECT_EQ(s.messages, 100u * s.chunks);
    if (!s.truncated.empty()) {
      EXPECT_NE(s.truncated.find("cut.mcap: cut short at byte"), std::string::npos) << s.truncated;
      EXPECT_NE(s.truncated.find("missing:"), std::string::npos) << s.truncated;
    }
    ++checked;
  }
  EXPECT_GT(checked, 100u);
  // Cut inside the third chunk: two chunks read, the rest missing.
  const ReadSummary s = ReadBytes("cut.mcap", bytes.substr(0, bytes.size() * 2 / 3 + 1), nullptr);
  EXPECT_GE(s.chunks, 1u);
  EXPECT_NE(s.truncated.find("Data End"), std::string::npos) << s.truncated;
}

void ExpectInvalid(const std::string& bytes, const std::string& what) {
  try {
    ReadBytes("bad.mcap", bytes, nullptr);
    ADD_FAILURE() << "no error for: " << what;
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("bad.mcap: ", 0), 0u) << e.what();
  }
}

TEST(Mcap, CorruptFilesAreErrors) {
  const std::string path = TempPath("bad.mcap");
  const std::string none = WriteSample(path, Compression::kNone);
  std::filesystem::remove(path);
  const std::string zstd = WriteSample(path, Compression::kZstd);
  std::filesystem::remove(path);
  ExpectInvalid("", "empty");
  ExpectInvalid("PAR1 not mcap at all", "bad magic");
  std::string b = none;
  b[8] = 0x05;  // first record not a Header
  ExpectInvalid(b, "first record");
  // A payload byte flipped: the chunk CRC.
  b = none;
  const std::size_t msg = b.find(Payload(5));
  ASSERT_NE(msg, std::string::npos);
  b[msg + 10] ^= 0x40;
  ExpectInvalid(b, "crc");
  // Compressed bytes damaged.
  b = zstd;
  b[b.find("zstd") + 30] ^= 0xff;
  ExpectInvalid(b, "zstd data");
  // Unknown compression name.
  b = zstd;
  b.replace(b.find("zstd"), 4, "zzzz");
  ExpectInvalid(b, "compression");
  // Trailing garbage after the closing magic.
  ExpectInvalid(none + "x", "trailing bytes");
  // The closing magic damaged.
  b = none;
  b[b.size() - 3] = 'X';
  ExpectInvalid(b, "closing magic");
}

TEST(Mcap, StatisticsMustMatchTheData) {
  const std::string path = TempPath("stats.mcap");
  std::string b = WriteSample(path, Compression::kNone);
  std::filesystem::remove(path);
  // The Statistics record (opcode 0x0b, 66 bytes: two channel counts): its
  // message_count, after the opcode and length.
  const std::size_t stats = b.rfind(std::string("\x0b\x42\x00\x00\x00\x00\x00\x00\x00", 9));
  ASSERT_NE(stats, std::string::npos);
  b[stats + 9] = static_cast<char>(b[stats + 9] + 1);
  ExpectInvalid(b, "statistics count");
}

TEST(Mcap, Crc32MatchesTheStandardCheckValue) { EXPECT_EQ(Crc32("123456789", 9), 0xCBF43926u); }

}  // namespace
}  // namespace magnav::mcap
