// `magnav plot` end to end on the reference data: every kind draws a valid
// SVG, PNG or PDF of sane size from what the offline commands write (magnav
// invert, track, localize, match, simulate, evaluate --gospa), and bad
// requests are clear errors that leave no picture behind. The SVGs are read
// back for what makes a figure fit for a report (issue 23): the title is
// not a file path, each truth vessel is drawn in the colour of the track
// magnav evaluate pairs with it, a σ band has its line's colour, no text is
// turned into subscripts, and a map has equal metres on both axes.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
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

// The text elements of an SVG, in order.
std::vector<std::string> SvgTexts(const std::string& svg) {
  std::vector<std::string> out;
  const std::regex re("<text>([^<]*)</text>");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), re); it != std::sregex_iterator(); ++it) {
    out.push_back((*it)[1]);
  }
  return out;
}

// Every series gnuplot drew (its <g id="gnuplot_plot_N"> group): the legend
// text and the colour of its key sample (stroke, or fill for a band).
struct Series {
  std::string label, colour;
};
std::vector<Series> SvgSeries(const std::string& svg) {
  std::vector<Series> out;
  const std::string mark = "<g id=\"gnuplot_plot_";
  for (std::size_t at = svg.find(mark); at != std::string::npos;) {
    const std::size_t next = svg.find(mark, at + 1);
    const std::string block = svg.substr(at, next == std::string::npos ? std::string::npos : next - at);
    std::smatch text, colour;
    Series s;
    if (std::regex_search(block, text, std::regex("<text>([^<]*)</text>"))) s.label = text[1];
    if (std::regex_search(block, colour, std::regex("(?:stroke|fill) ?= ?'(rgb\\([^)]*\\))'"))) s.colour = colour[1];
    out.push_back(s);
    at = next;
  }
  return out;
}

std::string ColourOf(const std::vector<Series>& series, const std::string& label) {
  for (const auto& s : series) {
    if (s.label == label) return s.colour;
  }
  ADD_FAILURE() << "no series '" << label << "'";
  return "";
}

// No text of a picture is a file path, and none was set as enhanced text
// (gnuplot draws sub/superscripts of enhanced text as <tspan> elements).
void ExpectPlainTextNoPath(const std::string& svg_path) {
  const std::string s = Slurp(svg_path);
  EXPECT_EQ(s.find("<tspan"), std::string::npos) << svg_path << ": enhanced text (sub- or superscripts)";
  for (const auto& t : SvgTexts(s)) {
    EXPECT_EQ(t.find('/'), std::string::npos) << svg_path << ": a text is a path: " << t;
    EXPECT_EQ(t.find(".csv"), std::string::npos) << svg_path << ": a text names a file: " << t;
  }
}

// Pixels per data unit along x and along y, from the numeric tick labels:
// the x axis's are the lowest numbers drawn in a row (largest SVG y), the y
// axis's the leftmost in a column.
std::pair<double, double> PixelsPerUnit(const std::string& svg) {
  struct Tick {
    double x, y, v;
  };
  std::vector<Tick> ticks;
  const std::regex re("translate\\(([0-9.]+),([0-9.]+)\\)[^>]*>\\s*<text>\\s*(-?[0-9.]+)</text>");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), re); it != std::sregex_iterator(); ++it) {
    ticks.push_back({std::stod((*it)[1]), std::stod((*it)[2]), std::stod((*it)[3])});
  }
  double max_y = 0, min_x = 1e9;
  for (const auto& t : ticks) max_y = std::max(max_y, t.y), min_x = std::min(min_x, t.x);
  std::vector<Tick> on_x, on_y;
  for (const auto& t : ticks) {
    if (std::abs(t.y - max_y) < 0.5) on_x.push_back(t);
    if (std::abs(t.x - min_x) < 0.5) on_y.push_back(t);
  }
  if (on_x.size() < 2 || on_y.size() < 2) {
    ADD_FAILURE() << "too few tick labels";
    return {0, 0};
  }
  return {std::abs((on_x.back().x - on_x.front().x) / (on_x.back().v - on_x.front().v)),
          std::abs((on_y.back().y - on_y.front().y) / (on_y.back().v - on_y.front().v))};
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
  ExpectSvg(dir_ + "/tracks.svg", {"track 1", "track 2", "sensors", "2 tracks against 2 true vessel paths"});
  ExpectPng(dir_ + "/tracks.png", 900, 750);
  ExpectPlainTextNoPath(dir_ + "/tracks.svg");
  // Each vessel in the colour of the track magnav evaluate pairs with it
  // ("vessel V: ... track T (purity ..."), the two colours distinct.
  const auto [erc, eout] = Magnav({"evaluate", "--estimate", dir_ + "/t.csv", "--truth", dir_ + "/truth.csv",
                                   "--gospa", dir_ + "/gospa.csv"});
  ASSERT_EQ(erc, 0) << eout;
  const auto series = SvgSeries(Slurp(dir_ + "/tracks.svg"));
  std::set<std::string> colours;
  int paired = 0;
  const std::regex vessel_track("vessel ([0-9]+): [^\\n]*, track ([0-9]+) \\(purity");
  for (auto it = std::sregex_iterator(eout.begin(), eout.end(), vessel_track); it != std::sregex_iterator(); ++it) {
    const std::string v = (*it)[1], t = (*it)[2];
    const std::string truth_colour = ColourOf(series, "vessel " + v + " (truth), track " + t);
    EXPECT_EQ(truth_colour, ColourOf(series, "track " + t)) << "vessel " << v;
    EXPECT_NE(truth_colour, "");
    colours.insert(truth_colour);
    ++paired;
  }
  EXPECT_EQ(paired, 2) << eout;
  EXPECT_EQ(colours.size(), 2u);
  // Okabe–Ito's yellow (and pure yellow) are not used: invisible on white.
  for (const auto& s : series) {
    EXPECT_NE(s.colour, "rgb(240, 228,  66)") << s.label;
    EXPECT_NE(s.colour, "rgb(255, 255,   0)") << s.label;
  }
  // The error against time: each band in its line's colour, the y label a
  // quantity with its unit.
  const auto [rc, out] = Magnav({"plot", "--kind", "error", "--estimate", dir_ + "/t.csv", "--truth",
                                 dir_ + "/truth.csv", "--output", dir_ + "/error.svg"});
  ASSERT_EQ(rc, 0) << out;
  ExpectSvg(dir_ + "/error.svg", {"position error, 3-D (m)", "position error against the truth, 2 tracks"});
  ExpectPlainTextNoPath(dir_ + "/error.svg");
  const auto error_series = SvgSeries(Slurp(dir_ + "/error.svg"));
  for (const char* t : {"track 1", "track 2"}) {
    EXPECT_EQ(ColourOf(error_series, std::string(t) + ": 1-σ"), ColourOf(error_series, std::string(t) + ": |error|"));
  }
  EXPECT_NE(ColourOf(error_series, "track 1: |error|"), ColourOf(error_series, "track 2: |error|"));
  // GOSPA against time, as PDF and SVG.
  for (const char* ext : {".svg", ".pdf"}) {
    const auto [grc, gout] =
        Magnav({"plot", "--kind", "gospa", "--gospa", dir_ + "/gospa.csv", "--output", dir_ + "/gospa" + ext});
    ASSERT_EQ(grc, 0) << gout;
  }
  ExpectSvg(dir_ + "/gospa.svg", {"GOSPA (m)", "c = 10 m, p = 2", "one vessel missed"});
  ExpectPlainTextNoPath(dir_ + "/gospa.svg");
  const std::string pdf = Slurp(dir_ + "/gospa.pdf");
  EXPECT_EQ(pdf.substr(0, 5), "%PDF-");
  EXPECT_GT(pdf.size(), 5000u);
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
  // The reason is printed as written (an underscore, not a subscript).
  ExpectSvg(dir_ + "/fixes.svg", {"accepted (", "uncertain (", "rejected without a position: weak_signal"});
  ExpectPlainTextNoPath(dir_ + "/fixes.svg");
  // The accepted fixes are drawn after (over) every rejected kind.
  const auto series = SvgSeries(Slurp(dir_ + "/fixes.svg"));
  int accepted_at = -1, last_rejected_at = -1;
  for (int i = 0; i < static_cast<int>(series.size()); ++i) {
    const std::string& l = series[static_cast<std::size_t>(i)].label;
    if (l.rfind("accepted (", 0) == 0) accepted_at = i;
    if (l.rfind("uncertain (", 0) == 0 || l.rfind("infeasible_speed (", 0) == 0) last_rejected_at = i;
  }
  EXPECT_GE(last_rejected_at, 0);
  EXPECT_GT(accepted_at, last_rejected_at);
  // A title given with underscores and carets stays as written.
  ASSERT_EQ(Magnav({"plot", "--kind", "fixes", "--fixes", dir_ + "/fixes.csv", "--title", "run_2 x^2",
                    "--output", dir_ + "/fixes2.svg"})
                .first,
            0);
  const auto texts = SvgTexts(Slurp(dir_ + "/fixes2.svg"));
  EXPECT_NE(std::find(texts.begin(), texts.end(), "run_2 x^2"), texts.end());
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
  for (const char* ext : {".png", ".svg"}) {
    const auto [rc, out] = Magnav({"plot", "--kind", "match", "--map", Ref("map_crustal_anomaly.csv"),
                                   "--value-column", "anomaly_nT", "--path", path, "--matched", dir_ + "/m.csv",
                                   "--output", dir_ + "/match" + ext});
    ASSERT_EQ(rc, 0) << out;
  }
  ExpectPng(dir_ + "/match.png", 900, 750);
  ExpectSvg(dir_ + "/match.svg", {"anomaly (nT)", "north (km)", "INS", "matched", "true"});
  ExpectPlainTextNoPath(dir_ + "/match.svg");
  // Equal metres on both axes: as many pixels per km east as north (the
  // old plot in degrees drew this 45° N tile 1/cos 45° = 1.41 times too wide).
  const auto [px_east, px_north] = PixelsPerUnit(Slurp(dir_ + "/match.svg"));
  EXPECT_NEAR(px_east / px_north, 1.0, 0.01);
  // And the axes span the map's extent in km (spherical Earth here, WGS84 in
  // magnav: they agree to 0.5 %): the tick labels' span over the pixels.
  std::ifstream map(Ref("map_crustal_anomaly.csv"));
  std::string line;
  double lat_lo = 1e9, lat_hi = -1e9, lon_lo = 1e9, lon_hi = -1e9;
  int lat_col = -1, lon_col = -1;
  while (std::getline(map, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    if (lat_col < 0) {
      lat_col = static_cast<int>(std::find(cells.begin(), cells.end(), "lat") - cells.begin());
      lon_col = static_cast<int>(std::find(cells.begin(), cells.end(), "lon") - cells.begin());
      ASSERT_LT(lat_col, static_cast<int>(cells.size()));
      ASSERT_LT(lon_col, static_cast<int>(cells.size()));
      continue;
    }
    const double lat = std::stod(cells[lat_col]), lon = std::stod(cells[lon_col]);
    lat_lo = std::min(lat_lo, lat), lat_hi = std::max(lat_hi, lat);
    lon_lo = std::min(lon_lo, lon), lon_hi = std::max(lon_hi, lon);
  }
  const double km_per_deg = 6371.0 * M_PI / 180.0;
  const double east_km = (lon_hi - lon_lo) * km_per_deg * std::cos(0.5 * (lat_lo + lat_hi) * M_PI / 180.0);
  const double north_km = (lat_hi - lat_lo) * km_per_deg;
  const std::string svg = Slurp(dir_ + "/match.svg");
  // The plot's frame: the border path drawn last (M left,top L left,bottom L right,bottom ...).
  std::smatch border;
  ASSERT_TRUE(std::regex_search(svg, border,
                                std::regex("d='M([0-9.]+),([0-9.]+) L[0-9.]+,([0-9.]+) L([0-9.]+),[0-9.]+ "
                                           "L[0-9.]+,[0-9.]+ L[0-9.]+,[0-9.]+ Z")));
  const double width_px = std::stod(border[4]) - std::stod(border[1]);
  const double height_px = std::stod(border[3]) - std::stod(border[2]);
  EXPECT_NEAR((width_px / height_px) / (east_km / north_km), 1.0, 0.01)
      << width_px << " x " << height_px << " px for " << east_km << " x " << north_km << " km";
}

TEST_F(Plot, BadRequestsAreClearAndLeaveNoPicture) {
  const auto [rc1, out1] = Magnav({"plot", "--kind", "tracks", "--output", dir_ + "/x.svg"});
  EXPECT_EQ(rc1, 2);
  EXPECT_NE(out1.find("--kind tracks needs --estimate"), std::string::npos) << out1;
  const auto [rc2, out2] = Magnav({"plot", "--kind", "tracks", "--estimate", Ref("track_truth_auv.csv"), "--output",
                                   dir_ + "/x.jpg"});
  EXPECT_EQ(rc2, 2);
  EXPECT_NE(out2.find("ends in .svg, .png or .pdf"), std::string::npos) << out2;
  const auto [rc5, out5] = Magnav({"plot", "--kind", "tracks", "--estimate", Ref("track_truth_auv.csv"), "--format",
                                   "pdf", "--output", dir_ + "/x.svg"});
  EXPECT_EQ(rc5, 2);
  EXPECT_NE(out5.find("--format pdf disagrees"), std::string::npos) << out5;
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
