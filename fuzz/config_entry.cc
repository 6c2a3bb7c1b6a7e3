// FuzzConfig: a service's --config file through StrictConfig (entries.h). The
// options are magnav-matcher's (its own, the particle filter's, the DDS
// flags'), plus the B0 and X,Y,Z options of the inverter and the localiser.
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "entries.h"
#include "magnav/cli/options.h"
#include "magnav/cli/particle_filter_options.h"
#include "magnav/core/error.h"
#include "magnav/mapmatch/particle_filter.h"
#include "mem_file.h"

namespace magnav::fuzz {

void FuzzConfig(const std::uint8_t* data, std::size_t size) {
  static MemFile file;
  const std::string& path = file.Write(AsText(data, size));

  CLI::App app{"fuzz"};
  cli::ConfigureServiceApp(app);
  std::string map, column, method = "afpf", sensors, profiles, participant;
  double reference_field_nT = 0.0, fix_every_m = 0.0, stats_period_s = 10.0;
  std::uint32_t vehicle_id = 0, sensor_id = 0;
  int domain_id = -1;
  std::vector<double> weights;
  std::vector<std::string> topics;
  bool verbose = false;
  mapmatch::ParticleFilterOptions pf;
  cli::B0Arg b0;
  cli::Vec3Arg moment;
  app.add_option("--map", map, "map");
  app.add_option("--value-column", column, "column");
  app.add_option("--reference-field", reference_field_nT, "nT");
  app.add_option("--method", method, "pf or afpf")->check(CLI::IsMember({"pf", "afpf"}));
  app.add_option("--fix-every", fix_every_m, "m");
  app.add_option("--vehicle-id", vehicle_id, "id");
  app.add_option("--sensor-id", sensor_id, "id");
  cli::AddParticleFilterOptions(app, &pf);
  double max_correction_deg = 0.0;
  cli::AddOutlierSigmasOption(app, &pf.outlier_sigmas);
  cli::AddMaxCorrectionOption(app, &max_correction_deg);
  app.add_option("--stats-period", stats_period_s, "s");
  app.add_option("--domain", domain_id, "domain")->check(CLI::Range(0, 232));
  app.add_option("--dds-profiles", profiles, "file");
  app.add_option("--dds-participant", participant, "profile");
  cli::AddB0Option(app, &b0, "T");
  cli::AddVec3Option(app, "--moment", &moment, "A m^2");
  app.add_option("--sensors", sensors, "X,Y,Z;X,Y,Z");
  app.add_option("--weights", weights, "list");
  app.add_option("--topic", topics, "list");
  app.add_flag("--verbose", verbose, "flag");

  const char* argv[] = {"fuzz", "--config", path.c_str()};
  try {
    app.parse(3, argv);
  } catch (const CLI::ParseError&) {
    return;  // ParseCommandLine: message, exit code 2
  }
  try {
    (void)cli::RequireB0(b0);
    if (!sensors.empty()) (void)cli::ParseVec3List("--sensors", sensors);
  } catch (const InputError&) {
  }
}

}  // namespace magnav::fuzz
