// magnav-tracker: subscribes magnav/gradiometer (and magnav/dipole_fix, for
// track initiation), publishes magnav/track (one TrackEstimate per epoch from
// the sliding-window tracker). Options from flags or a TOML/INI file
// (--config). Stops cleanly on SIGINT/SIGTERM.
#include <cstdio>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "magnav/cli/options.h"
#include "magnav/core/error.h"
#include "magnav/cli/dds_options.h"
#include "magnav/dds/service.h"
#include "magnav/dds/shutdown.h"
#include "tracker_node.h"

int main(int argc, char** argv) {
  using namespace magnav;
  CLI::App app{"magnav-tracker: vessel tracks from gradiometer samples (magnav/gradiometer -> magnav/track)"};
  magnav::cli::ConfigureServiceApp(app);
  tracker::TrackerNodeOptions opt;
  magnav::cli::B0Arg b0;
  std::string loss = tracker::LossTypeName(opt.tracker.measurement_loss);
  std::string init_from = tracker::InitSourceName(opt.tracker.init.source);
  double stats_period_s = 10.0;
  magnav::cli::DdsArgs dds_args;
  magnav::cli::AddB0Option(app, &b0,
                           "regional field: BX,BY,BZ in T (NED), or 'estimate': per sensor from quiet stretches of the stream (a "
                           "sensor's samples are not used until then; the track is very sensitive to a B0 error, see "
                           "tracker/README.md). Required");
  app.add_option("--window", opt.tracker.window_s, "sliding window length, s");
  app.add_option("--loss", loss, "robust loss on measurements: trivial, huber, cauchy")
      ->capture_default_str()
      ->check(CLI::IsMember({"trivial", "huber", "cauchy"}));
  app.add_option("--loss-scale", opt.tracker.measurement_loss_scale_sigma, "robust loss scale, sigmas");
  app.add_option("--sigma-b", opt.tracker.default_sigma_B_T, "B noise, T, for samples that carry none");
  app.add_option("--sigma-t", opt.tracker.default_sigma_T_Tpm, "tensor noise, T/m, for samples that carry none");
  app.add_option("--init-from", init_from,
                 "fixes that start a track: auto (magnav-inverter's from magnav/dipole_fix when they suffice, "
                 "else its own TED+EGT on the samples), dipole_fix (the inverter's only), samples (its own only)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "dipole_fix", "samples"}));
  app.add_option("--reorder-delay", opt.reorder_delay_s, "hold samples this long (sample time, s) to order streams");
  app.add_option("--track-id", opt.track_id, "track id published");
  app.add_option("--stats-period", stats_period_s, "log throughput every N seconds (0 = never)");
  magnav::cli::AddDdsOptions(app, &dds_args);
  if (const int code = magnav::cli::ParseCommandLine(app, argc, argv); code >= 0) return code;

  return magnav::dds::RunService("magnav-tracker", [&] {
    std::unique_ptr<magnav::dds::RegionalFieldSource> b0_source =
        magnav::dds::MakeRegionalFieldSource("magnav-tracker", magnav::cli::RequireB0(b0), opt.tracker.default_sigma_B_T, opt.tracker.default_sigma_T_Tpm);
    tracker::ParseLossType(loss, &opt.tracker.measurement_loss);
    tracker::ParseInitSource(init_from, &opt.tracker.init.source);
    magnav::dds::InstallShutdownHandlers();
    magnav::dds::Node node(dds_args.ToNodeOptions("magnav-tracker"));
    tracker::TrackerNode tracker_node(node, opt, std::move(b0_source));
    spdlog::info("magnav-tracker: window {} s, initiation from {}, on domain {}; {}", opt.tracker.window_s, init_from,
                 node.domain_id(), tracker_node.b0().Describe());
    magnav::dds::RunUntilShutdown(stats_period_s, [&] {
      spdlog::info("magnav-tracker: {} samples in, {} estimates out, {} late, {} rejected, {} bad samples, {} before "
                   "B0; {} fixes in, {} skipped",
                   tracker_node.received(), tracker_node.published(), tracker_node.dropped_late(),
                   tracker_node.rejected(), tracker_node.bad_samples(), tracker_node.b0().waiting(),
                   tracker_node.fixes_received(), tracker_node.fixes_rejected());
    });
    tracker_node.Flush();
    tracker_node.WaitForAcknowledgments(std::chrono::seconds(5));
    spdlog::info("magnav-tracker: stopping after {} samples, {} estimates", tracker_node.received(),
                 tracker_node.published());
  });
}
