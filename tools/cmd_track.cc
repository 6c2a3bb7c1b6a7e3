// `magnav track`: follows every dipole (vessel) of a gradiometer pass or
// sensor field (tracker/multi_tracker.h), in batch (each track refined over
// its own samples) or sliding-window (causal) mode, and writes one row per
// track and epoch with its track_id.
// --fixes hands the initialiser single-sample fixes computed elsewhere (the
// output of `magnav invert`, or `magnav record --topic dipole_fix`), as
// magnav-tracker takes them from magnav/dipole_fix.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include "commands.h"
#include "magnav/cli/progress.h"
#include "magnav/cli/tracker_options.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tools {

namespace {

// Passes of at least this many epochs also say each track's refinement (a
// line each off a terminal); shorter ones only the window pass's progress.
constexpr std::size_t kSayStagesFromEpochs = 100000;

struct TrackArgs {
  std::string input, output, mode = "batch";
  Vec3Arg b0;
  std::string solver = "chain";
  std::string fixes;
  cli::TrackerFlags flags;
};

// A fix file: t, sensor_id (optional: 0), dipole_x..z, valid (optional: 1).
// A row that is not valid may leave its position empty. In time order. Every
// sensor_id must be one of the pass's (`sensor_ids`); positions within
// kLimitPosition.
std::vector<tracker::DipoleFix> ReadFixes(const std::string& path, const std::set<std::uint32_t>& sensor_ids,
                                          const std::string& pass_path) {
  const CsvTable c = CsvTable::Read(path);
  const std::size_t t = c.column("t"), x = c.column("dipole_x"), y = c.column("dipole_y"), z = c.column("dipole_z");
  const auto id = c.find_column("sensor_id");
  const auto valid = c.find_column("valid");
  const auto where = [&](std::size_t row, std::size_t col) {
    return path + ":" + std::to_string(c.line_of(row)) + ": column '" + c.header()[col] + "': ";
  };
  std::vector<tracker::DipoleFix> out;
  for (std::size_t i = 0; i < c.num_rows(); ++i) {
    const bool ok = !valid || c.integer(i, *valid) != 0;
    const std::uint32_t sensor = id ? c.uint32(i, *id) : 0;
    if (id && sensor_ids.count(sensor) == 0) {
      throw InputError(where(i, *id) + "sensor " + std::to_string(sensor) + " is not in the pass " + pass_path);
    }
    Eigen::Vector3d p = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    if (ok) {
      for (const std::size_t col : {x, y, z}) {
        if (!WithinLimit(kLimitPosition, c.number(i, col))) {
          throw InputError(where(i, col) + OutOfRange(kLimitPosition, c.number(i, col)));
        }
      }
      p = {c.number(i, x), c.number(i, y), c.number(i, z)};
    }
    out.push_back(tracker::MakeFix(c.number(i, t), sensor, p, ok));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const tracker::DipoleFix& a, const tracker::DipoleFix& b) { return a.t_s < b.t_s; });
  return out;
}

// One output row: a track's estimate.
struct Row {
  std::uint32_t track_id = 0;
  tracker::EpochEstimate e;
  tracker::TrackState state = tracker::TrackState::kConfirmed;
};

void WriteTracks(const std::string& path, const std::string& input, const std::string& mode, std::vector<Row> rows,
                 const std::vector<tracker::TrackRecord>& tracks, const std::string& summary) {
  std::stable_sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) {
    return a.e.t_s != b.e.t_s ? a.e.t_s < b.e.t_s : a.track_id < b.track_id;
  });
  // The longest track's moment keeps the single-vessel header line.
  std::map<std::uint32_t, int> count;
  for (const auto& r : rows) ++count[r.track_id];
  const tracker::TrackRecord* longest = nullptr;
  for (const auto& t : tracks) {
    if (longest == nullptr || count[t.track_id] > count[longest->track_id]) longest = &t;
  }
  std::vector<std::pair<std::string, std::string>> params = {{"source", input}, {"mode", mode}};
  if (longest != nullptr) {
    params.push_back({"moment_body_Am2", FormatVec3(longest->m_B_Am2)});
    params.push_back({"sigma_moment_body_Am2", FormatVec3(longest->cov_m_B.diagonal().cwiseMax(0.0).cwiseSqrt())});
  }
  for (const auto& t : tracks) {
    params.push_back({"track_moment_body_Am2", std::to_string(t.track_id) + ", " + FormatVec3(t.m_B_Am2)});
  }
  for (const auto& t : tracks) {
    params.push_back({"track", std::to_string(t.track_id) + ": " + std::to_string(count[t.track_id]) + " rows, t " +
                                   FormatNumber(t.t_start_s) + "-" + FormatNumber(t.t_end_s) + " s, ended: " +
                                   (t.end_reason.empty() ? "no" : t.end_reason) +
                                   (std::isnan(t.t_window_offsets_s)
                                        ? std::string()
                                        : ", window sensor offsets from t " + FormatNumber(t.t_window_offsets_s) + " s")});
  }
  params.push_back({"frame",
                    "local NED (x north, y east, z down), m; t in s; vx, vy in m/s; heading in rad from "
                    "north, clockwise seen from above; sigma_*: 1-sigma position uncertainty (m), empty if "
                    "unknown; cov_xy, cov_xz, cov_yz: the position covariance's off-diagonal terms (m^2; with "
                    "sigma_x..z the full 3x3), empty if unknown; track_id: one per vessel, never reused; state: "
                    "confirmed (the track detected at this epoch), coasting (not detected: predicted, corrected "
                    "at most by samples too weak for a detection) or start (window: a row before the track's "
                    "confirmation, back-filled later from the window's smoothed estimate; --start-rows)"});
  params.push_back({"summary", summary});
  CsvWriter w(path,
              {"t", "track_id", "x", "y", "z", "vx", "vy", "heading", "sigma_x", "sigma_y", "sigma_z", "state", "cov_xy",
               "cov_xz", "cov_yz"},
              params);
  for (const auto& r : rows) {
    const auto& e = r.e;
    const Eigen::Vector3d v = e.v_VinW();
    std::vector<std::string> row = {FormatNumber(e.t_s),        std::to_string(r.track_id),
                                    FormatNumber(e.p_VinW.x()), FormatNumber(e.p_VinW.y()),
                                    FormatNumber(e.p_VinW.z()), FormatNumber(v.x()),
                                    FormatNumber(v.y()),        FormatNumber(e.heading_rad)};
    for (int i = 0; i < 3; ++i) {
      row.push_back(e.has_covariance ? FormatNumber(std::sqrt(std::max(e.cov_state(i, i), 0.0))) : "");
    }
    row.push_back(tracker::TrackStateName(r.state));
    for (const auto& [i, j] : {std::pair{0, 1}, std::pair{0, 2}, std::pair{1, 2}}) {
      row.push_back(e.has_covariance ? FormatNumber(e.cov_state(i, j)) : "");
    }
    w.WriteRow(row);
  }
  w.Close();
}

void RunTrack(const TrackArgs& a) {
  RefuseOutputOverInput(a.output, {a.input, a.fixes});
  GradiometerFile f = ReadGradiometerFile(a.input);
  if (!f.has_time) throw InputError(a.input + ": missing column 't': a pass to track needs its time column (s)");
  Eigen::Vector3d B0;
  if (a.b0.set) {
    B0 = {a.b0.v[0], a.b0.v[1], a.b0.v[2]};
  } else if (f.B0) {
    B0 = *f.B0;
  } else {
    throw InputError(a.input + ": no background field: give --b0 BX,BY,BZ or a '# B0_T:' line");
  }
  for (std::size_t i = 1; i < f.samples.size(); ++i) {
    if (f.samples[i].t_s < f.samples[i - 1].t_s) {
      throw InputError(a.input + ":" + std::to_string(f.lines[i]) +
                       ": column 't': time goes backwards (rows must be ordered by t)");
    }
  }
  tracker::MultiTrackerOptions mopt = cli::ApplyTrackerFlags(a.flags);
  tracker::TrackerOptions& opt = mopt.track;
  if (a.solver == "chain") {
    opt.batch_solver = tracker::TrackerOptions::BatchSolver::kChainLevenbergMarquardt;
  } else if (a.solver == "ceres") {
    opt.batch_solver = tracker::TrackerOptions::BatchSolver::kCeres;
  } else {
    throw InputError("--solver: expected chain or ceres, got '" + a.solver + "'");
  }
  if (opt.init.source == tracker::InitSource::kExternal && a.fixes.empty()) {
    throw InputError("--init-from dipole_fix needs --fixes FILE (e.g. the output of magnav invert)");
  }
  std::optional<std::vector<tracker::DipoleFix>> fixes;
  if (!a.fixes.empty()) {
    std::set<std::uint32_t> ids;
    for (const auto& s : f.samples) ids.insert(s.sensor_id);
    fixes = ReadFixes(a.fixes, ids, a.input);
  }
  const std::vector<tracker::DipoleFix>* given = fixes ? &*fixes : nullptr;

  std::vector<Row> rows;
  std::vector<tracker::TrackRecord> records;
  std::string summary;
  if (a.mode == "batch") {
    const auto epochs = tracker::GroupEpochs(f.samples, opt.epoch_tolerance_s);
    std::vector<GradiometerSample>().swap(f.samples);  // the epochs hold them now (a long pass: half the memory)
    cli::Progress progress("track", "epochs", epochs.size(), stderr);
    tracker::MultiSummary finder_summary;
    const auto tracks = tracker::SolveBatchMulti(
        epochs, B0, mopt, given,
        [&](const std::string& stage, std::size_t done, std::size_t total) {
          if (total > 0) {
            progress.Update(done, stage);
          } else if (epochs.size() >= kSayStagesFromEpochs) {
            progress.Say(stage);
          }
        },
        &finder_summary);
    progress.Done();
    for (const auto& t : tracks) {
      tracker::TrackRecord r;
      r.track_id = t.track_id;
      r.m_B_Am2 = t.track.m_B_Am2;
      r.cov_m_B = t.track.cov_m_B;
      r.live = false;
      r.t_start_s = t.track.epochs.empty() ? 0.0 : t.track.epochs.front().t_s;
      r.t_end_s = t.track.epochs.empty() ? 0.0 : t.track.epochs.back().t_s;
      records.push_back(r);
      for (std::size_t k = 0; k < t.track.epochs.size(); ++k) {
        const tracker::EpochEstimate& e = t.track.epochs[k];
        if (e.usable) rows.push_back({t.track_id, e, t.states.at(k)});
      }
      summary += "track " + std::to_string(t.track_id) + ": " + t.track.summary.BriefReport() + "; ";
    }
    // What the finder's far source removed (the refinement removes the same).
    if (finder_summary.far_source_enabled) summary += finder_summary.far_source.BriefReport();
  } else if (a.mode == "window") {
    // As magnav-tracker: each fix is handed in before the sample it came from.
    tracker::MultiTracker tr(B0, mopt);
    std::size_t next_fix = 0;
    const auto take = [&](const std::vector<tracker::TrackOutput>& out) {
      for (const auto& o : out) rows.push_back({o.track_id, o.estimate, o.state});
    };
    cli::Progress progress("track", "samples", f.samples.size(), stderr);
    for (std::size_t i = 0; i < f.samples.size(); ++i) {
      const GradiometerSample& s = f.samples[i];
      while (given && next_fix < given->size() && (*given)[next_fix].t_s <= s.t_s) tr.AddFix((*given)[next_fix++]);
      take(tr.AddSample(s));
      progress.Update(i + 1, "window");
    }
    progress.Done();
    take(tr.Flush());
    records = tr.Tracks();
    summary = tr.summary().BriefReport();
  } else {
    throw InputError("--mode: expected batch or window, got '" + a.mode + "'");
  }
  // Nothing to track is a result (no vessel close enough to any sensor): an
  // empty track file whose summary says why, exit 0.
  if (records.empty()) {
    std::string why = tracker::NoTrackMessage(opt, given != nullptr);
    if (!summary.empty()) why += "; " + summary;
    std::fprintf(stderr, "magnav track: %s: %s; writing a track file with no rows\n", a.input.c_str(), why.c_str());
    summary = why;
  }
  WriteTracks(a.output, a.input, a.mode, rows, records, summary);
}

}  // namespace

void AddTrackCommand(CLI::App& app) {
  auto args = std::make_shared<TrackArgs>();
  CLI::App* cmd = app.add_subcommand("track", "Track every dipole (vessel) of a gradiometer pass or field");
  cmd->add_option("--input", args->input, "pass file: t,sensor_id,sensor_x..z,B_x..B_z,T00..T22")->required();
  cmd->add_option("--output", args->output,
                  "track file: t,track_id,x,y,z,vx,vy,heading,sigma_x,sigma_y,sigma_z,state (confirmed|coasting|start),"
                  "cov_xy,cov_xz,cov_yz (m^2)")
      ->required();
  AddVec3Option(*cmd, "--b0", &args->b0, "background field B0 in tesla, NED (default: the file's '# B0_T:')");
  cmd->add_option("--mode", args->mode, "batch (whole pass) or window (fixed-lag, causal)")
      ->check(CLI::IsMember({"batch", "window"}));
  cmd->add_option("--solver", args->solver,
                  "batch solver: chain (Levenberg-Marquardt on the chain of states, O(N)) or ceres "
                  "(ceres::Solve, sparse Cholesky; same problem, slower)")
      ->check(CLI::IsMember({"chain", "ceres"}));
  cmd->add_option("--fixes", args->fixes,
                  "single-sample fixes to start the track from (magnav invert output or a recorded dipole_fix "
                  "topic: t,sensor_id,dipole_x..z,valid)");
  cli::AddTrackerOptions(*cmd, &args->flags, "--fixes");
  cmd->add_option("--batch-rounds", args->flags.options.batch_rounds,
                  "batch: refinement rounds over every track (at least; more while a span grows)")
      ->capture_default_str();
  cmd->add_option("--batch-gate-snr", args->flags.options.batch_gate_snr,
                  "batch: a track is refined over the samples where its predicted SNR is at least this, its span "
                  "grown over the epochs where its predicted tensor SNR is")
      ->capture_default_str();
  cmd->add_option("--batch-extension-step", args->flags.options.batch_extension_step_s,
                  "batch: each round grows a track's span by at most this much per side, over the epochs where its "
                  "predicted tensor SNR reaches --batch-gate-snr, s")
      ->capture_default_str();
  cmd->add_option("--batch-turn-change-points", args->flags.options.track.batch_turn_change_points,
                  "batch: restarts from the estimate with its turn rate made piecewise constant with 1..this many "
                  "change points, each kept if it ends at a lower cost (0 = none, at most " +
                      std::to_string(tracker::TrackerOptions::kMaxBatchTurnChangePoints) + ")")
      ->capture_default_str();
  cli::AddSwitchOption(*cmd, "--batch-restart-from-window", &args->flags.options.batch_restart_from_window,
                  "batch: also restart each track's solve from the window track that found it, kept if it ends at a "
                  "lower cost (0/1)")
      ->capture_default_str();
  cli::AddSwitchOption(*cmd, "--batch-weak-init", &args->flags.options.batch_weak_init,
                  "batch: a track too weak for the field's start SNR (started in the residual) is initialised at "
                  "the residual start's SNR (--residual-start-snr) and refined; 0: it keeps its window rows (0/1)")
      ->capture_default_str();
  cmd->add_option("--batch-turn-loss-scale", args->flags.options.batch_turn_loss_scale_sigma,
                  "batch: Cauchy scale of the turn-rate changes in each track's solve, in sigmas of one step (0 = "
                  "--turn-loss-scale, as the window)")
      ->capture_default_str();
  cli::AddSwitchOption(*cmd, "--batch-other-field-cov", &args->flags.options.batch_other_field_covariance,
                       "batch: the other tracks' removed fields are uncertain by their own covariance (position, "
                       "heading, moment; first order) instead of 5 % of their norm (0/1)")
      ->capture_default_str();
  cmd->add_option("--batch-other-field-rel", args->flags.options.batch_other_field_relative_error,
                  "batch: the other tracks' removed fields are uncertain by this share of their norm, in [0, 1] "
                  "(the window keeps 0.05)")
      ->capture_default_str();
  cli::AddSwitchOption(*cmd, "--batch-model-spread", &args->flags.options.track.batch_model_spread,
                  "batch: add to each state's covariance the spread of the restarts' ends about the chosen one, "
                  "weighted by exp(-cost difference) (model averaging over the turn's change points; 0/1)")
      ->capture_default_str();
  cli::AddSwitchOption(*cmd, "--start-rows", &args->flags.options.management.backfill_start,
                  "window: a track started by a two-dipole fit also gets its start's rows from its first strong "
                  "epoch (state start: the window's smoothed estimates, output up to --window late; 0/1)")
      ->capture_default_str();
  cli::AddSwitchOption(*cmd, "--start-rows-single", &args->flags.options.management.backfill_single,
                  "window: with --start-rows, a track made by a single start (its own fixes) gets its start's rows "
                  "too, from its first fix (0/1)")
      ->capture_default_str();
  cli::AddSwitchOption(*cmd, "--start-rows-older", &args->flags.options.management.residual_start.backfill_older,
                  "window: with --start-rows, the older track of a joint start (a single start confirmed before the "
                  "other vessel's start made them a pair) gets its start's rows too (0/1)")
      ->capture_default_str();
  cmd->callback([args] { RunTrack(*args); });
}

}  // namespace magnav::tools
