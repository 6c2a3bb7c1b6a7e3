// magnav-matcher: sequential geomagnetic map matching. Subscribes
// magnav/vessel_nav (the vehicle's INS/DR, geodetic lat/lon) and
// magnav/magnetometer, runs the library's particle filter (pf) or adaptive
// fission particle filter (afpf) on a map and publishes magnav/map_fix every
// --fix-every metres travelled (the paper: once per km; 0 = every step).
// Stops cleanly on SIGINT/SIGTERM.
#include <chrono>
#include <cstdio>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "magnav/cli/dds_options.h"
#include "magnav/cli/options.h"
#include "magnav/cli/particle_filter_options.h"
#include "magnav/core/error.h"
#include "magnav/dds/service.h"
#include "magnav/dds/shutdown.h"
#include "magnav/mapmatch/geo_grid.h"
#include "matcher_node.h"

int main(int argc, char** argv) {
  using namespace magnav;
  CLI::App app{"magnav-matcher: sequential map matching (magnav/vessel_nav + magnav/magnetometer -> magnav/map_fix)"};
  magnav::cli::ConfigureServiceApp(app);
  mapmatch::MatcherNodeOptions opt;
  mapmatch::ParticleFilterOptions& f = opt.filter;
  std::string map, column, method = "afpf";
  double stats_period_s = 10.0;
  magnav::cli::DdsArgs dds_args;
  app.option_defaults()->always_capture_default();
  app.add_option("--map", map,
                 "map: CSV lat,lon (deg) and the value column (nT), a complete regular grid; NGDC text (*.xyz, *.txt); or a "
                 "GDAL raster (GeoTIFF, NetCDF)")
      ->required();
  app.add_option("--value-column", column, "the map column to match, e.g. anomaly_nT")->required();
  app.add_option("--reference-field", opt.reference_field_nT,
                 "the map's reference field, nT: anomaly = |B| - this (required; docs/PROTOCOL.md)")
      ->required();
  app.add_option("--method", method, "pf or afpf")->check(CLI::IsMember({"pf", "afpf"}));
  app.add_option("--fix-every", opt.fix_every_m, "publish a MapFix every N metres travelled (0 = every step)");
  app.add_option("--vehicle-id", opt.vehicle_id, "VesselNav vessel_id followed (and MapFix vehicle_id)");
  app.add_option("--sensor-id", opt.sensor_id, "MagnetometerSample sensor_id used");
  magnav::cli::AddParticleFilterOptions(app, &f);
  magnav::cli::AddOutlierSigmasOption(app, &f.outlier_sigmas);
  magnav::cli::AddMaxCorrectionOption(app, &opt.max_correction_deg);
  app.add_option("--min-observability", opt.observability.min_information_ratio,
                 "a fix whose map information along the least observed direction is below this fraction of the INS "
                 "prior's there (the filter's prior square and drift, or --ins-start-sd/--ins-drift-sd) is published "
                 "with status PARTLY_OBSERVABLE and its covariance raised along that direction to what the map and "
                 "the prior can know (as `magnav match` at a path's end); lost and off_map take precedence; 0 = never");
  app.add_option("--ins-start-sd", opt.observability.prior.start_sd_deg,
                 "the prior on the INS error at the first step, 1 sigma per axis (deg); both 0: the filter's own "
                 "(--prior-half-width / sqrt(3), --drift-sigma)");
  app.add_option("--ins-drift-sd", opt.observability.prior.drift_sd_deg,
                 "the INS error's random walk per step, 1 sigma per axis (deg)");
  app.add_option("--stats-period", stats_period_s, "log throughput every N seconds (0 = never)");
  magnav::cli::AddDdsOptions(app, &dds_args);
  if (const int code = magnav::cli::ParseCommandLine(app, argc, argv); code >= 0) return code;

  return magnav::dds::RunService("magnav-matcher", [&] {
    opt.kind = method == "pf" ? mapmatch::ParticleFilterKind::kPf : mapmatch::ParticleFilterKind::kAfpf;
    const mapmatch::GeoGrid grid = mapmatch::ReadGeoGridFile(map, {column});  // CSV, NGDC text or a GDAL raster
    magnav::dds::InstallShutdownHandlers();
    magnav::dds::Node node(dds_args.ToNodeOptions("magnav-matcher"));
    mapmatch::MatcherNode matcher(node, grid, 0, opt);
    spdlog::info("magnav-matcher: {} on {} ({}), a fix every {} m, on domain {}", method, map, column,
                 opt.fix_every_m, node.domain_id());
    using Clock = std::chrono::steady_clock;
    const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(stats_period_s));
    auto next_stats = Clock::now() + period;
    auto log = [&](const char* what) {
      const mapmatch::FilterCounters c = matcher.filter_counters();
      spdlog::info("magnav-matcher: {} {} vessel_nav + {} magnetometer in, {} steps ({} updates, {} bad readings, "
                   "{} all off the map, {} INS jumps, {} lost steps; status {}{}), {} skipped, {} ignored (another vehicle, sensor "
                   "or source), {} repeated, {} missing (sequence gaps), {} wild stamps or seqs, {} waiting, {} fixes out",
                   what, matcher.navs_received(), matcher.samples_received(), matcher.steps(), c.updates,
                   c.bad_measurements, c.all_off_map, c.ins_jumps, c.lost_steps,
                   mapmatch::RunVerdictName(matcher.run_verdict()),
                   matcher.run_reason().empty() ? std::string() : ": " + matcher.run_reason(), matcher.skipped(), matcher.ignored(),
                   matcher.repeated(), matcher.missing(), matcher.wild(), matcher.buffered(), matcher.published());
    };
    while (!magnav::dds::WaitForShutdown(std::chrono::milliseconds(50))) {
      if (stats_period_s > 0 && Clock::now() >= next_stats) {
        log("so far");
        next_stats += period;
      }
    }
    matcher.WaitForAcknowledgments(std::chrono::seconds(5));
    log("stopping after");
  });
}
