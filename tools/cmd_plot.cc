// `magnav plot`: pictures (SVG or PNG, by gnuplot) of what the offline
// commands and `magnav record` write:
//   tracks   track(s) against the truth in plan view, one colour per track_id, with the sensors
//   error    position error against time with each estimate's 1-σ (3-D) envelope
//   fixes    inverter fixes in plan view: accepted, and rejected ones by reason, with the truth
//   sensors  localised sensors with their 1-σ and Cramér–Rao ellipses, the deployment guesses and
//            the truth
//   match    a map-matching run over the map (colour scale): INS, matched and true paths
// Plan views put east (y) across and north (x) up, metres, equal scales.
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "gnuplot.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/mapmatch/geo_grid.h"

namespace magnav::tools {

namespace {

struct PlotArgs {
  std::string kind, output, title;
  std::string estimate, truth, pass, fixes, sensors, deployment, map, value_column, path, matched;
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

void PlanView(GnuplotFigure* fig, const std::string& title) {
  fig->Script("set title " + Quote(title) + " noenhanced");
  fig->Script("set xlabel 'east y (m)'\nset ylabel 'north x (m)'\nset size ratio -1\nset grid\nset key outside right");
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
};

Truth ReadTruth(const std::string& path) {
  const CsvTable t = CsvTable::Read(path);
  const std::size_t ct = t.column("t"), cx = t.column("x"), cy = t.column("y"), cz = t.column("z");
  const auto cv = t.find_column("vessel_id");
  Truth out;
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    const long long v = cv ? t.integer(i, *cv) : 0;
    const Eigen::Vector3d p(t.number(i, cx), t.number(i, cy), t.number(i, cz));
    out.at[std::llround(t.number(i, ct) * 1e6)][v] = p;
    out.paths[v].push_back({p.y(), p.x()});
  }
  return out;
}

void PlotTruthPaths(const Truth& truth, GnuplotFigure* fig, std::vector<std::string>* plots) {
  for (const auto& [v, rows] : truth.paths) {
    const std::string d = fig->Data("truth" + std::to_string(v), rows);
    plots->push_back(d + " using 1:2 with lines dt 2 lw 1.5 lc rgb 'black' title " +
                     Quote(truth.paths.size() > 1 ? "truth, vessel " + std::to_string(v) : "truth"));
  }
}

void Tracks(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.estimate.empty()) throw InputError("--kind tracks needs --estimate TRACK.csv");
  const CsvTable e = CsvTable::Read(a.estimate);
  const std::size_t cx = e.column("x"), cy = e.column("y");
  std::vector<std::string> plots;
  if (!a.truth.empty()) PlotTruthPaths(ReadTruth(a.truth), fig, &plots);
  for (const auto& [id, rows] : GroupBy(e, "track_id")) {
    Rows r;
    for (std::size_t i : rows) r.push_back({e.number(i, cy), e.number(i, cx)});
    plots.push_back(fig->Data("track" + std::to_string(id), r) + " using 1:2 with lines lw 2.5 title " +
                    Quote("track " + std::to_string(id)));
  }
  if (!a.pass.empty()) {
    plots.push_back(fig->Data("sensors", SensorsOfPass(a.pass)) +
                    " using 1:2 with points pt 9 ps 1.8 lc rgb 'dark-red' title 'sensors'");
  }
  PlanView(fig, a.title.empty() ? "tracks: " + a.estimate : a.title);
  PlotAll(fig, plots);
}

void Error(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.estimate.empty() || a.truth.empty()) throw InputError("--kind error needs --estimate and --truth");
  const CsvTable e = CsvTable::Read(a.estimate);
  const Truth truth = ReadTruth(a.truth);
  const std::size_t ct = e.column("t"), cx = e.column("x"), cy = e.column("y"), cz = e.column("z");
  const auto sx = e.find_column("sigma_x"), sy = e.find_column("sigma_y"), sz = e.find_column("sigma_z");
  std::vector<std::string> plots;
  int used = 0;
  const auto tracks = GroupBy(e, "track_id");
  for (const auto& [id, rows] : tracks) {
    Rows r;
    for (std::size_t i : rows) {
      const auto it = truth.at.find(std::llround(e.number(i, ct) * 1e6));
      if (it == truth.at.end()) continue;
      const Eigen::Vector3d p(e.number(i, cx), e.number(i, cy), e.number(i, cz));
      double err = 1e300;
      for (const auto& [v, q] : it->second) err = std::min(err, (p - q).norm());
      double sigma = std::nan("");
      if (sx && sy && sz) {
        const auto a2 = Cell(e, i, *sx), b2 = Cell(e, i, *sy), c2 = Cell(e, i, *sz);
        if (a2 && b2 && c2) sigma = std::sqrt(*a2 * *a2 + *b2 * *b2 + *c2 * *c2);
      }
      r.push_back({e.number(i, ct), err, sigma});
      ++used;
    }
    if (r.empty()) continue;
    const std::string d = fig->Data("error" + std::to_string(id), r);
    const std::string name = tracks.size() > 1 ? " (track " + std::to_string(id) + ")" : "";
    plots.push_back(d + " using 1:(0):3 with filledcurves fs transparent solid 0.25 noborder title " +
                    Quote("1-σ (3-D)" + name));
    plots.push_back(d + " using 1:2 with lines lw 1.5 title " + Quote("|error|" + name));
  }
  if (used == 0) throw InputError(a.estimate + ": no estimate at a time of " + a.truth);
  fig->Script("set title " + Quote(a.title.empty() ? "position error: " + a.estimate : a.title) + " noenhanced");
  fig->Script("set xlabel 't (s)'\nset ylabel 'm'\nset logscale y\nset format y '10^{%L}'\nset grid\nset key outside right");
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
  if (!a.truth.empty()) PlotTruthPaths(ReadTruth(a.truth), fig, &plots);
  int k = 0;
  for (const auto& [reason, rows] : drawn) {
    const bool ok = reason == "accepted";
    const std::string style = ok ? "pt 7 ps 0.6 lc rgb 'forest-green'" : "pt " + std::to_string(1 + k % 6) + " ps 0.8";
    plots.push_back(fig->Data("fix" + std::to_string(k), rows) + " using 1:2 with points " + style + " title " +
                    Quote(reason + " (" + std::to_string(rows.size()) + ")"));
    ++k;
  }
  std::string note;
  for (const auto& [reason, n] : undrawn) note += (note.empty() ? "" : ", ") + reason + " " + std::to_string(n);
  if (plots.empty()) throw InputError(a.fixes + ": no fix has a position to draw (" + note + ")");
  PlanView(fig, (a.title.empty() ? "dipole fixes: " + a.fixes : a.title) +
                    (note.empty() ? "" : "\nrejected without a position: " + note));
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
  plots.push_back(fig->Data("sigma", sig) + " using 1:2:3:4:5 with ellipses lw 2 lc rgb 'blue' title " +
                  Quote("1-σ" + times));
  if (!crlb.empty()) {
    plots.push_back(fig->Data("crlb", crlb) + " using 1:2:3:4:5 with ellipses dt 2 lw 1.5 lc rgb 'red' title " +
                    Quote("Cramér–Rao bound" + times));
  }
  plots.push_back(fig->Data("est", est) + " using 1:2 with points pt 7 ps 0.7 lc rgb 'blue' title 'estimate'");
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
  if (!a.truth.empty()) {
    const CsvTable t = CsvTable::Read(a.truth);
    Rows truth;
    for (std::size_t i = 0; i < t.num_rows(); ++i) truth.push_back({t.number(i, t.column("y")), t.number(i, t.column("x"))});
    plots.push_back(fig->Data("truth", truth) + " using 1:2 with points pt 6 ps 1.6 lc rgb 'black' title 'truth'");
  }
  PlanView(fig, a.title.empty() ? "sensor positions: " + a.sensors : a.title);
  PlotAll(fig, plots);
}

void Match(const PlotArgs& a, GnuplotFigure* fig) {
  if (a.map.empty() || a.value_column.empty() || a.path.empty()) {
    throw InputError("--kind match needs --map, --value-column and --path (and --matched, magnav match's output)");
  }
  const mapmatch::GeoGrid grid = mapmatch::ReadGeoGridFile(a.map, {a.value_column});
  Rows nodes;
  nodes.reserve(grid.num_nodes());
  for (int i = 0; i < grid.lat().count; ++i) {
    for (int j = 0; j < grid.lon().count; ++j) nodes.push_back({grid.lon().at(j), grid.lat().at(i), grid.node(0, i, j)});
  }
  std::vector<std::string> plots;
  plots.push_back(fig->Data("map", nodes) + " using 1:2:3 with image title ''");
  const CsvTable p = CsvTable::Read(a.path);
  Rows ins, truth;
  const auto tl = p.find_column("true_lat"), tn = p.find_column("true_lon");
  for (std::size_t i = 0; i < p.num_rows(); ++i) {
    ins.push_back({p.number(i, p.column("ins_lon")), p.number(i, p.column("ins_lat"))});
    if (tl && tn) truth.push_back({p.number(i, *tn), p.number(i, *tl)});
  }
  plots.push_back(fig->Data("ins", ins) + " using 1:2 with lines lw 2 lc rgb 'gray25' title 'INS'");
  if (!truth.empty()) {
    plots.push_back(fig->Data("true", truth) + " using 1:2 with lines lw 2 dt 2 lc rgb 'black' title 'true'");
  }
  if (!a.matched.empty()) {
    const CsvTable m = CsvTable::Read(a.matched);
    Rows r;
    for (std::size_t i = 0; i < m.num_rows(); ++i) r.push_back({m.number(i, m.column("lon")), m.number(i, m.column("lat"))});
    plots.push_back(fig->Data("matched", r) + " using 1:2 with lines lw 2.5 lc rgb 'magenta' title 'matched'");
  }
  fig->Script("set title " + Quote(a.title.empty() ? "map matching: " + a.path : a.title) + " noenhanced");
  fig->Script("set xlabel 'longitude (deg)'\nset ylabel 'latitude (deg)'\nset cblabel " + Quote(a.value_column + " (nT)") +
              " noenhanced\nset palette rgb 33,13,10\nset key outside bottom center horizontal\nset size ratio -1");
  fig->Script("set xrange [" + FormatNumber(grid.lon().first_deg) + ":" + FormatNumber(grid.lon().last_deg()) + "]");
  fig->Script("set yrange [" + FormatNumber(grid.lat().first_deg) + ":" + FormatNumber(grid.lat().last_deg()) + "]");
  PlotAll(fig, plots);
}

void RunPlot(const PlotArgs& a) {
  std::vector<std::string> inputs;
  for (const std::string* in : {&a.estimate, &a.truth, &a.pass, &a.fixes, &a.sensors, &a.deployment, &a.map, &a.path,
                                &a.matched}) {
    if (!in->empty()) inputs.push_back(*in);
  }
  RefuseOutputOverInput(a.output, inputs);
  GnuplotFigure fig(a.output, a.width, a.height);
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
  } else {
    throw InputError("--kind: expected tracks, error, fixes, sensors or match, got '" + a.kind + "'");
  }
  fig.Render();
  std::printf("wrote %s\n", a.output.c_str());
}

}  // namespace

void AddPlotCommand(CLI::App& app) {
  auto args = std::make_shared<PlotArgs>();
  CLI::App* cmd = app.add_subcommand("plot", "Draw a picture (SVG or PNG, by gnuplot) of a result file");
  cmd->add_option("--kind", args->kind,
                  "tracks (plan view, one colour per track_id), error (|error| and 1-sigma against time), fixes "
                  "(accepted / rejected by reason), sensors (localised sensors with 1-sigma and CRLB ellipses), "
                  "match (map-matching paths over the map)")
      ->required()
      ->check(CLI::IsMember({"tracks", "error", "fixes", "sensors", "match"}));
  cmd->add_option("--output", args->output, "picture to write: *.svg or *.png")->required();
  cmd->add_option("--title", args->title, "title (default: what is drawn and from which file)");
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
  cmd->add_option("--width", args->width, "picture width, px")->check(CLI::Range(200, 4000));
  cmd->add_option("--height", args->height, "picture height, px")->check(CLI::Range(200, 4000));
  cmd->callback([args] { RunPlot(*args); });
}

}  // namespace magnav::tools
