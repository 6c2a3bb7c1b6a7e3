// Every input in tests/data/fuzz/<target>/ (see its README) goes through the
// fuzz target's own entry point (fuzz/entries.h) and is refused cleanly: the
// entry returns (it catches InputError and CLI11's ParseError, as the
// programs do); a crash, another exception or a broken invariant (abort)
// fails the test.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "entries.h"
#include "test_data.h"

namespace magnav {
namespace {

namespace fs = std::filesystem;

using Entry = void (*)(const std::uint8_t*, std::size_t);

std::vector<std::string> Inputs(const std::string& target) {
  std::vector<std::string> files;
  const fs::path dir = fs::path(testing::TestDataDir()) / "fuzz" / target;
  if (!fs::is_directory(dir)) return files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file()) files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

void Replay(const std::string& target, Entry entry) {
  const auto files = Inputs(target);
  for (const std::string& file : files) {
    SCOPED_TRACE(file);
    std::ifstream in(file, std::ios::binary);
    ASSERT_TRUE(in) << "cannot read " << file;
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NO_THROW(entry(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
  }
  ::testing::Test::RecordProperty("inputs", static_cast<int>(files.size()));
}

TEST(FuzzRegression, Csv) { Replay("csv", fuzz::FuzzCsv); }
TEST(FuzzRegression, Map) { Replay("map", fuzz::FuzzMap); }
TEST(FuzzRegression, Config) { Replay("config", fuzz::FuzzConfig); }
// The MCAP reader on its seeds and on the bad-input corpus's MCAP files.
TEST(FuzzRegression, Mcap) {
  Replay("mcap", fuzz::FuzzMcap);
  ASSERT_FALSE(Inputs("../bad/mcap").empty());
  Replay("../bad/mcap", fuzz::FuzzMcap);
}
#ifdef MAGNAV_WITH_DDS
TEST(FuzzRegression, DdsConvert) {
  ASSERT_FALSE(Inputs("dds_convert").empty());
  Replay("dds_convert", fuzz::FuzzDdsConvert);
}
#endif

}  // namespace
}  // namespace magnav
