// `magnav plot` end to end on the reference data: every kind draws a valid
// SVG and PNG of sane size from what the offline commands write (magnav
// invert, track, localize, match, simulate), and bad requests are clear
// errors that leave no picture behind.
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "subprocess.h"
#include "test_data.h"

namespace magnav {
namespace {

const std::string kMagnav = MAGNAV_BIN;

std::pair<int, std::string> Magnav(std::vector<std::string> args) {
  args.insert(args.begin(), kMagnav);
  return testing::RunCommand(args, {}, std::chrono::seconds(120));
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// A PNG starts with its signature and an IHDR chunk (width, height big-endian).
void ExpectPng(const std::string& path, int width, int height) {
  const std::string b = Slurp(path);
  ASSERT_GT(b.size(), 5000u) << path;
  ASSERT_LT(b.size(), 5000000u) << path;
  EXPECT_EQ(b.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8)) << path;
  EXPECT_EQ(b.substr(12, 4), "IHDR") << path;
  const auto be32 = [&](std::size_t at) {
    return (static_cast<unsigned char>(b[at]) << 24) | (static_cast<unsigned char>(b[at + 1]) << 16) |
           (static_cast<unsigned char>(b[at + 2]) << 8) | static_cast<unsigned char>(b[at + 3]);
  };
  EXPECT_EQ(static_cast<int>(be32(16)), width) << path;
  EXPECT_EQ(static_cast<int>(be32(20)), height) << path;
}

// An SVG document that closes, with `fragments` in it (legend texts).
void ExpectSvg(const std::string& path, const std::vector<std::string>& fragments) {
  const std::string s = Slurp(path);
  ASSERT_GT(s.size(), 5000u) << path;
  ASSERT_LT(s.size(), 20000000u) << path;
  EXPECT_NE(s.find("<svg"), std::string::npos) << path;
  EXPECT_NE(s.find("</svg>"), std::string::npos) << path;
  for (const auto& f : fragments) EXPECT_NE(s.find(f), std::string::npos) << path << ": " << f;
}

class Plot : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::TempDir(); }
  std::string Ref(const std::string& name) { return testing::ReferencePath(name); }
  std::string dir_;
};

TEST_F(Plot, TracksOfATwoVesselFieldAgainstTheTruth) {
  ASSERT_EQ(Magnav({"simulate", "--noise", "fluxgate", "--grid", "3,3,40", "--vessel",
                    "id=1;start=-100,38,-5;heading=0;speed=1.5;moment=2500,300,900;turns=140:0", "--vessel",
                    "id=2;start=38,100,-6;heading=-1.5708;speed=1.2;moment=1800,-500,700;turns=140:0", "--output",
                    dir_ + "/field.csv", "--truth", dir_ + "/truth.csv"})
                .first,
            0);
  ASSERT_EQ(Magnav({"track", "--input", dir_ + "/field.csv", "--mode", "window", "--output", dir_ + "/t.csv"}).first,
            0);
  for (const char* ext : {".svg", ".png"}) {
    const auto [rc, out] = Magnav({"plot", "--kind", "tracks", "--estimate", dir_ + "/t.csv", "--truth",
                                   dir_ + "/truth.csv", "--pass", dir_ + "/field.csv", "--output",
                                   dir_ + "/tracks" + ext});
    ASSERT_EQ(rc, 0) << out;
  }
  ExpectSvg(dir_ + "/tracks.svg", {"track 1", "track 2", "truth, vessel 1", "truth, vessel 2", "sensors"});
  ExpectPng(dir_ + "/tracks.png", 900, 750);
  // The error against time, with the σ envelope.
  const auto [rc, out] = Magnav({"plot", "--kind", "error", "--estimate", dir_ + "/t.csv", "--truth",
                                 dir_ + "/truth.csv", "--output", dir_ + "/error.svg"});
  ASSERT_EQ(rc, 0) << out;
  ExpectSvg(dir_ + "/error.svg", {"|error| (track 1)", "1-σ (3-D) (track 2)"});
}

TEST_F(Plot, InverterFixesByReason) {
  ASSERT_EQ(Magnav({"invert", "--input", Ref("track_pass_auv_1sensor_fluxgate.csv"), "--method", "ted-egt",
                    "--output", dir_ + "/fixes.csv"})
                .first,
            0);
  const auto [rc, out] = Magnav({"plot", "--kind", "fixes", "--fixes", dir_ + "/fixes.csv", "--truth",
                                 Ref("track_truth_auv.csv"), "--output", dir_ + "/fixes.svg", "--width", "640",
                                 "--height", "480"});
  ASSERT_EQ(rc, 0) << out;
  ExpectSvg(dir_ + "/fixes.svg", {"accepted (", "uncertain (", "rejected without a position: weak_signal"});
}

TEST_F(Plot, LocalisedSensorsWithTheirEllipses) {
  ASSERT_EQ(Magnav({"localize", "--measurements", Ref("localize_measurements.csv"), "--deployment",
                    Ref("localize_deployment.csv"), "--gnss", Ref("localize_gnss_full.csv"), "--method", "ekf",
                    "--output", dir_ + "/sensors.csv"})
                .first,
            0);
  const auto [rc, out] =
      Magnav({"plot", "--kind", "sensors", "--sensors", dir_ + "/sensors.csv", "--deployment",
              Ref("localize_deployment.csv"), "--truth", Ref("localize_truth_sensors.csv"), "--output",
              dir_ + "/sensors.png"});
  ASSERT_EQ(rc, 0) << out;
  ExpectPng(dir_ + "/sensors.png", 900, 750);
  ASSERT_EQ(Magnav({"plot", "--kind", "sensors", "--sensors", dir_ + "/sensors.csv", "--output",
                    dir_ + "/sensors.svg"})
                .first,
            0);
  ExpectSvg(dir_ + "/sensors.svg", {"1-σ ×100", "Cramér–Rao bound ×100"});
}

TEST_F(Plot, MapMatchingOverTheMap) {
  const std::string path = Ref("mappath_crustal_off0p01deg_noise0p5nT.csv");
  ASSERT_EQ(Magnav({"match", "--map", Ref("map_crustal_anomaly.csv"), "--value-column", "anomaly_nT", "--path", path,
                    "--meas-column", "meas_nT", "--method", "fast-msd", "--search-window", "0.15", "--output",
                    dir_ + "/m.csv"})
                .first,
            0);
  const auto [rc, out] = Magnav({"plot", "--kind", "match", "--map", Ref("map_crustal_anomaly.csv"), "--value-column",
                                 "anomaly_nT", "--path", path, "--matched", dir_ + "/m.csv", "--output",
                                 dir_ + "/match.png"});
  ASSERT_EQ(rc, 0) << out;
  ExpectPng(dir_ + "/match.png", 900, 750);
}

TEST_F(Plot, BadRequestsAreClearAndLeaveNoPicture) {
  const auto [rc1, out1] = Magnav({"plot", "--kind", "tracks", "--output", dir_ + "/x.svg"});
  EXPECT_EQ(rc1, 2);
  EXPECT_NE(out1.find("--kind tracks needs --estimate"), std::string::npos) << out1;
  const auto [rc2, out2] = Magnav({"plot", "--kind", "tracks", "--estimate", Ref("track_truth_auv.csv"), "--output",
                                   dir_ + "/x.jpg"});
  EXPECT_EQ(rc2, 2);
  EXPECT_NE(out2.find("ends in .svg or .png"), std::string::npos) << out2;
  std::ofstream(dir_ + "/bad.csv") << "t,track_id,x,y,z\n0,1,1,oops,3\n";
  const auto [rc3, out3] =
      Magnav({"plot", "--kind", "tracks", "--estimate", dir_ + "/bad.csv", "--output", dir_ + "/x.svg"});
  EXPECT_EQ(rc3, 2);
  EXPECT_NE(out3.find("bad.csv:2: column 'y'"), std::string::npos) << out3;
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/x.svg"));
  // A picture over one of its inputs is refused, the input left as it was.
  std::ofstream(dir_ + "/in.svg") << "t,track_id,x,y,z\n0,1,1,2,3\n";
  const auto [rc4, out4] =
      Magnav({"plot", "--kind", "tracks", "--estimate", dir_ + "/in.svg", "--output", dir_ + "/in.svg"});
  EXPECT_EQ(rc4, 2);
  EXPECT_EQ(Slurp(dir_ + "/in.svg"), "t,track_id,x,y,z\n0,1,1,2,3\n");
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/x.jpg"));
}

}  // namespace
}  // namespace magnav
