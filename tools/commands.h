// Subcommands of the `magnav` program. Each lives in its own cmd_*.cc file and
// registers itself on the CLI11 app; errors are reported as InputError and
// turned into a message and exit code 2 by main.
#pragma once

#include <CLI/CLI.hpp>

namespace magnav::tools {

// Parses "a,b,c" (a CLI value) into three numbers; throws InputError naming the flag.
struct Vec3Arg {
  bool set = false;
  double v[3] = {0, 0, 0};
};
void AddVec3Option(CLI::App& app, const std::string& name, Vec3Arg* out, const std::string& help);

void AddSimulateCommand(CLI::App& app);
// `magnav track`: batch or sliding-window tracking of one dipole (vessel).
void AddTrackCommand(CLI::App& app);

}  // namespace magnav::tools
