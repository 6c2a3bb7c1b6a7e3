// The services' config files (--config, TOML/INI, keys = long flag names):
// an unknown key, a typo or a key under a [section] is refused at start.
#include <chrono>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "subprocess.h"
#include "test_data.h"

namespace magnav {
namespace {

// A service refuses to start on a config file with an unknown key, a typo, or
// a key under a [section] (CLI11 would ignore them: with b0 under [magnav] the
// inverter ran with B0 = 0), naming the file, the line and the key; exit 2.
TEST(ServiceConfig, UnknownKeysAndSectionsAreRefused) {
  const std::string cfg = testing::TempDir() + "/service.toml";
  struct Case {
    std::string text, expected;
  };
  const std::vector<Case> cases = {
      {"stats-period = 5\nstats-perod = 5\n", cfg + ":2: unknown option 'stats-perod'"},
      {"# magnav\n\n[magnav]\nb0 = \"2e-05,1e-06,4.5e-05\"\n", cfg + ":4: section [magnav] is not supported (key 'b0')"},
      {"stats-period = 5\n[dds]\n", cfg + ":2: section [dds] is not supported"},
      {"\xEF\xBB\xBF" "stats-period = 5\nstats_period = 5\n", cfg + ":2: unknown option 'stats_period'"},
  };
  int refused = 0;
  for (const std::string bin : {MAGNAV_INVERTER_BIN, MAGNAV_TRACKER_BIN, MAGNAV_LOCALIZER_BIN, MAGNAV_MATCHER_BIN}) {
    for (const Case& c : cases) {
      std::ofstream(cfg, std::ios::binary) << c.text;
      const auto [rc, out] = testing::RunCommand({bin, "--config", cfg}, {}, std::chrono::seconds(20));
      EXPECT_EQ(rc, 2) << bin << "\n" << c.text << "\n" << out;
      EXPECT_NE(out.find(c.expected), std::string::npos) << bin << "\n" << c.text << "\n" << out;
      refused += rc == 2;
    }
  }
  EXPECT_EQ(refused, 16);
}

}  // namespace
}  // namespace magnav
