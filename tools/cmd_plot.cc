// `magnav plot`: pictures (SVG, PNG or PDF, by gnuplot) of what the offline
// commands and `magnav record` write:
//   tracks   track(s) against the truth in plan view, one colour per track_id; each truth vessel
//            dashed in the colour of the track paired with it (association.h, as magnav evaluate
//            scores it), with the sensors
//   error    position error against time with each estimate's 1-σ (3-D) band, same colour
//   fixes    inverter fixes in plan view: rejected ones by reason, the accepted ones drawn last
//            (on top), with the truth
//   sensors  localised sensors with their 1-σ and Cramér–Rao ellipses, the deployment guesses and
//            the truth
//   match    a map-matching run over the map (viridis): INS, matched and true paths, in metres
//            east / north of the map's centre (a local equirectangular projection, WGS84
//            metres per degree at the centre's latitude), equal scales
//   gospa    GOSPA against time (magnav evaluate --gospa output)
// Plan views put east (y) across and north (x) up, metres, equal scales.
// Colours: gnuplot.h's kPalette (Okabe–Ito, colour-blind safe, no yellow).
// Default titles say what is drawn, never a file path.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "association.h"
#include "commands.h"
#include "gnuplot.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/mapmatch/fix_schedule.h"
#include "magnav/mapmatch/geo_grid.h"

namespace magnav::tools {

namespace {

struct PlotArgs {
  std::string kind, output, title;
  std::string estimate, truth, pass, fixes, sensors, deployment, map, value_column, path, matched, gospa;
  std::string format;    // svg, png, pdf; "" = from the output's ending
  double gate_m = 5.0;   // tracks: a track row farther than this from every vessel is paired with none
  int width = 900, height = 750;
};

using Rows = std::vector<std::vector<double>>;

// A number of a row, or nullopt for an empty or "nan" cell (a rejected fix
// has no position: magnav invert leaves it empty, magnav record writes nan).
std::optional<double> Cell(const CsvTable& t, std::size_t row, std::size_t col) {
  std::string text(t.text(row, col));
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  if (text.empty() || text == "nan" || text == "-nan") return std::nullopt;
  return t.number(row, col);
}

// Rows grouped by an integer column (or all in group 0 without it).
std::map<long long, std::vector<std::size_t>> GroupBy(const CsvTable& t, const std::string& column) {
  std::map<long long, std::vector<std::size_t>> g;
  const auto c = t.find_column(column);
  for (std::size_t i = 0; i < t.num_rows(); ++i) g[c ? t.integer(i, *c) : 0].push_back(i);
  return g;
}

std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (char ch : s) {
    if (ch == '\n') {
      out += "\\n";
      continue;
    }
    if (ch == '"' || ch == '\\') out += '\\';
    out += ch;
  }
  return out + "\"";
}

// One `plot` command of every series.
void PlotAll(GnuplotFigure* fig, const std::vector<std::string>& plots) {
  std::string cmd = "plot ";
  for (std::size_t i = 0; i < plots.size(); ++i) cmd += (i ? ", \\\n  " : "") + plots[i];
  fig->Script(cmd);
}

// A legend that takes little room: short samples, left-aligned texts, its
// top left corner against the plot's top right corner (whatever the plot's
// aspect), in a right margin kept for it.
constexpr const char* kKey =
    "set key at graph 1.03, graph 1 left top Left reverse samplen 2 spacing 1.1 width 1 font ',10'\n"
    "set rmargin 26";

void PlanView(GnuplotFigure* fig, const std::string& title) {
  fig->Script("set title " + Quote(title));
  fig->Script("set xlabel 'east y (m)'\nset ylabel 'north x (m)'\nset size ratio -1\nset grid");
  fig->Script(kKey);
}

std::string Plural(std::size_t n, const std::string& one, const std::string& many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

// Sensor positions (east, north) of a pass file.
Rows SensorsOfPass(const std::string& path) {
  const GradiometerFile f = ReadGradiometerFile(path);
  std::map<std::uint32_t, Eigen::Vector3d> at;
  for (const auto& s : f.samples) at.emplace(s.sensor_id, s.p_SinW);
  Rows rows;
  for (const auto& [id, p] : at) rows.push_back({p.y(), p.x()});
  return rows;
}

// The truth as position by (time, vessel): vessel 0 when there is no vessel_id.
struct Truth {
  std::map<long long, std::map<long long, Eigen::Vector3d>> at;  // round(t·1e6) -> vessel -> p
  std::map<long long, Rows> paths;                               // vessel -> (east, north)
  bool has_vessel_id = false;
};

Truth ReadTruth(const std::string& path) {
  const CsvTable t = CsvTable::Read(path);
  const std::size_t ct = t.column("t"), cx = t.column("x"), cy = t.column("y"), cz = t.column("z");
  const auto cv = t.find_column("vessel_id");
  Truth out;
  out.has_vessel_id = cv.has_value();
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    const long long v = cv ? t.integer(i, *cv) : 0;
    const Eigen::Vector3d p(t.number(i, cx), t.number(i, cy), t.number(i, cz));
    out.at[std::llround(t.number(i, ct) * 1e6)][v] = p;
    out.paths[v].push_back({p.y(), p.x()});
  }
  return out;
}

std::string VesselName(const Truth& truth, long long v) {
  return truth.has_vessel_id ? "vessel " + std::to_string(v) : "truth";
}

// The truth paths, dashed: a vessel paired with a track in that track's
// colour (colour_of_vessel), the others dark grey, each with its own dash
// pattern.
void PlotTruthPaths(const Truth& truth, const std::map<long long, std::string>& colour_of_vessel,
                    const std::map<long long, long long>& track_of_vessel, GnuplotFigure* fig,
                    std::vector<std::string>* plots) {
  int k = 0;
  for (const auto& [v, rows] : truth.paths) {
    const std::string d = fig->Data("truth" + std::to_string(v), rows);
    const auto c = colour_of_vessel.find(v);
    const auto t = track_of_vessel.find(v);
    std::string name = VesselName(truth, v) + (truth.has_vessel_id ? " (truth)" : "");
    if (t != track_of_vessel.end()) name += ", track " + std::to_string(t->second);
    plots->push_back(d + " using 1:2 with lines lw 2 " +
                     (c != colour_of_vessel.end() ? c->second + " dt (8,5)"
                                                  : "lc rgb '#404040' dt " + std::to_string(2 + k % 4)) +
                     " title " + Quote(name));
    ++k;
  }
}

void Tracks(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.estimate.empty()) throw InputError("--kind tracks needs --estimate TRACK.csv");
  const CsvTable e = CsvTable::Read(a.estimate);
  const std::size_t ct = e.column("t"), cx = e.column("x"), cy = e.column("y"), cz = e.column("z");
  const auto groups = GroupBy(e, "track_id");
  std::map<long long, std::string> colour_of_track;
  int k = 0;
  for (const auto& [id, rows] : groups) colour_of_track[id] = PaletteColour(k++);
  std::vector<std::string> plots;
  std::size_t vessels = 0;
  if (!a.truth.empty()) {
    const Truth truth = ReadTruth(a.truth);
    vessels = truth.paths.size();
    // Rows of each track per vessel, as magnav evaluate assigns them.
    std::map<long long, std::map<long long, std::size_t>> shared;
    for (const auto& [id, rows] : groups) {
      for (std::size_t i : rows) {
        const auto it = truth.at.find(std::llround(e.number(i, ct) * 1e6));
        if (it == truth.at.end()) continue;
        const auto n = FindNearestVessel(it->second, {e.number(i, cx), e.number(i, cy), e.number(i, cz)});
        if (n && n->distance_m <= a.gate_m) ++shared[n->vessel_id][id];
      }
    }
    const auto track_of_vessel = PairVesselsWithTracks(shared);
    std::map<long long, std::string> colour_of_vessel;
    for (const auto& [v, id] : track_of_vessel) colour_of_vessel[v] = colour_of_track.at(id);
    PlotTruthPaths(truth, colour_of_vessel, track_of_vessel, fig, &plots);
  }
  for (const auto& [id, rows] : groups) {
    Rows r;
    for (std::size_t i : rows) r.push_back({e.number(i, cy), e.number(i, cx)});
    plots.push_back(fig->Data("track" + std::to_string(id), r) + " using 1:2 with lines lw 2.5 " +
                    colour_of_track.at(id) + " title " + Quote("track " + std::to_string(id)));
  }
  std::size_t num_sensors = 0;
  if (!a.pass.empty()) {
    const Rows s = SensorsOfPass(a.pass);
    num_sensors = s.size();
    plots.push_back(fig->Data("sensors", s) + " using 1:2 with points pt 9 ps 1.6 lc rgb 'gray30' title 'sensors'");
  }
  std::string title = Plural(groups.size(), "track", "tracks");
  if (vessels > 0) title += " against " + Plural(vessels, "true vessel path", "true vessel paths") + " (dashed)";
  if (num_sensors > 0) title += ", " + Plural(num_sensors, "sensor", "sensors");
  PlanView(fig, a.title.empty() ? title : a.title);
  PlotAll(fig, plots);
}

void Error(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.estimate.empty() || a.truth.empty()) throw InputError("--kind error needs --estimate and --truth");
  const CsvTable e = CsvTable::Read(a.estimate);
  const Truth truth = ReadTruth(a.truth);
  const std::size_t ct = e.column("t"), cx = e.column("x"), cy = e.column("y"), cz = e.column("z");
  const auto sx = e.find_column("sigma_x"), sy = e.find_column("sigma_y"), sz = e.find_column("sigma_z");
  std::vector<std::string> bands, lines;
  int used = 0, k = 0;
  const auto tracks = GroupBy(e, "track_id");
  for (const auto& [id, rows] : tracks) {
    Rows r;
    for (std::size_t i : rows) {
      const auto it = truth.at.find(std::llround(e.number(i, ct) * 1e6));
      if (it == truth.at.end()) continue;
      const auto n = FindNearestVessel(it->second, {e.number(i, cx), e.number(i, cy), e.number(i, cz)});
      double sigma = std::nan("");
      if (sx && sy && sz) {
        const auto a2 = Cell(e, i, *sx), b2 = Cell(e, i, *sy), c2 = Cell(e, i, *sz);
        if (a2 && b2 && c2) sigma = std::sqrt(*a2 * *a2 + *b2 * *b2 + *c2 * *c2);
      }
      r.push_back({e.number(i, ct), n->distance_m, sigma});
      ++used;
    }
    if (r.empty()) continue;
    const std::string d = fig->Data("error" + std::to_string(id), r);
    const std::string name = tracks.size() > 1 ? "track " + std::to_string(id) : "estimate";
    const std::string colour = PaletteColour(k++);
    // The bands first, all of them, so that no band covers a line.
    bands.push_back(d + " using 1:(0):3 with filledcurves fs transparent solid 0.2 noborder " + colour + " title " +
                    Quote(name + ": 1-σ"));
    lines.push_back(d + " using 1:2 with lines lw 1.8 " + colour + " title " + Quote(name + ": |error|"));
  }
  if (used == 0) throw InputError(a.estimate + ": no estimate at a time of " + a.truth);
  std::vector<std::string> plots = bands;
  plots.insert(plots.end(), lines.begin(), lines.end());
  fig->Script("set title " +
              Quote(a.title.empty() ? "position error against the truth, " + Plural(tracks.size(), "track", "tracks") +
                                          (tracks.size() == 1 ? ", with its" : ", each with its") + " 1-σ (3-D) band"
                                    : a.title));
  fig->Script("set xlabel 'time t (s)'\nset ylabel 'position error, 3-D (m)'\nset logscale y\nset format y '%g'\nset grid");
  fig->Script(kKey);
  PlotAll(fig, plots);
}

void Fixes(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.fixes.empty()) throw InputError("--kind fixes needs --fixes FIXES.csv (magnav invert or record output)");
  const CsvTable f = CsvTable::Read(a.fixes);
  const std::size_t cx = f.column("dipole_x"), cy = f.column("dipole_y"), cv = f.column("valid");
  const auto cr = f.find_column("reason");
  std::map<std::string, Rows> drawn;
  std::map<std::string, int> undrawn;
  for (std::size_t i = 0; i < f.num_rows(); ++i) {
    const bool valid = f.integer(i, cv) != 0;
    const std::string reason = valid ? "accepted" : (cr ? std::string(f.text(i, *cr)) : std::string("rejected"));
    const auto x = Cell(f, i, cx), y = Cell(f, i, cy);
    if (x && y && std::isfinite(*x) && std::isfinite(*y)) {
      drawn[reason].push_back({*y, *x});
    } else {
      ++undrawn[reason];
    }
  }
  std::vector<std::string> plots;
  // Rejected fixes by reason (open markers, palette colours 2..), then the
  // accepted ones (filled, palette colour 1) over them.
  const int kOpen[] = {6, 4, 8, 12, 2, 1};
  int k = 0;
  std::size_t accepted = 0, total = 0;
  for (const auto& [reason, rows] : drawn) {
    total += rows.size();
    if (reason == "accepted") {
      accepted = rows.size();
      continue;
    }
    plots.push_back(fig->Data("fix" + std::to_string(k), rows) + " using 1:2 with points pt " +
                    std::to_string(kOpen[k % 6]) + " ps 0.8 " + PaletteColour(1 + k) + " title " +
                    Quote(reason + " (" + std::to_string(rows.size()) + ")"));
    ++k;
  }
  if (drawn.count("accepted")) {
    plots.push_back(fig->Data("accepted", drawn.at("accepted")) + " using 1:2 with points pt 7 ps 0.6 " +
                    PaletteColour(0) + " title " + Quote("accepted (" + std::to_string(accepted) + ")"));
  }
  // The truth last, over the fixes (which would hide it), dark grey (the
  // colours are the fixes'), one dash pattern per vessel.
  if (!a.truth.empty()) PlotTruthPaths(ReadTruth(a.truth), {}, {}, fig, &plots);
  std::string note;
  std::size_t not_drawn = 0;
  for (const auto& [reason, n] : undrawn) {
    note += (note.empty() ? "" : ", ") + reason + " " + std::to_string(n);
    not_drawn += static_cast<std::size_t>(n);
  }
  if (plots.empty()) throw InputError(a.fixes + ": no fix has a position to draw (" + note + ")");
  const std::string title = "dipole fixes: " + std::to_string(accepted) + " accepted of " +
                            std::to_string(total + not_drawn) + (a.truth.empty() ? "" : ", truth dashed");
  PlanView(fig, (a.title.empty() ? title : a.title) + (note.empty() ? "" : "\nrejected without a position: " + note));
  PlotAll(fig, plots);
}

void Sensors(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.sensors.empty()) throw InputError("--kind sensors needs --sensors SENSORS.csv (magnav localize output)");
  const CsvTable s = CsvTable::Read(a.sensors);
  const std::size_t id = s.column("sensor_id"), cx = s.column("x"), cy = s.column("y"), sx = s.column("sigma_x"),
                    sy = s.column("sigma_y");
  const auto kx = s.find_column("crlb_x"), ky = s.find_column("crlb_y");
  // The ellipses are drawn magnified so that they can be seen: the largest
  // is about 10-15 % of the plot's extent (the factor is in the legend).
  double lo_x = 1e300, hi_x = -1e300, lo_y = 1e300, hi_y = -1e300, max_sigma = 0.0;
  Rows est, sig, crlb;
  std::map<long long, Eigen::Vector2d> estimate;
  for (std::size_t i = 0; i < s.num_rows(); ++i) {
    const double x = s.number(i, cx), y = s.number(i, cy);
    estimate[s.integer(i, id)] = {x, y};
    lo_x = std::min(lo_x, x), hi_x = std::max(hi_x, x), lo_y = std::min(lo_y, y), hi_y = std::max(hi_y, y);
    max_sigma = std::max({max_sigma, s.number(i, sx), s.number(i, sy)});
  }
  const double extent = std::max({hi_x - lo_x, hi_y - lo_y, 1.0});
  const double scale =
      max_sigma > 0 ? std::pow(10.0, std::floor(std::log10(0.15 * extent / max_sigma))) : 1.0;
  for (std::size_t i = 0; i < s.num_rows(); ++i) {
    const double x = s.number(i, cx), y = s.number(i, cy);
    est.push_back({y, x});
    sig.push_back({y, x, 2 * scale * s.number(i, sy), 2 * scale * s.number(i, sx), 0.0});
    if (kx && ky) crlb.push_back({y, x, 2 * scale * s.number(i, *ky), 2 * scale * s.number(i, *kx), 0.0});
  }
  std::vector<std::string> plots;
  const std::string times = scale == 1.0 ? "" : " ×" + FormatNumber(scale);
  if (!a.deployment.empty()) {
    const CsvTable d = CsvTable::Read(a.deployment);
    Rows guess, moved;
    for (std::size_t i = 0; i < d.num_rows(); ++i) {
      const double x = d.number(i, d.column("x")), y = d.number(i, d.column("y"));
      guess.push_back({y, x});
      const auto it = estimate.find(d.integer(i, d.column("sensor_id")));
      if (it != estimate.end()) {
        moved.push_back({y, x, it->second.y() - y, it->second.x() - x});
      }
    }
    plots.push_back(fig->Data("moved", moved) +
                    " using 1:2:3:4 with vectors nohead dt 3 lc rgb 'gray50' title 'guess → estimate'");
    plots.push_back(fig->Data("guess", guess) + " using 1:2 with points pt 2 ps 1.2 lc rgb 'gray40' title 'deployment guess'");
  }
  plots.push_back(fig->Data("sigma", sig) + " using 1:2:3:4:5 with ellipses lw 2 " + PaletteColour(0) + " title " +
                  Quote("1-σ" + times));
  if (!crlb.empty()) {
    plots.push_back(fig->Data("crlb", crlb) + " using 1:2:3:4:5 with ellipses dt 2 lw 1.5 " + PaletteColour(1) +
                    " title " + Quote("Cramér–Rao bound" + times));
  }
  plots.push_back(fig->Data("est", est) + " using 1:2 with points pt 7 ps 0.7 " + PaletteColour(0) + " title 'estimate'");
  if (!a.truth.empty()) {
    const CsvTable t = CsvTable::Read(a.truth);
    Rows truth;
    for (std::size_t i = 0; i < t.num_rows(); ++i) truth.push_back({t.number(i, t.column("y")), t.number(i, t.column("x"))});
    plots.push_back(fig->Data("truth", truth) + " using 1:2 with points pt 6 ps 1.6 lc rgb 'black' title 'truth'");
  }
  PlanView(fig, a.title.empty() ? Plural(s.num_rows(), "localised sensor", "localised sensors") +
                                      ": estimates with 1-σ" + (crlb.empty() ? "" : " and Cramér–Rao") +
                                      " ellipses" + times
                                : a.title);
  PlotAll(fig, plots);
}

// What a map layer's column holds, for the colour bar: "anomaly_nT" ->
// "anomaly (nT)"; a column without a unit suffix is taken as nT.
std::string LayerLabel(const std::string& column) {
  std::string name = column, unit = "nT";
  const auto us = column.rfind('_');
  if (us != std::string::npos && us > 0) {
    const std::string suffix = column.substr(us + 1);
    if (suffix == "nT" || suffix == "nT/m" || suffix == "pT") {
      name = column.substr(0, us);
      unit = suffix;
    }
  }
  std::replace(name.begin(), name.end(), '_', ' ');
  return name + " (" + unit + ")";
}

// Viridis (matplotlib's, van der Walt & Smith 2015) at 9 of its 256 points:
// perceptually uniform, readable in grey and by colour-blind readers.
constexpr const char* kViridis =
    "set palette defined (0 '#440154', 1 '#472D7B', 2 '#3B528B', 3 '#2C728E', 4 '#21918C', 5 '#28AE80', "
    "6 '#5EC962', 7 '#ADDC30', 8 '#FDE725')";

void Match(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.map.empty() || a.value_column.empty() || a.path.empty()) {
    throw InputError("--kind match needs --map, --value-column and --path (and --matched, magnav match's output)");
  }
  const mapmatch::GeoGrid grid = mapmatch::ReadGeoGridFile(a.map, {a.value_column});
  // Local metric projection about the map's centre: km east and north.
  const double lat0 = 0.5 * (grid.lat().first_deg + grid.lat().last_deg());
  const double lon0 = 0.5 * (grid.lon().first_deg + grid.lon().last_deg());
  const double m_lat = mapmatch::MetresPerDegreeLat(lat0), m_lon = mapmatch::MetresPerDegreeLon(lat0);
  const auto east = [&](double lon) { return (lon - lon0) * m_lon * 1e-3; };
  const auto north = [&](double lat) { return (lat - lat0) * m_lat * 1e-3; };
  Rows nodes;
  nodes.reserve(grid.num_nodes());
  for (int i = 0; i < grid.lat().count; ++i) {
    for (int j = 0; j < grid.lon().count; ++j) {
      nodes.push_back({east(grid.lon().at(j)), north(grid.lat().at(i)), grid.node(0, i, j)});
    }
  }
  std::vector<std::string> plots;
  plots.push_back(fig->Data("map", nodes) + " using 1:2:3 with image notitle");
  const CsvTable p = CsvTable::Read(a.path);
  Rows ins, truth;
  const auto tl = p.find_column("true_lat"), tn = p.find_column("true_lon");
  for (std::size_t i = 0; i < p.num_rows(); ++i) {
    ins.push_back({east(p.number(i, p.column("ins_lon"))), north(p.number(i, p.column("ins_lat")))});
    if (tl && tn) truth.push_back({east(p.number(i, *tn)), north(p.number(i, *tl))});
  }
  // Each path over a casing of the opposite lightness, so that it shows on
  // every colour of the map.
  const auto path = [&](const std::string& name, const Rows& rows, const std::string& style, const std::string& casing,
                        const std::string& title) {
    const std::string d = fig->Data(name, rows);
    plots.push_back(d + " using 1:2 with lines lw 5 lc rgb '" + casing + "' notitle");
    plots.push_back(d + " using 1:2 with " + (name == "matched" ? "linespoints " : "lines ") + style + " title " +
                    Quote(title));
  };
  path("ins", ins, "lw 2 lc rgb 'white'", "black", "INS");
  if (!truth.empty()) path("true", truth, "lw 2 dt (5,3) lc rgb 'black'", "white", "true");
  std::size_t fixes = 0;
  if (!a.matched.empty()) {
    const CsvTable m = CsvTable::Read(a.matched);
    Rows r;
    for (std::size_t i = 0; i < m.num_rows(); ++i) {
      r.push_back({east(m.number(i, m.column("lon"))), north(m.number(i, m.column("lat")))});
    }
    fixes = r.size();
    path("matched", r, "lw 2.5 pt 7 ps 0.7 " + PaletteColour(1), "white", "matched");
  }
  std::string layer = LayerLabel(a.value_column);
  layer = layer.substr(0, layer.rfind(" ("));
  std::string title = "map matching over the " + layer + " map: INS" +
                      (truth.empty() ? "" : ", true") + (fixes > 0 ? " and matched paths" : " path" + std::string(truth.empty() ? "" : "s"));
  fig->Script("set title " + Quote(a.title.empty() ? title : a.title));
  fig->Script("set xlabel " + Quote("east of " + FormatNumber(lat0) + "° N, " + FormatNumber(lon0) + "° E (km)") +
              "\nset ylabel 'north (km)'\nset cblabel " + Quote(LayerLabel(a.value_column)) + "\n" + kViridis +
              "\nset size ratio -1\n"
              // Mid grey behind the legend: the white INS and black true samples both show.
              "set key inside top left Left reverse opaque fc rgb '#A0A0A0' box samplen 3 font ',10'");
  fig->Script("set xrange [" + FormatNumber(east(grid.lon().first_deg)) + ":" + FormatNumber(east(grid.lon().last_deg())) +
              "]");
  fig->Script("set yrange [" + FormatNumber(north(grid.lat().first_deg)) + ":" +
              FormatNumber(north(grid.lat().last_deg())) + "]");
  PlotAll(fig, plots);
}

// GOSPA against time (magnav evaluate --gospa FILE: t,gospa,...), with the
// value of one missed vessel and nothing else, c·2^(-1/p), for scale.
void Gospa(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.gospa.empty()) throw InputError("--kind gospa needs --gospa GOSPA.csv (magnav evaluate --gospa output)");
  const CsvTable g = CsvTable::Read(a.gospa);
  const std::size_t ct = g.column("t"), cg = g.column("gospa");
  Rows r;
  for (std::size_t i = 0; i < g.num_rows(); ++i) r.push_back({g.number(i, ct), g.number(i, cg)});
  // c and p from the file's "# gospa: c = 10 m, p = 2, ..." line.
  std::string params;
  double c = std::nan(""), p = std::nan("");
  {
    std::ifstream in(a.gospa);
    std::string line;
    for (int n = 0; n < 100 && std::getline(in, line); ++n) {
      if (line.rfind("# gospa: ", 0) == 0) {
        params = line.substr(9, line.find(';') == std::string::npos ? std::string::npos : line.find(';') - 9);
        std::sscanf(params.c_str(), "c = %lf m, p = %lf", &c, &p);
        break;
      }
    }
  }
  std::vector<std::string> plots;
  plots.push_back(fig->Data("gospa", r) + " using 1:2 with lines lw 2 " + PaletteColour(0) + " title 'GOSPA'");
  if (std::isfinite(c) && std::isfinite(p) && p >= 1) {
    plots.push_back(FormatNumber(c * std::pow(2.0, -1.0 / p)) + " with lines dt 2 lw 1.5 lc rgb 'gray40' title " +
                    Quote("one vessel missed"));
  }
  fig->Script("set title " + Quote(a.title.empty() ? "GOSPA of the tracks against the truth, per epoch" +
                                                         (params.empty() ? "" : " (" + params + ")")
                                                   : a.title));
  fig->Script("set xlabel 'time t (s)'\nset ylabel 'GOSPA (m)'\nset yrange [0:*]\nset grid");
  fig->Script(kKey);
  PlotAll(fig, plots);
}

void RunPlot(const PlotArgs& a) {
  std::vector<std::string> inputs;
  for (const std::string* in : {&a.estimate, &a.truth, &a.pass, &a.fixes, &a.sensors, &a.deployment, &a.map, &a.path,
                                &a.matched, &a.gospa}) {
    if (!in->empty()) inputs.push_back(*in);
  }
  RefuseOutputOverInput(a.output, inputs);
  GnuplotFigure fig(a.output, a.width, a.height, a.format);
  if (a.kind == "tracks") {
    Tracks(a, &fig);
  } else if (a.kind == "error") {
    Error(a, &fig);
  } else if (a.kind == "fixes") {
    Fixes(a, &fig);
  } else if (a.kind == "sensors") {
    Sensors(a, &fig);
  } else if (a.kind == "match") {
    Match(a, &fig);
  } else if (a.kind == "gospa") {
    Gospa(a, &fig);
  } else {
    throw InputError("--kind: expected tracks, error, fixes, sensors, match or gospa, got '" + a.kind + "'");
  }
  fig.Render();
  std::printf("wrote %s\n", a.output.c_str());
}

}  // namespace

void AddPlotCommand(CLI::App& app) {
  auto args = std::make_shared<PlotArgs>();
  CLI::App* cmd = app.add_subcommand("plot", "Draw a picture (SVG, PNG or PDF, by gnuplot) of a result file");
  cmd->add_option("--kind", args->kind,
                  "tracks (plan view, one colour per track_id, each truth vessel dashed in the colour of the track "
                  "paired with it as magnav evaluate assigns rows), error (|error| and 1-sigma band against time), "
                  "fixes (rejected by reason, accepted on top), sensors (localised sensors with 1-sigma and CRLB "
                  "ellipses), match (map-matching paths over the map, km east/north of its centre, viridis), gospa "
                  "(GOSPA against time, magnav evaluate --gospa output)")
      ->required()
      ->check(CLI::IsMember({"tracks", "error", "fixes", "sensors", "match", "gospa"}));
  cmd->add_option("--output", args->output, "picture to write: *.svg, *.png or *.pdf")->required();
  cmd->add_option("--format", args->format, "svg, png or pdf (default: from the --output ending)")
      ->check(CLI::IsMember({"svg", "png", "pdf"}));
  cmd->add_option("--title", args->title, "title (default: what is drawn, e.g. '2 tracks against 2 true vessel paths')");
  cmd->add_option("--estimate", args->estimate, "tracks, error: magnav track output or a recorded track topic");
  cmd->add_option("--truth", args->truth,
                  "tracks, error, fixes: truth t,x,y,z (vessel_id for several vessels); sensors: true sensor "
                  "positions sensor_id,x,y");
  cmd->add_option("--pass", args->pass, "tracks: pass or field file whose sensors are drawn");
  cmd->add_option("--fixes", args->fixes, "fixes: magnav invert output or a recorded dipole_fix topic");
  cmd->add_option("--sensors", args->sensors, "sensors: magnav localize output (sensor_id,x,y,z,sigma_x,sigma_y,...)");
  cmd->add_option("--deployment", args->deployment, "sensors: the deployment guesses (sensor_id,x,y,...)");
  cmd->add_option("--map", args->map, "match: the map (CSV, NGDC text or a GDAL raster)");
  cmd->add_option("--value-column", args->value_column, "match: the map layer drawn");
  cmd->add_option("--path", args->path, "match: the map-matching path (k,ins_lat,ins_lon[,true_lat,true_lon])");
  cmd->add_option("--matched", args->matched, "match: magnav match output (k,lat,lon)");
  cmd->add_option("--gospa", args->gospa, "gospa: magnav evaluate --gospa output (t,gospa,...)");
  cmd->add_option("--gate", args->gate_m,
                  "tracks: a track row farther than this from every truth vessel pairs with none, m (default 5, "
                  "magnav evaluate's --gate)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--width", args->width, "picture width, px")->check(CLI::Range(200, 4000));
  cmd->add_option("--height", args->height, "picture height, px")->check(CLI::Range(200, 4000));
  cmd->callback([args] { RunPlot(*args); });
}

}  // namespace magnav::tools
