// magnav-tracker: subscribes magnav/gradiometer (and magnav/dipole_fix, for
// track initiation), publishes magnav/track (one TrackEstimate per confirmed
// track and epoch from the multi-vessel sliding-window tracker; key
// track_id), logs every track's start and end. Options from flags or a TOML/INI file
// (--config). Stops cleanly on SIGINT/SIGTERM.
#include <chrono>
#include <cstdio>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "magnav/cli/options.h"
#include "magnav/core/error.h"
#include "magnav/cli/dds_options.h"
#include "magnav/cli/merge_options.h"
#include "magnav/cli/tracker_options.h"
#include "magnav/dds/service.h"
#include "magnav/dds/shutdown.h"
#include "tracker_node.h"

int main(int argc, char** argv) {
  using namespace magnav;
  CLI::App app{"magnav-tracker: vessel tracks from gradiometer samples (magnav/gradiometer -> magnav/track)"};
  magnav::cli::ConfigureServiceApp(app);
  tracker::TrackerNodeOptions opt;
  magnav::cli::TrackerFlags flags;
  magnav::cli::B0Arg b0;
  double stats_period_s = 10.0;
  magnav::cli::DdsArgs dds_args;
  magnav::cli::AddB0Option(app, &b0,
                           "regional field: BX,BY,BZ in T (NED), or 'estimate': per sensor from quiet stretches of the stream (a "
                           "sensor's samples are not used until then; the track is very sensitive to a B0 error, see "
                           "tracker/README.md). Required");
  magnav::cli::AddTrackerOptions(app, &flags, "magnav-inverter's fixes from magnav/dipole_fix");
  app.add_option("--sigma-b", flags.options.track.default_sigma_B_T, "B noise, T, for samples that carry none")
      ->capture_default_str();
  app.add_option("--sigma-t", flags.options.track.default_sigma_T_Tpm, "tensor noise, T/m, for samples that carry none")
      ->capture_default_str();
  magnav::cli::AddMergeOptions(app, &opt.merge, "each sensor");
  app.add_option("--kept-ended-tracks", opt.kept_ended_tracks,
                 "ended tracks whose last estimates a late consumer still gets; older ones are unregistered "
                 "(memory: ~0.5 MB each)")
      ->check(CLI::Range(0, magnav::tracker::TrackerNodeOptions::kMaxKeptEndedTracks))
      ->capture_default_str();
  app.add_option("--stats-period", stats_period_s, "log throughput every N seconds (0 = never)");
  double checkpoint_period_s = 5.0;
  app.add_option("--state-dir", opt.state_dir,
                 "checkpoint the tracks' state to DIR/magnav-tracker.state (atomically) every --checkpoint-period "
                 "and at a clean stop, and resume from it at start (a checkpoint that is corrupt, of another version "
                 "or made for other options is refused, kept as .refused, and the tracker starts fresh)");
  app.add_option("--checkpoint-period", checkpoint_period_s, "with --state-dir: write a checkpoint every N seconds")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  magnav::cli::AddDdsOptions(app, &dds_args);
  if (const int code = magnav::cli::ParseCommandLine(app, argc, argv); code >= 0) return code;

  return magnav::dds::RunService("magnav-tracker", [&] {
    std::unique_ptr<magnav::dds::RegionalFieldSource> b0_source = magnav::dds::MakeRegionalFieldSource(
        "magnav-tracker", magnav::cli::RequireB0(b0), flags.options.track.default_sigma_B_T,
        flags.options.track.default_sigma_T_Tpm);
    opt.tracker = magnav::cli::ApplyTrackerFlags(flags);
    magnav::dds::InstallShutdownHandlers();
    magnav::dds::Node node(dds_args.ToNodeOptions("magnav-tracker"));
    tracker::TrackerNode tracker_node(node, opt, std::move(b0_source));
    spdlog::info("magnav-tracker: every vessel (multi-track), window {} s, initiation from {}, on domain {}; {}",
                 opt.tracker.track.window_s, flags.init_from, node.domain_id(), tracker_node.b0().Describe());
    using Clock = std::chrono::steady_clock;
    const auto period = [](double s) {
      return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
    };
    auto next_stats = Clock::now() + period(stats_period_s);
    auto next_checkpoint = Clock::now() + period(checkpoint_period_s);
    while (!magnav::dds::WaitForShutdown(std::chrono::milliseconds(50))) {
      tracker_node.Tick();
      if (!opt.state_dir.empty() && Clock::now() >= next_checkpoint) {
        tracker_node.Checkpoint();
        next_checkpoint += period(checkpoint_period_s);
      }
      if (stats_period_s <= 0 || Clock::now() < next_stats) continue;
      next_stats += period(stats_period_s);
      spdlog::info("magnav-tracker: {} samples in, {} estimates out, {} tracks ({} live), {} late, {} rejected, {} "
                   "bad samples, {} before B0, {} repeated, {} missing (sequence gaps), {} wild stamps or seqs; {} fixes "
                   "in, {} skipped; {} already in the checkpoint{}",
                   tracker_node.received(), tracker_node.published(), tracker_node.num_tracks(),
                   tracker_node.num_live_tracks(), tracker_node.dropped_late(), tracker_node.rejected(),
                   tracker_node.bad_samples(), tracker_node.b0().waiting(), tracker_node.repeated(), tracker_node.missing(),
                   tracker_node.wild(),
                   tracker_node.fixes_received(), tracker_node.fixes_rejected(), tracker_node.already_consumed(),
                   [&] {
                     const std::string far = tracker_node.far_source_report();
                     return far.empty() ? far : "; " + far;
                   }());
    }
    // The checkpoint of a clean stop is taken before the end-of-data flush
    // ends the live tracks: a restart goes on with them.
    const bool saved = !opt.state_dir.empty() && tracker_node.Checkpoint();
    tracker_node.Flush();
    tracker_node.WaitForAcknowledgments(std::chrono::seconds(5));
    spdlog::info("magnav-tracker: stopping after {} samples ({} repeated, {} missing, {} late, {} wild stamps or "
                 "seqs, {} already in the checkpoint), {} estimates ({} not published), {} tracks{}",
                 tracker_node.received(), tracker_node.repeated(), tracker_node.missing(), tracker_node.dropped_late(),
                 tracker_node.wild(), tracker_node.already_consumed(), tracker_node.published(), tracker_node.not_published(),
                 tracker_node.num_tracks(), saved ? "; checkpoint written to " + tracker_node.state_path() : "");
  });
}
