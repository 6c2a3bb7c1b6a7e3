// The command-line helpers of magnav::cli: a yes/no option takes 0/1,
// true/false or on/off and refuses any other value (CLI11 alone turns any
// integer into a bool: "--x 2" would silently mean on, "--x -1" off); an
// on/off option takes only on or off, and its default is its option's own.
#include <string>
#include <tuple>
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

TEST(OnOffOption, TakesOnOrOffOnlyAndShowsTheOptionsOwnDefault) {
  for (const bool initial : {false, true}) {
    for (const auto& [value, accepted, result] :
         {std::tuple<std::string, bool, bool>{"on", true, true}, {"off", true, false}, {"1", false, initial},
          {"true", false, initial}, {"ON", false, initial}, {"", false, initial}}) {
      CLI::App app;
      bool b = initial;
      CLI::Option* o = AddOnOffOption(app, "--x", &b, "a choice");
      EXPECT_EQ(o->get_default_str(), initial ? "on" : "off");
      EXPECT_EQ(Parses(app, {"prog", "--x", value}), accepted) << value;
      EXPECT_EQ(b, result) << value;
    }
    CLI::App app;
    bool b = initial;
    AddOnOffOption(app, "--x", &b, "a choice");
    ASSERT_TRUE(Parses(app, {"prog"}));
    EXPECT_EQ(b, initial) << "not given: the option keeps its value";
  }
}

TEST(OnOffOption, TrackerFlagsGiveTheLibraryDefaultsAndSetTheirOptions) {
  {
    CLI::App app;
    TrackerFlags flags;
    AddTrackerOptions(app, &flags, "fixes");
    ASSERT_TRUE(Parses(app, {"prog"}));
    const tracker::MultiTrackerOptions o = ApplyTrackerFlags(flags);
    const tracker::MultiTrackerOptions d;
    EXPECT_EQ(o.background.enabled, d.background.enabled);
    EXPECT_EQ(o.cluster_background.enabled, d.cluster_background.enabled);
    EXPECT_EQ(o.far_source.drift.enabled, d.far_source.drift.enabled);
    EXPECT_EQ(o.far_source.drift.batch_refit, d.far_source.drift.batch_refit);
    EXPECT_EQ(o.far_source.grid_when_refused, d.far_source.grid_when_refused);
    EXPECT_EQ(o.far_source.back_predict_new_tracks, d.far_source.back_predict_new_tracks);
    EXPECT_EQ(o.variance_factor.enabled, d.variance_factor.enabled);
    EXPECT_EQ(o.track.batch_variance_factor.enabled, d.track.batch_variance_factor.enabled);
    EXPECT_EQ(o.track.sensor_offset.carry, d.track.sensor_offset.carry);
    EXPECT_EQ(o.track.sensor_offset.batch_score_test, d.track.sensor_offset.batch_score_test);
    EXPECT_EQ(o.track.sensor_offset.batch_joint, d.track.sensor_offset.batch_joint);
    EXPECT_EQ(o.track.sensor_offset.quiet, d.track.sensor_offset.quiet);
    EXPECT_EQ(o.track.sensor_offset.quiet_rate, d.track.sensor_offset.quiet_rate);
    EXPECT_EQ(o.track.sensor_offset.quiet_rate_span_s, d.track.sensor_offset.quiet_rate_span_s);
    EXPECT_EQ(o.track.sensor_offset.quiet_approach, d.track.sensor_offset.quiet_approach);
    EXPECT_EQ(o.track.sensor_offset.window_lines, d.track.sensor_offset.window_lines);
    EXPECT_EQ(o.track.sensor_offset.window_score_test, d.track.sensor_offset.window_score_test);
    EXPECT_EQ(o.track.sensor_offset.window_score_persist_s, d.track.sensor_offset.window_score_persist_s);
  }
  {
    // Each flag set against its default reaches its own option.
    const tracker::MultiTrackerOptions d;
    auto word = [](bool on) { return std::string(on ? "off" : "on"); };  // the opposite of the default
    CLI::App app;
    TrackerFlags flags;
    AddTrackerOptions(app, &flags, "fixes");
    ASSERT_TRUE(Parses(app, {"prog", "--far-drift", word(d.far_source.drift.enabled), "--far-back-predict",
                             word(d.far_source.back_predict_new_tracks), "--batch-variance-factor",
                             word(d.track.batch_variance_factor.enabled), "--sensor-offset-joint",
                             word(d.track.sensor_offset.batch_joint), "--window-offset-lines",
                             word(d.track.sensor_offset.window_lines), "--window-offset-score-test",
                             word(d.track.sensor_offset.window_score_test), "--sensor-offset-quiet-rate-span", "30",
                             "--window-offset-score-persist", "2.5"}));
    const tracker::MultiTrackerOptions o = ApplyTrackerFlags(flags);
    EXPECT_NE(o.far_source.drift.enabled, d.far_source.drift.enabled);
    EXPECT_NE(o.far_source.back_predict_new_tracks, d.far_source.back_predict_new_tracks);
    EXPECT_NE(o.track.batch_variance_factor.enabled, d.track.batch_variance_factor.enabled);
    EXPECT_NE(o.track.sensor_offset.batch_joint, d.track.sensor_offset.batch_joint);
    EXPECT_NE(o.track.sensor_offset.window_lines, d.track.sensor_offset.window_lines);
    EXPECT_NE(o.track.sensor_offset.window_score_test, d.track.sensor_offset.window_score_test);
    EXPECT_EQ(o.track.sensor_offset.quiet_rate_span_s, 30.0);
    EXPECT_EQ(o.track.sensor_offset.window_score_persist_s, 2.5);
    EXPECT_EQ(o.far_source.grid_when_refused, d.far_source.grid_when_refused);  // not given: as it was
  }
}

}  // namespace
}  // namespace magnav::cli
