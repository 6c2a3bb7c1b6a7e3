// magnav-localizer: where the deployed sensors are, from a friendly vessel's
// passes. Subscribes magnav/magnetometer and magnav/vessel_nav, publishes a
// magnav/sensor_position (position, covariance, Cramér–Rao bound) for every
// sensor every --publish-period seconds and at the end. Options from flags or
// a TOML/INI file (--config). Stops cleanly on SIGINT/SIGTERM.
#include <chrono>
#include <cstdio>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "localizer_node.h"
#include "magnav/cli/options.h"
#include "magnav/core/error.h"
#include "magnav/cli/dds_options.h"
#include "magnav/cli/merge_options.h"
#include "magnav/dds/service.h"
#include "magnav/dds/shutdown.h"
#include "magnav/localizer/input.h"

int main(int argc, char** argv) {
  using namespace magnav;
  CLI::App app{"magnav-localizer: sensor positions from a friendly vessel's pass "
               "(magnav/magnetometer + magnav/vessel_nav -> magnav/sensor_position)"};
  magnav::cli::ConfigureServiceApp(app);
  localizer::LocalizerNodeOptions opt;
  std::string deployment;
  magnav::cli::Vec3Arg moment;
  double sigma_B_T = 0.0, vessel_z_m = std::nan("");
  double publish_period_s = 1.0, stats_period_s = 10.0, checkpoint_period_s = 5.0;
  magnav::cli::DdsArgs dds_args;
  app.add_option("--deployment", deployment, "deployment guesses: sensor_id,x,y,z,sigma_xy (m)")->required();
  magnav::cli::AddVec3Option(app, "--moment-body", &moment, "vessel body moment, A*m^2 (required)");
  app.add_option("--vessel-z", vessel_z_m, "vessel depth (NED z), m (required)")->required();
  app.add_option("--sigma-b", sigma_B_T, "magnetometer noise per axis, T (required)")->required();
  StreamMergeOptions merge = opt.stream.Merge();
  merge.merge = StreamMerge::kWatermark;
  magnav::cli::AddMergeOptions(app, &merge, "each sensor, the GNSS");
  std::string method = "ekf-bounded";
  app.add_option("--method", method,
                 "ekf-bounded (memory and cost independent of uptime; = magnav localize --method ekf-bounded) or "
                 "ekf (the bound over every sample ever received, for comparison only: it grows with uptime)")
      ->check(CLI::IsMember({"ekf-bounded", "ekf"}))
      ->capture_default_str();
  app.add_option("--bound-lag", opt.stream.bound.lag_s,
                 "ekf-bounded: epochs older than this (s) are folded into the bound at the estimate of that time")
      ->capture_default_str();
  app.add_option("--bound-window-items", opt.stream.bound.max_window_items,
                 "ekf-bounded: at most this many samples and fixes in the bound's window")
      ->capture_default_str();
  app.add_option("--vessel-id", opt.vessel_id,
                 "the friendly vessel's vessel_id: only its GNSS VesselNav fixes are used")
      ->capture_default_str();
  app.add_option("--q-position", opt.localizer.process.position_m_per_sqrt_s, "position random walk, m/sqrt(s)");
  app.add_option("--q-speed", opt.localizer.process.speed_mps_per_sqrt_s, "speed random walk, m/s/sqrt(s)");
  app.add_option("--q-heading", opt.localizer.process.heading_rad_per_sqrt_s, "heading random walk, rad/sqrt(s)");
  app.add_option("--q-turn-rate", opt.localizer.process.turn_rate_radps_per_sqrt_s,
                 "turn-rate random walk, rad/s/sqrt(s)");
  app.add_option("--publish-period", publish_period_s, "publish every sensor's estimate every N seconds (> 0)")
      ->check(CLI::PositiveNumber);
  app.add_option("--state-dir", opt.state_dir,
                 "checkpoint the estimator's state to DIR/magnav-localizer.state (atomically) and resume from it at "
                 "start if it was made for this configuration (docs/RELIABILITY.md)");
  app.add_option("--checkpoint-period", checkpoint_period_s, "with --state-dir: write a checkpoint every N seconds")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--stats-period", stats_period_s, "log throughput every N seconds (0 = never)");
  magnav::cli::AddDdsOptions(app, &dds_args);
  if (const int code = magnav::cli::ParseCommandLine(app, argc, argv); code >= 0) return code;

  return magnav::dds::RunService("magnav-localizer", [&] {
    if (!moment.set) throw InputError("--moment-body MX,MY,MZ is required (A*m^2, body frame): no default moment");
    opt.vessel = {moment.value(), vessel_z_m};
    opt.stream.merge = merge.merge;
    opt.stream.idle_timeout_s = merge.idle_timeout_s;
    opt.stream.reorder_delay_s = merge.reorder_delay_s;
    opt.localizer.sigma_B_T = sigma_B_T;
    opt.stream.bounded = method == "ekf-bounded";
    opt.sensors = localizer::ReadDeploymentFile(deployment);
    magnav::dds::InstallShutdownHandlers();
    magnav::dds::Node node(dds_args.ToNodeOptions("magnav-localizer"));
    localizer::LocalizerNode loc(node, opt);
    spdlog::info("magnav-localizer: {} sensors from {}, on domain {}", opt.sensors.size(), deployment,
                 node.domain_id());
    using Clock = std::chrono::steady_clock;
    const auto period = [](double s) { return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s)); };
    auto next_publish = Clock::now() + period(publish_period_s);
    auto next_stats = Clock::now() + period(stats_period_s);
    auto next_checkpoint = Clock::now() + period(checkpoint_period_s);
    while (!magnav::dds::WaitForShutdown(std::chrono::milliseconds(50))) {
      loc.Tick();
      if (Clock::now() >= next_publish) {
        loc.Publish();
        next_publish += period(publish_period_s);
      }
      if (!opt.state_dir.empty() && Clock::now() >= next_checkpoint) {
        loc.Checkpoint();
        next_checkpoint += period(checkpoint_period_s);
      }
      if (stats_period_s > 0 && Clock::now() >= next_stats) {
        spdlog::info("magnav-localizer: {} magnetometer + {} vessel_nav samples in, {} used, {} skipped, {} "
                     "repeated, {} missing (sequence gaps), {} wild stamps or seqs, {} outliers refused by the EKF's gate, "
                     "{} vessel_nav of other vessels or sources ignored, {} already in the checkpoint, {} estimates out",
                     loc.samples_received(), loc.fixes_received(), loc.consumed(), loc.skipped(), loc.repeated(),
                     loc.missing(), loc.wild(), loc.outliers(), loc.ignored(), loc.already_consumed(),
                     loc.published());
        next_stats += period(stats_period_s);
      }
    }
    loc.Flush();
    const bool saved = loc.Checkpoint();
    loc.WaitForAcknowledgments(std::chrono::seconds(5));
    spdlog::info("magnav-localizer: stopping after {} samples used, {} skipped, {} repeated, {} missing, {} "
                 "estimates, {} already in the checkpoint{}",
                 loc.consumed(), loc.skipped(), loc.repeated(), loc.missing(), loc.published(), loc.already_consumed(),
                 saved ? "; checkpoint written to " + loc.state_path() : "");
  });
}
