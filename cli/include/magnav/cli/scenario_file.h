// Scenario files of `magnav simulate --scenario FILE`: a sensor field crossed
// by several vessels, in the TOML subset the --config files use (CLI11's
// reader). Strict: an unknown key or section is an error naming the key.
//
//   rate = 10                   # Hz (default 10)
//   seed = 1001                 # noise and drift directions (default 1)
//   noise = "fluxgate"          # none | fluxgate (1 nT, 1.4 nT/m) | squid (0.1 pT, 0.1 pT/m)
//   sigma_b = 1e-9              # T per axis, overrides noise (optional)
//   sigma_t = 1.4e-9            # T/m per element, overrides noise (optional)
//   b0 = [2e-5, 1e-6, 4.5e-5]   # background field NED, T (default as the reference)
//   grid = [3, 3, 36]           # NX, NY, SPACING_M: grid at z = 0 centred on the origin
//   sensors = [0,0,0, 36,0,0]   # or: the sensors' positions, X,Y,Z per sensor, NED m
//   drift_nt_per_min = 3        # per-sensor background drift, nT/min (default 0): each
//                               # sensor's B0 moves linearly at this rate in a direction
//                               # drawn from the seed (the pass file lists them)
//
//   [vessel.1]                  # one section per vessel; the number is its vessel_id
//   t0 = 0                      # s from the start, when it appears (default 0)
//   moment = [2000, 300, 800]   # body moment, A*m^2 (x fwd, y stbd, z down)
//   start = [-100, -12, -5]     # NED m at t0 (z: down; the grid lies at z = 0)
//   speed = 1.2                 # m/s and
//   heading = 0                 # rad from north clockwise, or instead of both:
//   velocity = [1.2, 0]         # north, east m/s
//   duration = 200              # s, a straight run, or:
//   turns = [80, 0, 60, 0.02]   # DURATION_S, TURN_RATE_RPS pairs
//   waypoints = [x,y,z, x,y,z]  # or: straight legs through these points at `speed`
//                               # (instead of start, heading, velocity, duration, turns)
#pragma once

#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Core>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/simulate.h"

namespace magnav::cli {

namespace scenario_detail {

inline std::vector<double> Numbers(const std::string& where, const std::string& key,
                                   const std::vector<std::string>& inputs) {
  std::vector<double> out;
  for (const std::string& raw : inputs) {
    std::string s = raw;
    CLI::detail::trim(s);
    if (s.empty()) continue;
    const auto x = ParseNumber(s);
    if (!x || !std::isfinite(*x)) throw InputError(where + "'" + key + "': '" + raw + "' is not a finite number");
    out.push_back(*x);
  }
  return out;
}

inline double One(const std::string& where, const std::string& key, const std::vector<std::string>& inputs) {
  const auto v = Numbers(where, key, inputs);
  if (v.size() != 1) throw InputError(where + "'" + key + "': expected one number");
  return v[0];
}

inline std::vector<Eigen::Vector3d> Triples(const std::string& where, const std::string& key,
                                            const std::vector<std::string>& inputs) {
  const auto v = Numbers(where, key, inputs);
  if (v.empty() || v.size() % 3 != 0) throw InputError(where + "'" + key + "': expected X, Y, Z per point");
  std::vector<Eigen::Vector3d> out;
  for (std::size_t i = 0; i < v.size(); i += 3) out.emplace_back(v[i], v[i + 1], v[i + 2]);
  return out;
}

inline Eigen::Vector3d Triple(const std::string& where, const std::string& key,
                              const std::vector<std::string>& inputs) {
  const auto t = Triples(where, key, inputs);
  if (t.size() != 1) throw InputError(where + "'" + key + "': expected [X, Y, Z]");
  return t[0];
}

}  // namespace scenario_detail

// Parses a scenario's text; `name` (the file) prefixes every message.
// Throws InputError on any unknown key, bad value or invalid scenario.
inline FieldScenario ParseScenario(const std::string& text, const std::string& name) {
  using namespace scenario_detail;
  std::string body = text;
  if (body.rfind("\xEF\xBB\xBF", 0) == 0) body.erase(0, 3);
  // A comment after a section header ("[vessel.1]  # the AUV") is cut here:
  // CLI11 2.1 reads it as part of the section name (after a value it drops it).
  {
    std::istringstream lines(body);
    std::string line, cleaned;
    while (std::getline(lines, line)) {
      std::string head = line;
      CLI::detail::ltrim(head);
      if (!head.empty() && head.front() == '[' && head.find('#') != std::string::npos) {
        line = head.substr(0, head.find('#'));
      }
      cleaned += line + "\n";
    }
    body = cleaned;
  }
  std::istringstream in(body);
  std::vector<CLI::ConfigItem> items;
  try {
    items = CLI::ConfigTOML().from_config(in);
  } catch (const CLI::Error& e) {
    throw InputError(name + ": " + e.what());
  }
  const std::string top = name + ": ";
  FieldScenario sc;
  sc.sensors.clear();
  std::string noise = "none";
  double sigma_b = -1.0, sigma_t = -1.0, drift_nt_per_min = 0.0;
  bool has_grid = false, has_sensors = false;
  std::set<std::string> seen_top;
  // Vessels by id, in file order of first appearance.
  std::vector<std::uint32_t> order;
  std::map<std::uint32_t, std::map<std::string, std::vector<std::string>>> vessel_keys;
  for (const CLI::ConfigItem& item : items) {
    if (item.name == "++" || item.name == "--") continue;
    if (item.parents.empty()) {
      const std::string& k = item.name;
      if (!seen_top.insert(k).second) throw InputError(top + "'" + k + "' given twice");
      if (k == "rate") {
        sc.rate_hz = One(top, k, item.inputs);
      } else if (k == "seed") {
        const double s = One(top, k, item.inputs);
        if (!(s >= 0) || s != std::floor(s) || s > 9e15) throw InputError(top + "'seed' must be a whole number >= 0");
        sc.seed = static_cast<std::uint64_t>(s);
      } else if (k == "noise") {
        if (item.inputs.size() != 1) throw InputError(top + "'noise': expected one of none, fluxgate, squid");
        noise = item.inputs[0];
        CLI::detail::remove_quotes(noise);
        if (noise != "none" && noise != "fluxgate" && noise != "squid") {
          throw InputError(top + "'noise': '" + noise + "' is not one of none, fluxgate, squid");
        }
      } else if (k == "sigma_b") {
        sigma_b = One(top, k, item.inputs);
      } else if (k == "sigma_t") {
        sigma_t = One(top, k, item.inputs);
      } else if (k == "b0") {
        sc.B0 = Triple(top, k, item.inputs);
      } else if (k == "grid") {
        const auto g = Numbers(top, k, item.inputs);
        if (g.size() != 3 || g[0] < 1 || g[1] < 1 || g[0] != std::floor(g[0]) || g[1] != std::floor(g[1]) ||
            g[0] * g[1] > 10000 || !(g[2] > 0.0)) {
          throw InputError(top +
                           "'grid': expected [NX, NY, SPACING_M] (whole NX, NY >= 1, NX*NY <= 10000, spacing > 0)");
        }
        sc.sensors = SensorGrid(static_cast<int>(g[0]), static_cast<int>(g[1]), g[2]);
        has_grid = true;
      } else if (k == "sensors") {
        sc.sensors = Triples(top, k, item.inputs);
        if (sc.sensors.size() > 10000) throw InputError(top + "'sensors': at most 10000");
        has_sensors = true;
      } else if (k == "drift_nt_per_min") {
        drift_nt_per_min = One(top, k, item.inputs);
        if (!(drift_nt_per_min >= 0.0) || drift_nt_per_min > 1e6) {
          throw InputError(top + "'drift_nt_per_min' must be in [0, 1e6]");
        }
      } else {
        throw InputError(top + "unknown key '" + k +
                         "' (top-level keys: rate, seed, noise, sigma_b, sigma_t, b0, grid, sensors, "
                         "drift_nt_per_min; vessels go in [vessel.ID] sections)");
      }
      continue;
    }
    if (item.parents.size() != 2 || item.parents[0] != "vessel") {
      std::string section;
      for (const auto& p : item.parents) section += (section.empty() ? "" : ".") + p;
      throw InputError(top + "section [" + section + "] is not supported (vessels go in [vessel.ID] sections)");
    }
    const auto id = ParseNumber(item.parents[1]);
    if (!id || !(*id >= 1.0) || *id != std::floor(*id) || *id > 4e9) {
      throw InputError(top + "[vessel." + item.parents[1] + "]: the id must be a whole number >= 1");
    }
    const auto vid = static_cast<std::uint32_t>(*id);
    if (!vessel_keys.count(vid)) order.push_back(vid);
    auto& keys = vessel_keys[vid];
    if (keys.count(item.name)) {
      throw InputError(top + "[vessel." + item.parents[1] + "] '" + item.name + "' given twice");
    }
    keys[item.name] = item.inputs;
  }
  if (has_grid && has_sensors) throw InputError(top + "'grid' and 'sensors': give one of them");
  if (!has_grid && !has_sensors) throw InputError(top + "no sensors: give 'grid' or 'sensors'");
  if (order.empty()) throw InputError(top + "no vessel: give at least one [vessel.ID] section");
  if (noise == "fluxgate") {
    sc.sigma_B = 1e-9;
    sc.sigma_T = 1.4e-9;
  } else if (noise == "squid") {
    sc.sigma_B = 1e-13;
    sc.sigma_T = 1e-13;
  }
  if (sigma_b >= 0.0) sc.sigma_B = sigma_b;
  if (sigma_t >= 0.0) sc.sigma_T = sigma_t;
  for (const std::uint32_t vid : order) {
    const std::string where = name + ": [vessel." + std::to_string(vid) + "] ";
    const auto& keys = vessel_keys[vid];
    FieldVessel v;
    v.vessel_id = vid;
    const auto has = [&](const char* k) { return keys.count(k) != 0; };
    for (const auto& [k, inputs] : keys) {
      if (k == "t0") {
        v.t_start_s = One(where, k, inputs);
      } else if (k == "moment") {
        v.moment_body = Triple(where, k, inputs);
      } else if (k == "start") {
        v.start_position = Triple(where, k, inputs);
      } else if (k == "speed") {
        v.speed_mps = One(where, k, inputs);
      } else if (k == "heading") {
        v.start_heading_rad = One(where, k, inputs);
      } else if (k == "velocity") {
        const auto vel = Numbers(where, k, inputs);
        if (vel.size() != 2) throw InputError(where + "'velocity': expected [NORTH, EAST] m/s");
        v.speed_mps = std::hypot(vel[0], vel[1]);
        v.start_heading_rad = std::atan2(vel[1], vel[0]);
      } else if (k == "duration") {
        v.segments = {{One(where, k, inputs), 0.0}};
      } else if (k == "turns") {
        const auto t = Numbers(where, k, inputs);
        if (t.empty() || t.size() % 2 != 0) {
          throw InputError(where + "'turns': expected DURATION_S, TURN_RATE_RPS pairs");
        }
        v.segments.clear();
        for (std::size_t i = 0; i < t.size(); i += 2) v.segments.push_back({t[i], t[i + 1]});
      } else if (k == "waypoints") {
        v.waypoints = Triples(where, k, inputs);
      } else {
        throw InputError(where + "unknown key '" + k +
                         "' (vessel keys: t0, moment, start, speed, heading, velocity, duration, turns, waypoints)");
      }
    }
    if (has("velocity") && (has("speed") || has("heading"))) {
      throw InputError(where + "'velocity' replaces 'speed' and 'heading': give one or the other");
    }
    if (has("duration") && has("turns")) throw InputError(where + "'duration' and 'turns': give one of them");
    if (has("waypoints")) {
      for (const char* k : {"start", "heading", "velocity", "duration", "turns"}) {
        if (has(k)) throw InputError(where + "'waypoints' replaces '" + std::string(k) + "'");
      }
    }
    sc.vessels.push_back(v);
  }
  if (drift_nt_per_min > 0.0) {
    // Drift directions from their own stream of the seed (not the noise's).
    sc.background_drift_Tps = RandomDrifts(sc.sensors.size(), drift_nt_per_min * 1e-9 / 60.0, sc.seed ^ 0x5DEECE66DULL);
  }
  std::string why;
  if (!sc.IsValid(&why)) throw InputError(top + why);
  return sc;
}

// Reads and parses a scenario file (ParseScenario).
inline FieldScenario ReadScenarioFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path + ": cannot open the scenario file");
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (text.size() > (1u << 20)) throw InputError(path + ": a scenario file is at most 1 MiB");
  return ParseScenario(text, path);
}

}  // namespace magnav::cli
