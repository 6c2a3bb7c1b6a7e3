// `magnav match`: correct an INS / dead-reckoning path by matching its
// measured field against a geomagnetic map (mapmatch/): single points, ICP,
// ICCP, MMA, MAD/MSD/PROD/NPROD correlation, fast MSD, and the sequential
// particle filters (pf, afpf) run over the path.
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/cli/particle_filter_options.h"
#include "magnav/core/error.h"
#include "magnav/mapmatch/match.h"

namespace magnav::tools {

namespace {

struct MatchArgs {
  std::string map, value_column, path, meas_column, method, output;
  std::string solver = "direct";
  std::string diagnostics;  // pf, afpf: per-step CSV
  bool icp_3d = false;
  bool no_map_error = false;
  bool no_basin_mean_shift = false;
  double outlier_sigmas = 5.0;
  double search_window_deg = 0.0;  // 0 = not given
  mapmatch::MatchOptions options;
};

const char* UpdateName(mapmatch::StepUpdate u) {
  switch (u) {
    case mapmatch::StepUpdate::kUpdated:
      return "updated";
    case mapmatch::StepUpdate::kBadMeasurement:
      return "bad_measurement";
    case mapmatch::StepUpdate::kAllOffMap:
      return "all_off_map";
    case mapmatch::StepUpdate::kOutlier:
      return "outlier";
    case mapmatch::StepUpdate::kSpaced:
      return "spaced";
  }
  return "?";
}

// One row per step of a particle filter (particle_filter.h StepDiagnostics).
void WriteDiagnostics(const std::string& file, const mapmatch::MatchPath& path,
                      const std::vector<mapmatch::StepDiagnostics>& steps) {
  CsvWriter w(file,
              {"k", "lat", "lon", "cov_lat_lat", "cov_lat_lon", "cov_lon_lon", "ess", "particles", "unique_particles",
               "occupied_cells", "nis", "resampled", "ins_jump", "update", "lost", "bias_nT", "bias_sigma_nT",
               "sigma_nT", "likelihood_exponent", "track_check_chi2", "innovation_nT", "predicted_spread_nT", "innovation_bias_chi2",
               "reacquiring", "cloud_cov_lat_lat", "cloud_cov_lat_lon", "cloud_cov_lon_lon", "track_check_failed",
               "subcloud_chi2", "subclouds_disagree", "innovation_cusum", "ins_step_ratio", "ins_glitch", "run_status",
               "converging", "status", "ensemble_chi2", "ensemble_separation_deg", "ensemble_evidence_nats",
               "ensemble_disagree"},
              {{"frame", "estimate lat/lon deg, covariance deg^2 (published; cloud_cov_*: the cloud's own; particle_filter.h StepDiagnostics)"},
               {"run_status", "the run's status had it ended at this step (run_status.h; magnav-matcher publishes it: converged = ok, "
                              "off_map = off_map, converging = converging, any other = lost)"},
               {"status", "the step's own status (particle_filter.h StatusOf: ok, converging, lost, off_map)"}});
  for (std::size_t p = 0; p < steps.size(); ++p) {
    const mapmatch::StepDiagnostics& d = steps[p];
    w.WriteRow({std::to_string(path.k[p]), FormatNumber(d.lat_deg), FormatNumber(d.lon_deg),
                FormatNumber(d.cov_lat_lat), FormatNumber(d.cov_lat_lon), FormatNumber(d.cov_lon_lon),
                FormatNumber(d.ess), std::to_string(d.particles), std::to_string(d.unique_particles),
                std::to_string(d.occupied_cells), FormatNumber(d.nis), d.resampled ? "1" : "0",
                d.ins_jump ? "1" : "0", UpdateName(d.update), d.lost ? "1" : "0", FormatNumber(d.bias_nT),
                FormatNumber(d.bias_sigma_nT), FormatNumber(d.sigma_nT), FormatNumber(d.likelihood_exponent),
                FormatNumber(d.track_check_chi2), FormatNumber(d.innovation_nT),
                FormatNumber(d.predicted_spread_nT), FormatNumber(d.innovation_bias_chi2), d.reacquiring ? "1" : "0",
                FormatNumber(d.cloud_cov_lat_lat), FormatNumber(d.cloud_cov_lat_lon), FormatNumber(d.cloud_cov_lon_lon),
                d.track_check_failed ? "1" : "0", FormatNumber(d.subcloud_chi2), d.subclouds_disagree ? "1" : "0",
                FormatNumber(d.innovation_cusum), FormatNumber(d.ins_step_ratio), d.ins_glitch ? "1" : "0",
                mapmatch::RunVerdictName(d.run_status), d.converging ? "1" : "0",
                mapmatch::StepStatusName(mapmatch::StatusOf(d)), FormatNumber(d.ensemble_chi2),
                FormatNumber(d.ensemble_separation_deg), FormatNumber(d.ensemble_evidence_nats),
                d.ensemble_disagree ? "1" : "0"});
  }
  w.Close();
}

void RunMatch(MatchArgs a) {
  RefuseOutputOverInput(a.output, {a.map, a.path});
  const auto method = mapmatch::ParseMethod(a.method);
  if (!method) throw InputError("--method: expected " + mapmatch::MethodNames() + ", got '" + a.method + "'");
  const bool correlation = *method == mapmatch::Method::kMad || *method == mapmatch::Method::kMsd ||
                           *method == mapmatch::Method::kProd || *method == mapmatch::Method::kNprod;
  if (correlation && !(a.search_window_deg > 0.0)) {
    throw InputError("--search-window: " + a.method + " needs the half-width of its search (deg), e.g. 0.15");
  }
  a.options.correlation.search_window_deg = a.search_window_deg;
  a.options.fast_msd.search_window_deg = a.search_window_deg;  // 0: no coarse stage
  a.options.icp.planar_motion = !a.icp_3d;
  a.options.fast_msd.map_error_in_covariance = !a.no_map_error;
  if (a.no_basin_mean_shift) a.options.fast_msd.basin_mean_shift = false;
  a.options.fast_msd.solver = a.solver == "direct" ? mapmatch::FastMsdSolver::kDirect : mapmatch::FastMsdSolver::kJacobi;
  // NGDC-style whitespace text ("lon lat value") by its extension, else CSV.
  const mapmatch::GeoGrid grid = mapmatch::ReadGeoGridFile(a.map, {a.value_column});
  const mapmatch::MatchPath path = mapmatch::ReadMatchPath(a.path, a.meas_column);
  const bool filter = *method == mapmatch::Method::kPf || *method == mapmatch::Method::kAfpf;
  if (!a.diagnostics.empty() && !filter) throw InputError("--diagnostics: only for pf and afpf");
  // A path entirely off the map: exit 2, naming the path file.
  try {
    mapmatch::RequirePathNearMap(*method, grid, path, a.options);
  } catch (const InputError& e) {
    throw InputError(a.path + ": " + e.what());
  }
  std::vector<mapmatch::StepDiagnostics> steps;
  // The status is reviewed (match.h ReviewResult).
  const mapmatch::MatchResult r = mapmatch::Match(*method, grid, 0, path, a.options, filter ? &steps : nullptr);
  // A result with a non-finite number is never written as a success: the
  // inputs passed the door, so it is this program's fault (exit 3).
  for (std::size_t p = 0; p < path.size(); ++p) {
    if (!std::isfinite(r.lat_deg[p]) || !std::isfinite(r.lon_deg[p])) {
      throw std::runtime_error(a.method + " gave a non-finite position at k = " + std::to_string(path.k[p]) +
                               " (" + r.BriefReport() + "); nothing written");
    }
  }
  if (!a.diagnostics.empty()) WriteDiagnostics(a.diagnostics, path, steps);
  std::vector<char> on_map(path.size());
  int off_map = 0;
  for (std::size_t p = 0; p < path.size(); ++p) {
    on_map[p] = grid.Contains(r.lat_deg[p], r.lon_deg[p]);
    off_map += !on_map[p];
  }
  // CsvWriter writes beside the output and renames on Close: a reader never sees half a file.
  // A method that publishes a covariance (fast-msd) adds it per point, deg² (as the pf/afpf diagnostics).
  const bool cov = r.cov_lat_lat.size() == path.size();
  std::vector<std::string> columns = {"k", "lat", "lon", "on_map"};
  if (cov) columns.insert(columns.end(), {"cov_lat_lat", "cov_lat_lon", "cov_lon_lon"});
  // pf, afpf: each step's status (ok, converging, lost, off_map; particle_filter.h StatusOf), as MapFix.status.
  if (filter) columns.push_back("status");
  CsvWriter w(a.output, columns,
              {{"map", a.map},
               {"value_column", a.value_column},
               {"path", a.path},
               {"meas_column", a.meas_column},
               {"frame", std::string("matched position, latitude/longitude in degrees (WGS84); on_map 1 inside "
                                     "the map's grid") +
                             (cov ? "; cov_* its covariance (lat, lon), deg^2" : "") +
                             (filter ? "; status the filter's at that step (ok, converging, lost, off_map)" : "")},
               {"off_map_points", std::to_string(off_map) + " of " + std::to_string(path.size())},
               {"summary", r.BriefReport()}});
  for (std::size_t p = 0; p < path.size(); ++p) {
    std::vector<std::string> row = {std::to_string(path.k[p]), FormatNumber(r.lat_deg[p]),
                                    FormatNumber(r.lon_deg[p]), on_map[p] ? "1" : "0"};
    if (cov) row.insert(row.end(), {FormatNumber(r.cov_lat_lat[p]), FormatNumber(r.cov_lat_lon[p]),
                                    FormatNumber(r.cov_lon_lon[p])});
    if (filter) row.push_back(mapmatch::StepStatusName(mapmatch::StatusOf(steps[p])));
    w.WriteRow(row);
  }
  w.Close();
}

}  // namespace

void AddMatchCommand(CLI::App& app) {
  auto args = std::make_shared<MatchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "match", "Correct an INS path by matching its measured field against a geomagnetic map (mapmatch/)");
  cmd->option_defaults()->always_capture_default();  // --help shows the papers' values
  cmd->add_option("--map", args->map,
                  "map CSV: lat,lon (deg) and value columns (nT), a complete regular grid; or NGDC text "
                  "'lon lat value' (*.xyz, *.txt; its one layer takes the --value-column name); or a raster "
                  "through GDAL (GeoTIFF, NetCDF, ...: a north-up lat/lon grid; the layer is the NetCDF variable "
                  "or band description named by --value-column, or the only band)")
      ->required();
  cmd->add_option("--value-column", args->value_column, "the map column to match, e.g. F_nT or anomaly_nT")
      ->required();
  cmd->add_option("--path", args->path, "path CSV: k,ins_lat,ins_lon (deg) and the measurement column (nT)")
      ->required();
  cmd->add_option("--meas-column", args->meas_column, "the path's measurement column, e.g. meas_nT")->required();
  cmd->add_option("--method", args->method, mapmatch::MethodNames())->required();
  cmd->add_option("--search-window", args->search_window_deg,
                  "half-width of the translation search, deg: required by mad|msd|prod|nprod; with fast-msd, "
                  "the coarse MSD stage (none without it)");
  cmd->add_option("--output", args->output,
                  "k,lat,lon (deg) of the matched path, on_map (1 inside the map's grid, 0 off it), a "
                  "'# off_map_points:' count and a '# summary:' line")
      ->required();
  cli::AddMaxCorrectionOption(*cmd, &args->options.max_correction_deg);
  cmd->add_option("--ins-start-sd", args->options.observability.prior.start_sd_deg,
                  "the prior on the INS error at the path's first point, 1 sigma per axis (deg); with "
                  "--ins-drift-sd, a random walk from there. Both 0: pf/afpf their own prior (--prior-half-width / "
                  "sqrt(3), --drift-sigma), the others a constant offset of 1/3 of --max-correction (or the method's "
                  "own plausible correction)");
  cmd->add_option("--ins-drift-sd", args->options.observability.prior.drift_sd_deg,
                  "the INS error's random walk per path step, 1 sigma per axis (deg); 0 = a constant offset");
  cmd->add_option("--min-observability", args->options.observability.min_information_ratio,
                  "a result whose map information along the least observed direction at the path's end is below "
                  "this fraction of the INS prior's there says 'not converged: partly observable: along-iso-line "
                  "error unconstrained (map information X of the prior's ...)' instead of 'converged' (a total-field "
                  "map on a smooth main field does not observe the error along its iso-lines), and a published "
                  "covariance (fast-msd's, the pf/afpf diagnostics') is raised along that direction to what the map "
                  "and the prior can know; the summary always gives the figure ('map information at the path's end: "
                  "...'); 0 = never");
  cli::AddOutlierSigmasOption(*cmd, &args->outlier_sigmas);
  mapmatch::MatchOptions& o = args->options;
  cmd->add_option("--tolerance", o.point.tolerance_nT, "point: half-width of the value window, nT");
  cmd->add_option("--field-scale", o.icp.field_scale_deg_per_nT,
                  "icp, mma: deg per nT in the closest-point distance; 0 = 1/(rms map gradient)");
  cmd->add_option("--subdivision", o.icp.closest_point_subdivision,
                  "icp, mma: closest points on a grid this many times finer than the map (bilinear values)");
  cmd->add_flag("--icp-3d", args->icp_3d,
               "icp: the thesis' rigid 3-D transform of (lat, lon, scale*field) instead of moving only (lat, lon)");
  cmd->add_option("--tau", o.icp.convergence_tau, "icp, iccp: convergence threshold on the transform increment");
  cmd->add_option("--max-iterations", o.icp.max_iterations, "icp, iccp: iteration cap");
  cmd->add_option("--min-on-map", o.correlation.min_on_map_fraction,
                  "mad|msd|prod|nprod: fraction of the points a shift needs on the map");
  cmd->add_option("--rotation-window", o.correlation.rotation_window_deg,
                  "mad|msd|prod|nprod: also turn the path within +-this (deg) about its centroid; 0 = translations only");
  cmd->add_option("--rotation-step", o.correlation.rotation_step_deg, "mad|msd|prod|nprod: rotation step, deg");
  cmd->add_option("--lambda", o.fast_msd.lambda_nT2_per_deg2, "fast-msd: smoothness weight, nT^2/deg^2");
  cmd->add_option("--lambda-first-factor", o.fast_msd.lambda_first_round_factor,
                  "fast-msd: the first round's lambda is this times --lambda, decreasing geometrically to it");
  cmd->add_option("--epsilon", o.fast_msd.epsilon_deg2, "fast-msd: Jacobi stop, mean squared change, deg^2");
  cmd->add_option("--solver", args->solver,
                  "fast-msd: direct (default: the fixed point of the paper's iteration by block-tridiagonal "
                  "elimination) or jacobi (the paper's iteration; same answer, ~100x slower)")
      ->check(CLI::IsMember({"jacobi", "direct"}));
  cmd->add_option("--rounds", o.fast_msd.rounds, "fast-msd: re-linearisation rounds");
  cmd->add_option("--ambiguity-ratio", o.fast_msd.ambiguity_ratio,
                  "fast-msd with --search-window: not converged ('ambiguous') when the coarse MSD surface's second "
                  "minimum is below this times the best; 0 = no check");
  cmd->add_flag("--no-map-error", args->no_map_error,
               "fast-msd: leave the map's bilinear interpolation error bound (from the grid's second "
               "differences) out of the covariance's reading variance (sigma^2 alone); positions are the "
               "same either way");
  cmd->add_option("--basin-half-width", o.fast_msd.basin_half_width_deg,
                  "fast-msd: half width (deg) of the offset grid whose posterior (forward-backward along the path) "
                  "adds the other basins' spread to each point's covariance; 0 = off (the linearised basin only); "
                  "0 also turns off the basin mean shift (--no-basin-mean-shift)");
  cmd->add_option("--basin-max-half-width", o.fast_msd.basin_max_half_width_deg,
                  "fast-msd: while the posterior's mass on the offset grid's edge reaches 1 %, the grid's half width "
                  "doubles up to this (deg); <= --basin-half-width = never widen");
  cmd->add_flag("--no-basin-mean-shift", args->no_basin_mean_shift,
                "fast-msd: keep the rounds' positions (by default each point moves to the mean of the other-basins "
                "posterior, the published basin's mass at the rounds' position, unless the result is ambiguous or "
                "that posterior reaches the offset grid's edge; the covariance is taken about the published point)");
  cmd->add_flag("--basin-full-mean", o.fast_msd.basin_full_mean,
                "fast-msd: move each point to the whole offset posterior's mean (its own basin's mass where the "
                "grid puts it) instead of the other basins' share only; off by default (docs/ACCURACY.md)");
  cmd->add_option("--lambda-from-path", o.fast_msd.lambda_from_path_iterations,
                  "fast-msd: set the smoothing weight from the path's own noise and drift, lambda = 2 sigma^2/tau^2 "
                  "(the covariance's EM on the solution), and solve again, up to this many times (stops once lambda "
                  "moves < 1 %); held to [--lambda-min, --lambda-max]; the notes say which lambda; 0 = off (--lambda as "
                  "given; the default, docs/ACCURACY.md)");
  cmd->add_option("--lambda-min", o.fast_msd.lambda_min_nT2_per_deg2,
                  "fast-msd with --lambda-from-path: the smallest lambda it may set (nT^2/deg^2; default 1e7, the default lambda)");
  cmd->add_option("--lambda-max", o.fast_msd.lambda_max_nT2_per_deg2,
                  "fast-msd with --lambda-from-path: the largest lambda it may set (nT^2/deg^2; default 1e11)");
  cmd->add_option("--max-jacobi", o.fast_msd.max_iterations_per_round, "fast-msd: Jacobi iterations per round");
  cmd->add_option("--diagnostics", args->diagnostics,
                  "pf, afpf: write every step's estimate, covariance, ESS, particle count, unique particles, "
                  "occupied map cells, NIS, resampled, INS jump, update and lost flags to this CSV (cov_*: the published "
                  "covariance, the prior's while lost; cloud_cov_*: the cloud's own)");
  cli::AddParticleFilterOptions(*cmd, &o.particle_filter);
  cmd->callback([args] {
    MatchArgs a = *args;
    a.options.mma.field_scale_deg_per_nT = a.options.icp.field_scale_deg_per_nT;
    a.options.mma.closest_point_subdivision = a.options.icp.closest_point_subdivision;
    a.options.iccp.convergence_tau = a.options.icp.convergence_tau;
    a.options.iccp.max_iterations = a.options.icp.max_iterations;
    a.options.icp.outlier_sigmas = a.options.iccp.outlier_sigmas = a.options.mma.outlier_sigmas =
        a.options.correlation.outlier_sigmas = a.options.fast_msd.outlier_sigmas =
            a.options.particle_filter.outlier_sigmas = a.outlier_sigmas;
    RunMatch(a);
  });
}

}  // namespace magnav::tools
