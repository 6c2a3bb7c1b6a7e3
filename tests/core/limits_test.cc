// The door's limits (core/limits.h): the defaults, a site's own limits
// (SetSiteLimits, LoadSiteLimits) and that every check follows the limits in
// force: the wire's CheckSample and the gradiometer file reader.
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/limits.h"
#include "test_data.h"

namespace magnav {
namespace {

struct SiteLimitsReset {
  ~SiteLimitsReset() { ResetSiteLimits(); }
};

std::string WriteText(const std::string& name, const std::string& text) {
  const std::string path = testing::TempDir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

GradiometerSample Squidlike(double T_element) {
  GradiometerSample s;
  s.B = {2e-5, 1e-6, 4.5e-5};
  s.T = Eigen::Matrix3d::Zero();
  s.T(0, 0) = T_element;
  s.T(1, 1) = -T_element;
  return s;
}

TEST(Limits, DefaultsAreTheTable) {
  SiteLimitsReset reset;
  for (const Limit& l : kLimits) {
    EXPECT_EQ(MaxAbs(l), l.max_abs) << l.key;
    EXPECT_EQ(LimitWhy(l), l.why) << l.key;
  }
  EXPECT_TRUE(DescribeSiteLimits().empty());
  EXPECT_EQ(CheckSample(Squidlike(1e-6)), SampleDefect::kNone);
}

// A site's tensor range (e.g. a SQUID array's): an element beyond 1e-7 T/m is
// not a reading there, though it is within the default of 10 T/m.
TEST(Limits, ASiteLimitHoldsOnTheWireAndInFiles) {
  SiteLimitsReset reset;
  const std::string limits = WriteText("squid_limits.toml", "# SQUID array\n[limits]\nT_Tpm = 1e-7  # T/m\n\n");
  LoadSiteLimits(limits);
  EXPECT_EQ(MaxAbs(kLimitT), 1e-7);
  EXPECT_EQ(MaxAbs(kLimitB), kLimitB.max_abs);  // not named: the default
  ASSERT_EQ(DescribeSiteLimits().size(), 1u);
  EXPECT_NE(DescribeSiteLimits()[0].find("T_Tpm = 1e-07"), std::string::npos) << DescribeSiteLimits()[0];
  EXPECT_EQ(CheckSample(Squidlike(1e-6)), SampleDefect::kOutOfRange);
  EXPECT_EQ(CheckSample(Squidlike(1e-8)), SampleDefect::kNone);
  EXPECT_FALSE(WithinLimit(kLimitT, 2e-7));
  EXPECT_TRUE(WithinLimit(kLimitT, -1e-7));
  // The file reader names the cell and the site's limit.
  const std::string pass = testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv");
  try {
    (void)ReadGradiometerFile(pass);
    FAIL() << "a pass with tensor elements up to 3.6e-7 T/m passed a 1e-7 T/m site limit";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("column 'T"), std::string::npos) << what;
    EXPECT_NE(what.find("(|value| > 1e-07 T/m; site limit from " + limits), std::string::npos) << what;
  }
  ResetSiteLimits();
  EXPECT_NO_THROW((void)ReadGradiometerFile(pass));
  EXPECT_EQ(CheckSample(Squidlike(1e-6)), SampleDefect::kNone);
}

TEST(Limits, ABadSiteFileChangesNothingAndSaysWhere) {
  SiteLimitsReset reset;
  SetSiteLimits({{"B_T", 1e-3}}, "earlier");
  const auto refused = [](const std::string& name, const std::string& text, const std::string& want) {
    const std::string path = WriteText(name, text);
    try {
      LoadSiteLimits(path);
      ADD_FAILURE() << name << ": accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << name << ": " << e.what();
    }
  };
  refused("unknown.toml", "B_nT = 5\n", "unknown limit 'B_nT' (known: position_m, B_T,");
  refused("nan.toml", "T_Tpm = nan\n", "'nan' is not a number");
  refused("negative.toml", "T_Tpm = -1\n", "must be a finite number > 0");
  refused("zero.toml", "time_step_s = 0\n", "must be a finite number > 0");
  refused("text.toml", "T_Tpm = small\n", ":1: limit 'T_Tpm': 'small' is not a number");
  refused("twice.toml", "T_Tpm = 1\nT_Tpm = 2\n", "given twice");
  refused("section.toml", "[inverter]\nT_Tpm = 1\n", ":1: section [inverter]");
  refused("noeq.toml", "T_Tpm 1\n", ":1: expected 'key = value'");
  refused("long.toml", std::string(5000, 'x') + "\n", ":1: line longer than");
  EXPECT_THROW(LoadSiteLimits(testing::TempDir()), InputError);  // a directory
  EXPECT_THROW(LoadSiteLimits(testing::TempDir() + "/missing.toml"), InputError);
  // Nothing above replaced the earlier site limits.
  EXPECT_EQ(MaxAbs(kLimitB), 1e-3);
  EXPECT_EQ(MaxAbs(kLimitT), kLimitT.max_abs);
}

}  // namespace
}  // namespace magnav
