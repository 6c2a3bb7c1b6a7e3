// `magnav localize`: where the deployed sensors really are, from a friendly
// vessel's pass (known body moment, GNSS): EKF-SLAM or batch smoother, with
// each sensor's 1-σ and its Cramér–Rao bound (localizer/).
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/localizer/batch.h"
#include "magnav/localizer/ekf.h"
#include "magnav/localizer/input.h"

namespace magnav::tools {

namespace {

struct LocalizeArgs {
  std::string measurements, deployment, gnss, output, method;
  Vec3Arg moment;
  std::string vessel_start;
  double sigma_B_T = 0.0;  // 0: from the file
  std::string loss = LossTypeName(localizer::LocalizerOptions{}.magnetometer_loss);
  std::string gnss_loss = LossTypeName(localizer::LocalizerOptions{}.gnss_loss);
  localizer::LocalizerOptions options;
  localizer::IncrementalCrlbOptions bound;
  bool check_batch = true;
};

std::string Sqrt(double variance) { return FormatNumber(std::sqrt(std::max(variance, 0.0))); }

void RunLocalize(LocalizeArgs a) {
  RefuseOutputOverInput(a.output, {a.measurements, a.deployment, a.gnss});
  const localizer::PassFile f =
      localizer::ReadPassFiles(a.measurements, a.deployment, a.gnss,
                               a.moment.set ? std::optional<Eigen::Vector3d>(a.moment.value()) : std::nullopt);
  if (a.sigma_B_T > 0.0) {
    a.options.sigma_B_T = a.sigma_B_T;
  } else if (f.sigma_B_T) {
    a.options.sigma_B_T = *f.sigma_B_T;
  } else {
    throw InputError(a.measurements + ": no magnetometer noise level: give --sigma-b S or a '# sigma_B_T: S' line (T)");
  }
  if (!ParseLossType(a.loss, &a.options.magnetometer_loss)) {
    throw InputError("--loss: expected huber, cauchy or trivial, got '" + a.loss + "'");
  }
  if (!ParseLossType(a.gnss_loss, &a.options.gnss_loss)) {
    throw InputError("--gnss-loss: expected huber, cauchy or trivial, got '" + a.gnss_loss + "'");
  }
  if (!a.vessel_start.empty()) {
    const auto v = ParseNumberList(a.vessel_start);
    if (!v || v->size() != 4) {
      throw InputError("--vessel-start: expected X,Y,SPEED,HEADING (m, m, m/s, rad), got '" + a.vessel_start + "'");
    }
    localizer::VesselVector x0;
    x0 << (*v)[0], (*v)[1], (*v)[2], (*v)[3], 0.0;
    a.options.vessel_start = x0;
  }
  std::string why;
  if (!a.options.IsValid(&why)) throw InputError("options: " + why);
  localizer::Localization out;
  if (!a.bound.IsValid(&why)) throw InputError("options: " + why);
  if (a.method == "ekf") {
    out = localizer::RunEkf(f.pass, a.options);
  } else if (a.method == "ekf-bounded") {
    out = localizer::RunEkfBounded(f.pass, a.options, a.bound);
  } else if (a.method == "batch") {
    out = localizer::SolveBatch(f.pass, a.options);
  } else {
    throw InputError("--method: expected ekf, ekf-bounded or batch, got '" + a.method + "'");
  }
  if (a.method != "batch" && a.check_batch && out.summary.converged) {
    // The smoother over the same pass (started from the EKF's trajectory for
    // ekf; ekf-bounded keeps none, so the batch runs its own EKF first).
    const localizer::Localization smoother =
        localizer::SolveBatch(f.pass, a.options, a.method == "ekf" ? &out : nullptr);
    localizer::CheckAgainstSmoother(smoother, a.options.gate_probability, &out);
  }
  double known = 0.0;
  for (const auto& e : out.sensors) known += e.crlb_known_trajectory_m2.trace() / static_cast<double>(out.sensors.size());
  // Never a non-finite number written as a result (exit 3, nothing written).
  for (const auto& e : out.sensors) {
    if (!e.p_SinW_m.allFinite() || !e.cov_xy_m2.allFinite() || !e.crlb_joint_m2.allFinite()) {
      throw std::runtime_error("localize: the estimate of sensor " + std::to_string(e.sensor_id) +
                               " is not finite (x " + FormatNumber(e.p_SinW_m.x()) + ", y " +
                               FormatNumber(e.p_SinW_m.y()) + "; " + out.summary.BriefReport() + "); nothing written");
    }
  }
  if (!std::isfinite(known)) throw std::runtime_error("localize: the known-trajectory bound is not finite; nothing written");
  const Eigen::Vector3d& m = f.pass.vessel.m_B_Am2;
  CsvWriter w(a.output, {"sensor_id", "x", "y", "z", "sigma_x", "sigma_y", "crlb_x", "crlb_y", "cov_xy"},
              {{"source", a.measurements},
               {"method", a.method},
               {"moment_body_Am2", FormatNumber(m.x()) + ", " + FormatNumber(m.y()) + ", " + FormatNumber(m.z())},
               {"frame",
                "local NED (x north, y east, z down), m; z = the deployment depth (known); sigma_*: 1-sigma of the "
                "estimate; crlb_*: 1-sigma Cramer-Rao bound with the trajectory unknown (joint), evaluated at the "
                "estimate; cov_xy: the x-y covariance of the estimate, m^2 (with sigma_x, sigma_y the full 2x2)"},
               {"crlb_known_trajectory_rms_m", FormatNumber(std::sqrt(known))},
               {"status", out.summary.Status()},
               {"summary", out.summary.BriefReport()}});
  for (const auto& e : out.sensors) {
    w.WriteRow({std::to_string(e.sensor_id), FormatNumber(e.p_SinW_m.x()), FormatNumber(e.p_SinW_m.y()),
                FormatNumber(e.p_SinW_m.z()), Sqrt(e.cov_xy_m2(0, 0)), Sqrt(e.cov_xy_m2(1, 1)),
                Sqrt(e.crlb_joint_m2(0, 0)), Sqrt(e.crlb_joint_m2(1, 1)), FormatNumber(e.cov_xy_m2(1, 0))});
  }
  w.Close();
}

}  // namespace

void AddLocalizeCommand(CLI::App& app) {
  auto args = std::make_shared<LocalizeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "localize", "Estimate the deployed sensors' positions from a friendly vessel's pass (EKF-SLAM or batch)");
  cmd->add_option("--measurements", args->measurements,
                  "magnetometer file: t,sensor_id,B_x,B_y,B_z (T) with '# moment_body_Am2:' and '# vessel_z_m:'")
      ->required();
  cmd->add_option("--deployment", args->deployment, "deployment guesses: sensor_id,x,y,z,sigma_xy (m)")->required();
  cmd->add_option("--gnss", args->gnss,
                  "vessel GNSS fixes: t,x,y,sigma (m); the vessel starts from the first 10 s of them");
  cmd->add_option("--vessel-start", args->vessel_start,
                  "X,Y,SPEED,HEADING of the vessel at the first sample (m, m, m/s, rad), for a pass without GNSS at "
                  "its start; 1-sigma --start-sigma-position, 0.5 m/s, 0.5 rad");
  cmd->add_option("--start-sigma-position", args->options.initial.position_m,
                  "1-sigma of --vessel-start's position, m");
  AddVec3Option(*cmd, "--moment-body", &args->moment,
                "vessel body moment, A*m^2 (default: the measurements file's '# moment_body_Am2:')");
  cmd->add_option("--method", args->method,
                  "ekf (EKF-SLAM; bound over the whole pass), ekf-bounded (the same EKF, bound by a recursion over "
                  "a window: what magnav-localizer runs, memory and cost independent of the pass length) or batch "
                  "(smoother over the whole pass)")
      ->required()
      ->check(CLI::IsMember({"ekf", "ekf-bounded", "batch"}));
  cmd->add_option("--bound-lag", args->bound.lag_s,
                  "ekf-bounded: epochs older than this (s) are folded into the bound's recursion at the estimate "
                  "of that time")
      ->capture_default_str();
  cmd->add_option("--bound-window-items", args->bound.max_window_items,
                  "ekf-bounded: at most this many samples and fixes in the bound's window")
      ->capture_default_str();
  cmd->add_option("--output", args->output, "sensor_id,x,y,z,sigma_x,sigma_y,crlb_x,crlb_y (m), cov_xy (m^2); '# status:' converged, NOT "
                  "converged or diverged (the outlier counts show the estimate lost, or, see --check-batch, the EKF "
                  "disagrees with the smoother: docs/ACCURACY.md \"Trust: honest status\"); exit 0 in every case")->required();
  cmd->add_option("--sigma-b", args->sigma_B_T,
                  "magnetometer noise per axis, T (default: the measurements file's '# sigma_B_T:')");
  cmd->add_option("--loss", args->loss, "batch: robust loss on each sample: huber, cauchy or trivial")
      ->check(CLI::IsMember({"huber", "cauchy", "trivial"}));
  cmd->add_option("--loss-scale", args->options.magnetometer_loss_scale_sigma,
                  "batch: robust loss scale, in sigmas of the sample residual");
  cmd->add_option("--gnss-loss", args->gnss_loss, "batch: robust loss on each GNSS fix: huber, cauchy or trivial")
      ->check(CLI::IsMember({"huber", "cauchy", "trivial"}));
  cmd->add_option("--gnss-loss-scale", args->options.gnss_loss_scale_sigma,
                  "batch: GNSS robust loss scale, in sigmas of the fix residual");
  cmd->add_option("--gate-probability", args->options.gate_probability,
                  "outlier gate per update (chi-square probability): the EKF refuses a magnetometer or GNSS update "
                  "beyond it, the batch counts residuals beyond it; 1 = no gate")
      ->capture_default_str();
  cmd->add_option("--ekf-iterations", args->options.magnetometer_iterations,
                  "EKF: iterations of each magnetometer update (iterated EKF); 1 = plain EKF")
      ->capture_default_str();
  cli::AddSwitchOption(*cmd, "--check-batch", &args->check_batch,
                  "ekf, ekf-bounded: also solve the batch smoother over the pass and report 'diverged' when a "
                  "sensor's EKF estimate is beyond the gate of its own covariance from the smoother's (2-dof NEES of "
                  "the difference > chi-square quantile of --gate-probability; docs/ACCURACY.md \"Trust: honest "
                  "status\"); 0 = the EKF alone")
      ->capture_default_str();
  auto& q = args->options.process;
  cmd->add_option("--q-position", q.position_m_per_sqrt_s, "position random walk, m/sqrt(s)");
  cmd->add_option("--q-speed", q.speed_mps_per_sqrt_s, "speed random walk, m/s/sqrt(s)");
  cmd->add_option("--q-heading", q.heading_rad_per_sqrt_s, "heading random walk, rad/sqrt(s)");
  cmd->add_option("--q-turn-rate", q.turn_rate_radps_per_sqrt_s, "turn-rate random walk, rad/s/sqrt(s)");
  cmd->callback([args] { RunLocalize(*args); });
}

}  // namespace magnav::tools
