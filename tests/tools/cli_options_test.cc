// The command-line helpers of magnav::cli: a yes/no option takes 0/1,
// true/false or on/off and refuses any other value (CLI11 alone turns any
// integer into a bool: "--x 2" would silently mean on, "--x -1" off).
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <gtest/gtest.h>

#include "magnav/cli/options.h"
#include "magnav/cli/particle_filter_options.h"
#include "magnav/cli/tracker_options.h"

namespace magnav::cli {
namespace {

// Parses `args` (program name first) and returns whether CLI11 accepted them.
bool Parses(CLI::App& app, std::vector<std::string> args) {
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
    return true;
  } catch (const CLI::ParseError&) {
    return false;
  }
}

TEST(SwitchOption, TakesTheWordsOfYesAndNoAndRefusesOtherNumbers) {
  struct Case {
    std::string value;
    bool accepted;
    bool result;
  };
  for (const Case& c : {Case{"1", true, true}, Case{"0", true, false}, Case{"on", true, true},
                        Case{"off", true, false}, Case{"TRUE", true, true}, Case{"false", true, false},
                        Case{"2", false, false}, Case{"-1", false, false}, Case{"0.5", false, false},
                        Case{"yes please", false, false}}) {
    CLI::App app;
    bool value = false;
    AddSwitchOption(app, "--x", &value, "a switch");
    EXPECT_EQ(Parses(app, {"prog", "--x", c.value}), c.accepted) << c.value;
    if (c.accepted) {
      EXPECT_EQ(value, c.result) << c.value;
    }
  }
}

TEST(SwitchOption, TrackerAndParticleFilterSwitchesRefuseAnInteger) {
  {
    CLI::App app;
    TrackerFlags flags;
    AddTrackerOptions(app, &flags, "fixes");
    EXPECT_FALSE(Parses(app, {"prog", "--excuse-beside", "2"}));
  }
  {
    CLI::App app;
    TrackerFlags flags;
    AddTrackerOptions(app, &flags, "fixes");
    ASSERT_TRUE(Parses(app, {"prog", "--pair-refit-excess", "0"}));
    EXPECT_FALSE(flags.options.management.pair_refit_excess);
  }
  {
    CLI::App app;
    mapmatch::ParticleFilterOptions pf;
    AddParticleFilterOptions(app, &pf);
    EXPECT_FALSE(Parses(app, {"prog", "--adaptive-sigma", "3"}));
  }
  {
    CLI::App app;
    mapmatch::ParticleFilterOptions pf;
    AddParticleFilterOptions(app, &pf);
    ASSERT_TRUE(Parses(app, {"prog", "--adaptive-sigma", "off"}));
    EXPECT_FALSE(pf.adaptive_sigma);
  }
}

}  // namespace
}  // namespace magnav::cli
