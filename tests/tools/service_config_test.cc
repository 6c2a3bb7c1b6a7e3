// The services' config files (--config, TOML/INI, keys = long flag names):
// an unknown key, a typo or a key under a [section] is refused at start; the
// site limits file (--limits) of every program.
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

// A site's limits (--limits FILE, also from --config as `limits = FILE`): a
// bad limits file stops every service at start (exit 2, naming file and line);
// a good one is logged, and `magnav` holds its commands' input to it (a pass
// whose tensor elements reach 3.6e-7 T/m is refused under a 1e-7 T/m site
// limit, the flag given before or after the subcommand).
TEST(ServiceConfig, SiteLimitsAreTheDoorsOfEveryProgram) {
  const std::string dir = testing::TempDir();
  const std::string bad = dir + "/bad_limits.toml", tight = dir + "/tight_limits.toml", cfg = dir + "/svc.toml";
  std::ofstream(bad) << "[limits]\nT_Tpm = -1\n";
  std::ofstream(tight) << "T_Tpm = 1e-7\n";
  std::ofstream(cfg) << "limits = \"" << bad << "\"\n";
  for (const std::string bin : {MAGNAV_INVERTER_BIN, MAGNAV_TRACKER_BIN, MAGNAV_LOCALIZER_BIN, MAGNAV_MATCHER_BIN}) {
    for (const std::vector<std::string>& args : {std::vector<std::string>{bin, "--limits", bad},
                                                  std::vector<std::string>{bin, "--config", cfg}}) {
      const auto [rc, out] = testing::RunCommand(args, {}, std::chrono::seconds(20));
      EXPECT_EQ(rc, 2) << bin << "\n" << out;
      EXPECT_NE(out.find(bad + ": limit 'T_Tpm' = -1: must be a finite number > 0"), std::string::npos) << bin << "\n" << out;
    }
  }
  const std::string pass = testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{MAGNAV_BIN, "invert", "--method", "ted-egt", "--input", pass, "--output", dir + "/f.csv", "--limits", tight},
        std::vector<std::string>{MAGNAV_BIN, "--limits", tight, "invert", "--method", "ted-egt", "--input", pass, "--output", dir + "/f.csv"}}) {
    const auto [rc, out] = testing::RunCommand(args);
    EXPECT_EQ(rc, 2) << out;
    EXPECT_NE(out.find("T/m is out of range (|value| > 1e-07 T/m; site limit from " + tight), std::string::npos) << out;
    EXPECT_NE(out.find("limit T_Tpm = 1e-07 T/m (site limit from " + tight), std::string::npos) << out;
  }
  const auto [rc, out] = testing::RunCommand({MAGNAV_BIN, "invert", "--method", "ted-egt", "--input", pass, "--output", dir + "/f.csv"});
  EXPECT_EQ(rc, 0) << out;  // the defaults
}

}  // namespace
}  // namespace magnav
