// `magnav`: offline runs of every algorithm from files, simulation, and (with
// DDS) replay/record. Thin: each subcommand is in cmd_*.cc.
#include <cstdio>
#include <exception>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"

int main(int argc, char** argv) {
  // Logs go to stderr: stdout may be data (`magnav record --output -`).
  spdlog::set_default_logger(spdlog::stderr_color_mt("magnav"));
  CLI::App app{"magnav: find and follow magnetic objects with gradiometer networks"};
  app.require_subcommand(1);
  // --limits is the program's and may follow the subcommand (fallthrough).
  magnav::cli::AddLimitsOption(app);
  app.fallthrough();
  magnav::tools::AddSimulateCommand(app);
#ifdef MAGNAV_WITH_DDS
  magnav::tools::AddReplayCommand(app);
  magnav::tools::AddRecordCommand(app);
  magnav::tools::AddInfoCommand(app);
  magnav::tools::AddExportCommand(app);
#endif
  magnav::tools::AddInvertCommand(app);
  magnav::tools::AddEvaluateCommand(app);
  magnav::tools::AddTrackCommand(app);
  magnav::tools::AddLocalizeCommand(app);
  magnav::tools::AddMatchCommand(app);
  magnav::tools::AddPlotCommand(app);
  try {
    if (const int code = magnav::cli::ParseCommandLine(app, argc, argv); code >= 0) return code;
  } catch (const magnav::InputError& e) {
    std::fprintf(stderr, "magnav: error: %s\n", e.what());
    return 2;
#ifdef MAGNAV_WITH_DDS
  } catch (const magnav::dds::DdsError& e) {
    std::fprintf(stderr, "magnav: DDS error: %s\n", e.what());
    return 4;
#endif
  } catch (const std::exception& e) {
    std::fprintf(stderr, "magnav: internal error: %s\n", e.what());
    return 3;
  }
  return 0;
}
