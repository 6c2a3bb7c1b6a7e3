// Subcommands of the `magnav` program. Each lives in its own cmd_*.cc file and
// registers itself on the CLI11 app; errors are reported as InputError and
// turned into a message and exit code 2 by main.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "magnav/cli/options.h"

#ifdef MAGNAV_WITH_DDS
#include "magnav/cli/dds_options.h"
#endif

namespace magnav::tools {

using cli::AddVec3Option;
using cli::Vec3Arg;

void AddSimulateCommand(CLI::App& app);
void AddEvaluateCommand(CLI::App& app);
// `magnav invert` (cmd_invert.cc).
void AddInvertCommand(CLI::App& app);
// `magnav track`: batch or sliding-window tracking of every dipole (vessel).
void AddTrackCommand(CLI::App& app);
// `magnav localize`: sensor positions from a friendly vessel's pass.
void AddLocalizeCommand(CLI::App& app);
// `magnav match`: an INS path matched against a geomagnetic map.
void AddMatchCommand(CLI::App& app);
// `magnav plot`: SVG/PNG pictures of result files (gnuplot).
void AddPlotCommand(CLI::App& app);

#ifdef MAGNAV_WITH_DDS
using cli::AddDdsOptions;
using cli::DdsArgs;
void AddReplayCommand(CLI::App& app);
void AddRecordCommand(CLI::App& app);
// `magnav info` and `magnav export` (cmd_info.cc): recordings, MCAP or CSV.
void AddInfoCommand(CLI::App& app);
void AddExportCommand(CLI::App& app);
#endif

}  // namespace magnav::tools
