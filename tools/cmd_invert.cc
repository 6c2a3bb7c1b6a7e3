// `magnav invert`: single-sample dipole inversion (TED, TED+EGT, EGT) or
// Monte-Carlo tracking of every row of a gradiometer file.
#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/inversion/inverter.h"
#include "magnav/inversion/particle_filter.h"

namespace magnav::tools {
namespace {

struct InvertArgs {
  std::string input;
  std::string output;
  std::string method;
  Vec3Arg b0;
  Vec3Arg moment_body;
  double sigma_B = -1.0;  // < 0: from the file
  double sigma_T = -1.0;
  double min_snr = inversion::GateOptions{}.min_snr;
  double max_relative_sigma = inversion::GateOptions{}.max_relative_sigma;
  double max_position_sigma = inversion::GateOptions{}.max_position_sigma_3d_m;
  bool min_snr_given = false, relative_sigma_given = false, position_sigma_given = false;
  int particles = 600;
  unsigned long long seed = 42;
};

// Empty for "not computed" (NaN); "inf" for an infinite condition number.
std::string Num(double v) {
  if (std::isnan(v)) return "";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return FormatNumber(v);
}

void RunInvert(const InvertArgs& args) {
  RefuseOutputOverInput(args.output, {args.input});
  GradiometerFile file = ReadGradiometerFile(args.input);
  const bool has_case = !file.case_ids.empty();
  const bool has_t = file.has_time;
  const bool has_id = file.has_sensor_id;

  for (auto& s : file.samples) {
    if (args.sigma_B >= 0.0) s.sigma_B = args.sigma_B;
    if (args.sigma_T >= 0.0) s.sigma_T = args.sigma_T;
  }
  Eigen::Vector3d B0 = Eigen::Vector3d::Zero();
  std::string b0_source;
  if (args.b0.set) {
    B0 = {args.b0.v[0], args.b0.v[1], args.b0.v[2]};
    b0_source = "--b0";
  } else if (file.B0) {
    B0 = *file.B0;
    b0_source = "file";
  } else {  // never a silent B0 = 0
    throw InputError(args.input + ": no regional field: give --b0 BX,BY,BZ (0,0,0 if B holds the anomaly field "
                                  "alone) or a '# B0_T:' line");
  }

  inversion::InverterOptions inv_options;
  inv_options.B0_W = B0;
  inv_options.gates.min_snr = args.min_snr;
  inv_options.gates.max_relative_sigma = args.max_relative_sigma;
  inv_options.gates.max_position_sigma_3d_m = args.max_position_sigma;
  // Without a time column the rows are independent cases: no speed gate.
  inv_options.gates.enable_speed_gate = has_t && !has_case;

  std::vector<inversion::DipoleFix> fixes(file.samples.size());
  std::vector<std::pair<std::string, std::string>> params = {{"method", args.method},
                                                             {"input", args.input},
                                                             {"B0_T", FormatVec3(B0)},
                                                             {"B0_source", b0_source}};
  if (args.method == "mc") {
    Eigen::Vector3d m_B;
    if (args.moment_body.set) {
      m_B = {args.moment_body.v[0], args.moment_body.v[1], args.moment_body.v[2]};
    } else if (file.moment_body) {
      m_B = *file.moment_body;
    } else {
      throw InputError(args.input +
                       ": method mc needs the body moment: give --moment-body or a '# moment_body_Am2:' line");
    }
    inversion::MonteCarloTrackerOptions mc;
    mc.filter.moment_body_Am2 = m_B;
    mc.filter.num_particles = args.particles;
    mc.filter.seed = args.seed;
    mc.init_inverter.B0_W = B0;
    mc.init_inverter.gates.enable_speed_gate = inv_options.gates.enable_speed_gate;
    // The initialising fixes keep their own uncertainty gate unless one is given.
    if (args.min_snr_given) mc.init_inverter.gates.min_snr = args.min_snr;
    if (args.relative_sigma_given) mc.init_inverter.gates.max_relative_sigma = args.max_relative_sigma;
    if (args.position_sigma_given) mc.init_inverter.gates.max_position_sigma_3d_m = args.max_position_sigma;
    std::string error;
    if (!mc.IsValid(&error)) throw InputError("invert --method mc: " + error);
    inversion::MonteCarloTracker tracker(mc);
    // One filter per sensor, each in time order.
    std::vector<std::size_t> order(file.samples.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      const auto& sa = file.samples[a];
      const auto& sb = file.samples[b];
      return sa.sensor_id != sb.sensor_id ? sa.sensor_id < sb.sensor_id : sa.t_s < sb.t_s;
    });
    for (const std::size_t i : order) fixes[i] = tracker.Process(file.samples[i]);
    params.emplace_back("moment_body_Am2", FormatVec3(m_B));
    params.emplace_back("particles", std::to_string(args.particles));
    params.emplace_back("seed", std::to_string(args.seed));
  } else {
    if (!inversion::ParseMethod(args.method, &inv_options.method)) {
      throw InputError("invert: unknown method '" + args.method + "'");
    }
    std::string error;
    if (!inv_options.IsValid(&error)) throw InputError("invert: " + error);
    inversion::Inverter inverter(inv_options);
    for (std::size_t i = 0; i < file.samples.size(); ++i) fixes[i] = inverter.Process(file.samples[i]);
  }

  std::vector<std::string> header;
  if (has_case) header.push_back("case_id");
  if (has_t) header.push_back("t");
  if (has_id) header.push_back("sensor_id");
  for (const char* c : {"dipole_x", "dipole_y", "dipole_z", "valid", "reason", "cond", "sigma_x", "sigma_y", "sigma_z",
                        "cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz"}) {
    header.push_back(c);
  }
  params.emplace_back("columns",
                      "dipole_* = dipole position, world NED, m (a rejected row keeps the rejected solution when "
                      "one was computed, else empty); valid 0/1; reason empty when valid; cond = condition number "
                      "of the method's system (mc: of T; inf when singular, empty when not computed); sigma_* = "
                      "1-sigma per axis (m) and cov_* the position covariance (m^2, NED), empty when sigma_B and "
                      "sigma_T are unknown");
  CsvWriter out(args.output, header, params);
  std::vector<std::string> row;
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    const auto& f = fixes[i];
    row.clear();
    if (has_case) row.push_back(std::to_string(file.case_ids[i]));
    if (has_t) row.push_back(FormatNumber(file.samples[i].t_s));
    if (has_id) row.push_back(std::to_string(file.samples[i].sensor_id));
    for (int k = 0; k < 3; ++k) row.push_back(Num(f.p_DinW[k]));
    row.push_back(f.valid ? "1" : "0");
    row.push_back(inversion::RejectReasonName(f.reason));
    row.push_back(Num(f.cond));
    const bool has_cov = f.cov_p_DinW.allFinite();
    for (int k = 0; k < 3; ++k) row.push_back(has_cov ? Num(std::sqrt(std::max(0.0, f.cov_p_DinW(k, k)))) : "");
    for (const auto& [i, j] : {std::pair{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}}) {
      row.push_back(has_cov ? Num(f.cov_p_DinW(i, j)) : "");
    }
    out.WriteRow(row);
  }
  out.Close();
}

}  // namespace

void AddInvertCommand(CLI::App& app) {
  auto args = std::make_shared<InvertArgs>();
  CLI::App* cmd = app.add_subcommand(
      "invert", "Locate a dipole from every gradiometer row (ted, ted-egt, egt) or track it (mc)");
  cmd->add_option("--input", args->input, "gradiometer CSV (sensor_x..z, B_x..z, T00..T22)")->required();
  cmd->add_option("--method", args->method, "ted | ted-egt | egt | mc")
      ->required()
      ->check(CLI::IsMember({"ted", "ted-egt", "egt", "mc"}));
  AddVec3Option(*cmd, "--b0", &args->b0, "regional field B0 in T (default: the file's '# B0_T:'; one of the two is required)");
  AddVec3Option(*cmd, "--moment-body", &args->moment_body,
                "body moment in A·m² for mc (default: the file's '# moment_body_Am2:')");
  cmd->add_option("--sigma-b", args->sigma_B, "B noise σ in T (default: the file's '# sigma_B_T:')")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--sigma-t", args->sigma_T, "tensor noise σ in T/m (default: '# sigma_T_Tpm:')")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--min-snr", args->min_snr,
                  "weak-signal gate: reject a row whose |T|_F < min_snr * sigma_T (0 = off; mc: for the "
                  "initialising fixes, whose default is 100)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--max-relative-sigma", args->max_relative_sigma,
                  "uncertainty gate: reject a fix whose predicted 3-D 1-sigma position error exceeds this fraction "
                  "of its range (0 = off, the default; mc: for the initialising fixes)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--max-position-sigma", args->max_position_sigma,
                  "uncertainty gate: reject a fix whose predicted 3-D 1-sigma position error exceeds this, m "
                  "(0 = off; 0.05 for the paper's SQUID per-fix accuracy; mc: its initialising fixes default to 1)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--particles", args->particles, "mc: number of particles")->check(CLI::Range(2, 1000000));
  cmd->add_option("--seed", args->seed, "mc: random seed");
  cmd->add_option("--output", args->output, "output CSV")->required();
  cmd->callback([args, cmd] {
    args->min_snr_given = cmd->count("--min-snr") > 0;
    args->relative_sigma_given = cmd->count("--max-relative-sigma") > 0;
    args->position_sigma_given = cmd->count("--max-position-sigma") > 0;
    RunInvert(*args);
  });
}

}  // namespace magnav::tools
