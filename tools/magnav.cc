// `magnav`: offline runs of every algorithm from files, simulation, and (with
// DDS) replay/record. Thin: each subcommand is in cmd_*.cc.
#include <cstdio>
#include <exception>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"

namespace magnav::tools {

void AddVec3Option(CLI::App& app, const std::string& name, Vec3Arg* out, const std::string& help) {
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


}  // namespace magnav::tools

int main(int argc, char** argv) {
  CLI::App app{"magnav: find and follow magnetic objects with gradiometer networks"};
  app.require_subcommand(1);
  magnav::tools::AddSimulateCommand(app);
#ifdef MAGNAV_WITH_DDS
  magnav::tools::AddReplayCommand(app);
  magnav::tools::AddRecordCommand(app);
#endif
  magnav::tools::AddInvertCommand(app);
  magnav::tools::AddEvaluateCommand(app);
  magnav::tools::AddTrackCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;  // usage errors are bad input too
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
