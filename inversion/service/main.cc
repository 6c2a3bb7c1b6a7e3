// magnav-inverter: subscribes magnav/gradiometer, publishes a magnav/dipole_fix
// for every sample (rejected ones with the gate's reason). Options from flags
// or a TOML/INI file (--config). Stops cleanly on SIGINT/SIGTERM.
#include <cstdio>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "inverter_node.h"
#include "magnav/cli/options.h"
#include "magnav/core/error.h"
#include "magnav/cli/dds_options.h"
#include "magnav/dds/service.h"
#include "magnav/dds/regional_field_source.h"
#include "magnav/dds/shutdown.h"

int main(int argc, char** argv) {
  using namespace magnav;
  CLI::App app{"magnav-inverter: dipole fixes from gradiometer samples (magnav/gradiometer -> magnav/dipole_fix)"};
  magnav::cli::ConfigureServiceApp(app);
  inversion::InverterOptions opt;
  inversion::MonteCarloTrackerOptions mc;
  std::string method = "ted-egt";
  magnav::cli::B0Arg b0;
  magnav::cli::Vec3Arg moment_body;
  double stats_period_s = 10.0;
  magnav::cli::DdsArgs dds_args;
  app.add_option("--method", method, "ted, ted-egt, egt or mc")->check(CLI::IsMember({"ted", "ted-egt", "egt", "mc"}));
  magnav::cli::AddB0Option(app, &b0,
                           "regional field: BX,BY,BZ in T (NED), subtracted before TED, or 'estimate': per sensor from quiet stretches of "
                           "the stream (fixes are rejected with reason no_b0 until then). Required");
  magnav::cli::AddVec3Option(app, "--moment-body", &moment_body, "known body moment in A*m^2 (mc only)");
  app.add_option("--min-snr", opt.gates.min_snr, "weak-signal gate: reject when |T|_F < min_snr * sigma_T")
      ->capture_default_str();
  app.add_option("--max-cond-ted", opt.gates.max_cond_ted, "condition-number gate for TED");
  app.add_option("--max-cond-ted-egt", opt.gates.max_cond_ted_egt, "condition-number gate for TED+EGT");
  app.add_option("--max-relative-sigma", opt.gates.max_relative_sigma,
                 "uncertainty gate: reject a fix whose predicted 3-D 1-sigma position error exceeds this fraction of "
                 "its range (0 = off, the default; 0.015 was the default before 0.4 m absolute)")
      ->capture_default_str();
  app.add_option("--max-position-sigma", opt.gates.max_position_sigma_3d_m,
                 "uncertainty gate: reject a fix whose predicted 3-D 1-sigma position error exceeds this, m (0 = off; "
                 "0.05 for the paper's SQUID per-fix accuracy)")
      ->capture_default_str();
  app.add_option("--max-speed", opt.gates.max_speed_mps, "speed gate: largest feasible target speed, m/s");
  app.add_option("--sigma-b", opt.sigma_B_fallback, "B noise, T, for samples that carry none");
  app.add_option("--sigma-t", opt.sigma_T_fallback, "tensor noise, T/m, for samples that carry none");
  app.add_option("--particles", mc.filter.num_particles, "particles per sensor (mc)");
  app.add_option("--seed", mc.filter.seed, "random seed (mc)");
  app.add_option("--stats-period", stats_period_s, "log throughput every N seconds (0 = never)");
  magnav::cli::AddDdsOptions(app, &dds_args);
  // Gate flags: for --method mc they override the initialising inverter's
  // gates only when given (its defaults differ from the single-sample ones).
  const std::vector<std::pair<std::string, std::pair<double*, double*>>> gate_flags = {
      {"--min-snr", {&opt.gates.min_snr, &mc.init_inverter.gates.min_snr}},
      {"--max-cond-ted", {&opt.gates.max_cond_ted, &mc.init_inverter.gates.max_cond_ted}},
      {"--max-cond-ted-egt", {&opt.gates.max_cond_ted_egt, &mc.init_inverter.gates.max_cond_ted_egt}},
      {"--max-speed", {&opt.gates.max_speed_mps, &mc.init_inverter.gates.max_speed_mps}},
      {"--max-relative-sigma", {&opt.gates.max_relative_sigma, &mc.init_inverter.gates.max_relative_sigma}},
      {"--max-position-sigma", {&opt.gates.max_position_sigma_3d_m, &mc.init_inverter.gates.max_position_sigma_3d_m}},
  };
  if (const int code = magnav::cli::ParseCommandLine(app, argc, argv); code >= 0) return code;

  return magnav::dds::RunService("magnav-inverter", [&] {
    std::unique_ptr<magnav::dds::RegionalFieldSource> b0_source =
        magnav::dds::MakeRegionalFieldSource("magnav-inverter", magnav::cli::RequireB0(b0), opt.sigma_B_fallback, opt.sigma_T_fallback);
    magnav::dds::InstallShutdownHandlers();
    magnav::dds::Node node(dds_args.ToNodeOptions("magnav-inverter"));
    std::unique_ptr<inversion::InverterNode> inverter;
    if (method == "mc") {
      if (!moment_body.set) throw InputError("--method mc needs --moment-body");
      mc.filter.moment_body_Am2 = moment_body.value();
      mc.filter.sigma_T_fallback = opt.sigma_T_fallback;
      // The initialising fixes keep the Monte-Carlo defaults (their own,
      // looser uncertainty gate: see MonteCarloTrackerOptions); only the
      // noise fallbacks and the flags given for the gates are carried over.
      mc.init_inverter.sigma_B_fallback = opt.sigma_B_fallback;
      mc.init_inverter.sigma_T_fallback = opt.sigma_T_fallback;
      for (const auto& [flag, value] : gate_flags) {
        if (app.count(flag) > 0) *value.second = *value.first;
      }
      inverter = std::make_unique<inversion::InverterNode>(node, mc, std::move(b0_source));
    } else {
      inversion::ParseMethod(method, &opt.method);
      inverter = std::make_unique<inversion::InverterNode>(node, opt, std::move(b0_source));
    }
    spdlog::info("magnav-inverter: method {} on domain {}; {}", method, node.domain_id(), inverter->b0().Describe());
    std::uint64_t last = 0;
    magnav::dds::RunUntilShutdown(stats_period_s, [&] {
      const std::uint64_t n = inverter->processed();
      spdlog::info("magnav-inverter: {} samples ({:.0f}/s), {} fixes, {} lost, {} bad samples, {} before B0, "
                   "{} repeated, {} missing (sequence gaps), {} wild stamps or seqs, {} handler errors",
                   n, (n - last) / stats_period_s, inverter->published(), inverter->input_stats().lost.load(),
                   inverter->bad_samples(), inverter->b0().waiting(), inverter->repeated(), inverter->missing(),
                   inverter->wild(), inverter->input_stats().callback_errors.load());
      last = n;
    });
    // Every fix already published reaches the readers before the writer goes
    // (bounded: a dead reader is forgotten after its lease).
    if (!inverter->WaitForAcknowledgments(std::chrono::seconds(5))) {
      spdlog::warn("magnav-inverter: a reader did not acknowledge every fix within 5 s of the stop");
    }
    spdlog::info("magnav-inverter: stopping after {} samples ({} repeated, {} missing)", inverter->processed(),
                 inverter->repeated(), inverter->missing());
  });
}
