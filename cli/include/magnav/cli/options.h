// Command-line helpers shared by the `magnav` program and the services:
// three-number options ("X,Y,Z"), the common set-up of a service's command
// line (options also from a TOML/INI file), and parsing with magnav's exit codes.
#pragma once

#include <iterator>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <spdlog/spdlog.h>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/limits.h"

namespace magnav::cli {

// A "X,Y,Z" option; `set` tells whether it was given.
struct Vec3Arg {
  bool set = false;
  double v[3] = {0, 0, 0};
  Eigen::Vector3d value() const { return {v[0], v[1], v[2]}; }
};

inline void AddVec3Option(CLI::App& app, const std::string& name, Vec3Arg* out, const std::string& help) {
  app.add_option_function<std::string>(
         name,
         [name, out](const std::string& s) {
           const auto v = ParseNumberList(s);
           if (!v || v->size() != 3) {
             throw CLI::ValidationError(name, "expected three comma-separated numbers, got '" + s + "'");
           }
           for (int i = 0; i < 3; ++i) out->v[i] = (*v)[i];
           out->set = true;
         },
         help)
      ->type_name("X,Y,Z");
}

// A yes/no option ("--x 1", "--x off"). CLI11 converts any integer to a bool
// (2 -> true, -1 -> false), so a mistyped value would silently pick a side;
// this accepts only 0/1, true/false, on/off (any case) and refuses the rest.
inline CLI::Option* AddSwitchOption(CLI::App& app, const std::string& name, bool* out, const std::string& help) {
  return app.add_option(name, *out, help)
      ->check(CLI::IsMember({"0", "1", "true", "false", "on", "off"}, CLI::ignore_case))
      ->type_name("0|1");
}

// An "on"/"off" option bound to a bool of an options struct. Its default is
// the struct's own value as the flag is added (shown as on or off), so a
// flag cannot disagree with the library's documented default; only "on" or
// "off" is accepted (AddSwitchOption takes 0/1 and true/false too).
inline CLI::Option* AddOnOffOption(CLI::App& app, const std::string& name, bool* out, const std::string& help) {
  return app
      .add_option_function<std::string>(
          name, [out](const std::string& s) { *out = s == "on"; }, help)
      ->check(CLI::IsMember({"on", "off"}))
      ->default_str(*out ? "on" : "off");
}

// The regional field B0 of a service: "--b0 BX,BY,BZ" (tesla, NED) or
// "--b0 estimate" (per sensor, from quiet stretches of the stream). There is
// no default: a service that is given neither refuses to start (a silent
// B0 = 0 made fixes kilometres off).
struct B0Arg {
  enum class Mode { kUnset, kGiven, kEstimate };
  Mode mode = Mode::kUnset;
  Eigen::Vector3d value = Eigen::Vector3d::Zero();  // T, when kGiven
};

inline void AddB0Option(CLI::App& app, B0Arg* out, const std::string& help) {
  app.add_option_function<std::string>(
         "--b0",
         [out](const std::string& s) {
           if (s == "estimate") {
             out->mode = B0Arg::Mode::kEstimate;
             return;
           }
           const auto v = ParseNumberList(s);
           if (!v || v->size() != 3) {
             throw CLI::ValidationError("--b0", "expected BX,BY,BZ in tesla or 'estimate', got '" + s + "'");
           }
           out->value = {(*v)[0], (*v)[1], (*v)[2]};
           out->mode = B0Arg::Mode::kGiven;
         },
         help)
      ->type_name("BX,BY,BZ|estimate");
}

// The given B0 (nullopt: estimate it). Throws InputError when --b0 was not given.
inline std::optional<Eigen::Vector3d> RequireB0(const B0Arg& arg) {
  if (arg.mode == B0Arg::Mode::kUnset) {
    throw InputError("the regional field is unknown: give --b0 BX,BY,BZ (tesla, NED) or --b0 estimate (per "
                     "sensor, from quiet stretches of the stream)");
  }
  if (arg.mode == B0Arg::Mode::kEstimate) return std::nullopt;
  return arg.value;
}

// Parses "X,Y,Z;X,Y,Z;..." (a list of points, e.g. sensor positions). Throws
// InputError naming the flag and the item that is not X,Y,Z.
inline std::vector<Eigen::Vector3d> ParseVec3List(const std::string& flag, const std::string& text) {
  std::vector<Eigen::Vector3d> out;
  std::size_t pos = 0;
  while (true) {
    const std::size_t semi = text.find(';', pos);
    const std::string item = text.substr(pos, semi == std::string::npos ? std::string::npos : semi - pos);
    const auto v = ParseNumberList(item);
    if (!v || v->size() != 3) throw InputError(flag + ": '" + item + "' is not X,Y,Z");
    out.emplace_back((*v)[0], (*v)[1], (*v)[2]);
    if (semi == std::string::npos) return out;
    pos = semi + 1;
  }
}

// The --config reader of the services: CLI11's TOML/INI reader, strict. Every
// key must be a long flag name of the program, at the top level. CLI11 2.1
// ignores an unknown key and reads "key" under "[section]" as "section.key",
// which it ignores too (with b0 under [magnav] the inverter ran with B0 = 0
// and published fixes 1.4 km off). Here either is an error naming the file,
// the line and the key; a UTF-8 byte-order mark at the start is skipped.
class StrictConfig : public CLI::ConfigTOML {
 public:
  explicit StrictConfig(const CLI::App* app) : app_(app) {}

  std::vector<CLI::ConfigItem> from_config(std::istream& input) const override {
    std::string text((std::istreambuf_iterator<char>(input)), std::istreambuf_iterator<char>());
    if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);
    std::istringstream in(text);
    std::vector<CLI::ConfigItem> items = CLI::ConfigTOML::from_config(in);
    // Keys in file order; a section's open/close markers ("++", "--") after
    // its keys, so that a key under a section is what is named.
    std::vector<const CLI::ConfigItem*> order;
    for (const CLI::ConfigItem& item : items) {
      if (item.name != "++" && item.name != "--") order.push_back(&item);
    }
    for (const CLI::ConfigItem& item : items) {
      if (item.name == "++" || item.name == "--") order.push_back(&item);
    }
    for (const CLI::ConfigItem* item : order) {
      if (!item->parents.empty()) {
        std::string section;
        for (const auto& p : item->parents) section += (section.empty() ? "" : ".") + p;
        const std::string key = item->name == "++" || item->name == "--" ? "" : item->name;
        throw CLI::ConfigError(Where(text, section, key) + "section [" + section + "] is not supported" +
                               (key.empty() ? "" : " (key '" + key + "')") +
                               ": options go at the top of the file, one per line as NAME = VALUE with NAME a "
                               "long flag name (see --help)");
      }
      if (Known(item->name)) continue;
      throw CLI::ConfigError(Where(text, "", item->name) + "unknown option '" + item->name +
                             "': keys are the long flag names without '--' (see --help)");
    }
    return items;
  }

 private:
  bool Known(const std::string& name) const {
    return app_->get_option_no_throw("--" + name) != nullptr ||
           (name.size() == 1 && app_->get_option_no_throw("-" + name) != nullptr);
  }

  // "FILE:LINE: " of the first line that sets `key` in `section` ("": the
  // top level; key "": the section's own line).
  std::string Where(const std::string& text, const std::string& section, const std::string& key) const {
    std::string file = "config file";
    if (const CLI::Option* opt = app_->get_config_ptr(); opt != nullptr && !opt->results().empty()) {
      file = opt->results().back();
    }
    std::istringstream lines(text);
    std::string line, current;
    for (int n = 1; std::getline(lines, line); ++n) {
      CLI::detail::trim(line);
      if (line.size() >= 2 && line.front() == '[' && line.back() == ']') {
        current = line.substr(1, line.size() - 2);
        if (current.size() >= 2 && current.front() == '[' && current.back() == ']') {
          current = current.substr(1, current.size() - 2);
        }
        CLI::detail::trim(current);
        if (key.empty() && current == section) return file + ":" + std::to_string(n) + ": ";
        continue;
      }
      if (line.empty() || line.front() == '#' || line.front() == ';' || current != section) continue;
      std::string name = line.substr(0, line.find('='));
      CLI::detail::trim(name);
      CLI::detail::remove_quotes(name);
      if (name == key) return file + ":" + std::to_string(n) + ": ";
    }
    return file + ": ";
  }

  const CLI::App* app_;
};

// --config FILE (TOML/INI, keys = long flag names; unknown keys and sections
// are errors, see StrictConfig) and defaults shown in --help. Call before
// adding the options.
// --limits FILE: the site's limits of the door (core/limits.h LoadSiteLimits),
// read when the command line is processed, before any input; each one in
// force is logged. A bad file is a bad flag (exit 2).
inline void AddLimitsOption(CLI::App& app) {
  app.add_option_function<std::string>(
         "--limits",
         [](const std::string& path) {
           try {
             LoadSiteLimits(path);
           } catch (const InputError& e) {
             throw CLI::ValidationError("--limits", e.what());
           }
           for (const std::string& l : DescribeSiteLimits()) spdlog::info("limit {}", l);
         },
         "site limits of the input checks: a TOML/INI file of 'key = value' lines (position_m, B_T, T_Tpm, "
         "map_value_nT, latitude_deg, longitude_deg, map_cells, time_s, time_step_s, seq_step; e.g. T_Tpm = 1e-5 for a "
         "SQUID array); limits not named keep their defaults (docs/RELIABILITY.md \"Limits\")")
      ->type_name("FILE");
}

inline void ConfigureServiceApp(CLI::App& app) {
  AddLimitsOption(app);
  app.set_config("--config", "", "read options from a TOML/INI file (keys = long flag names)");
  app.config_formatter(std::make_shared<StrictConfig>(&app));
  app.allow_config_extras(CLI::config_extras_mode::error);
  app.option_defaults()->always_capture_default();
}

// Parses a command line. On a bad flag prints CLI11's message and returns 2
// (magnav's exit codes: 0 ok, 2 bad input, 3 internal, 4 DDS); --help prints
// and returns 0. Returns -1 when the program should go on.
inline int ParseCommandLine(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  return -1;
}

}  // namespace magnav::cli
