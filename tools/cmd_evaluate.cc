// magnav evaluate: position error of an estimate file (magnav invert / track
// output, or a recorded dipole_fix / track topic) against a truth file; with a
// multi-vessel truth (vessel_id column), multi-track scores per vessel.
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <set>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"

namespace magnav::tools {
namespace {

struct EvaluateArgs {
  std::string estimate, truth, sensors, pass;
  double max_range_m = 0.0;  // 0 = every epoch
  double gate_m = 5.0;       // multi-track: a row farther than this from every vessel is false
};

struct Xyz {
  std::size_t x, y, z;
};

Xyz PositionColumns(const CsvTable& t) {
  if (t.has_column("dipole_x")) return {t.column("dipole_x"), t.column("dipole_y"), t.column("dipole_z")};
  return {t.column("x"), t.column("y"), t.column("z")};
}

// Multi-track scoring (truth with vessel_id, estimates with track_id): each
// estimate row goes to the nearest vessel at its time (3-D) or, farther than
// the gate from all, counts as false. Per vessel over its in-field instants
// (within max_range of a sensor, horizontally; all without --max-range):
// coverage = share of instants with a row assigned to it, purity = share of
// its rows carrying its most frequent track_id, RMS/max of its rows' errors;
// overrun = last row of its main track − its last in-field instant.
void RunMulti(const EvaluateArgs& a, const CsvTable& est, const CsvTable& truth,
              const std::vector<Eigen::Vector3d>& sensors) {
  const Xyz pe = PositionColumns(est), pt = PositionColumns(truth);
  const std::size_t te = est.column("t"), tt = truth.column("t"), vid = truth.column("vessel_id");
  const auto tid = est.find_column("track_id");
  const auto usable = est.find_column("usable");
  // Truth: time (ns) -> vessel -> position.
  std::map<long long, std::map<long long, Eigen::Vector3d>> truth_at;
  for (std::size_t i = 0; i < truth.num_rows(); ++i) {
    truth_at[std::llround(truth.number(i, tt) * 1e9)][truth.integer(i, vid)] =
        Eigen::Vector3d(truth.number(i, pt.x), truth.number(i, pt.y), truth.number(i, pt.z));
  }
  const auto in_field = [&](const Eigen::Vector3d& p) {
    if (sensors.empty()) return true;
    double best = 1e300;
    for (const auto& s : sensors) best = std::min(best, (p - s).head<2>().norm());
    return best <= a.max_range_m;
  };
  struct Vessel {
    std::size_t instants = 0, covered = 0, rows = 0;
    double sum_sq = 0.0, max_err = 0.0, last_in_field = -1e300;
    std::map<long long, std::size_t> ids;
    std::map<long long, double> id_last;  // last row time per track id
    std::set<long long> covered_at;
  };
  std::map<long long, Vessel> vessels;
  for (const auto& [t, vs] : truth_at) {
    for (const auto& [v, p] : vs) {
      Vessel& ve = vessels[v];
      if (in_field(p)) {
        ++ve.instants;
        ve.last_in_field = std::max(ve.last_in_field, t * 1e-9);
      }
    }
  }
  std::size_t rows = 0, false_rows = 0, unmatched = 0, skipped = 0;
  for (std::size_t i = 0; i < est.num_rows(); ++i) {
    if (usable && est.integer(i, *usable) == 0) {
      ++skipped;
      continue;
    }
    ++rows;
    const long long t = std::llround(est.number(i, te) * 1e9);
    const auto it = truth_at.find(t);
    if (it == truth_at.end()) {
      ++unmatched;
      continue;
    }
    const Eigen::Vector3d p(est.number(i, pe.x), est.number(i, pe.y), est.number(i, pe.z));
    long long best_v = -1;
    double best = 1e300;
    for (const auto& [v, q] : it->second) {
      if ((p - q).norm() < best) {
        best = (p - q).norm();
        best_v = v;
      }
    }
    if (best > a.gate_m) {
      ++false_rows;
      continue;
    }
    Vessel& ve = vessels[best_v];
    const long long id = tid ? est.integer(i, *tid) : 0;
    ++ve.ids[id];
    ve.id_last[id] = std::max(ve.id_last.count(id) ? ve.id_last[id] : -1e300, t * 1e-9);
    if (!in_field(it->second.at(best_v))) continue;
    ++ve.rows;
    ve.sum_sq += best * best;
    ve.max_err = std::max(ve.max_err, best);
    if (ve.covered_at.insert(t).second) ++ve.covered;
  }
  std::printf("rows %zu (+%zu not usable): %zu false (farther than %.3g m from every vessel, %.2f %%), %zu at no truth "
              "time\n",
              rows, skipped, false_rows, a.gate_m, rows > 0 ? 100.0 * false_rows / rows : 0.0, unmatched);
  for (const auto& [v, ve] : vessels) {
    long long main_id = -1;
    std::size_t main_n = 0, all_n = 0;
    for (const auto& [id, n] : ve.ids) {
      all_n += n;
      if (n > main_n) {
        main_n = n;
        main_id = id;
      }
    }
    std::printf("vessel %lld: in-field instants %zu, coverage %.4f, track %lld (purity %.4f, %zu track ids), RMS %.4g m, "
                "max %.4g m, overrun %.3g s\n",
                v, ve.instants, ve.instants > 0 ? static_cast<double>(ve.covered) / ve.instants : 0.0, main_id,
                all_n > 0 ? static_cast<double>(main_n) / all_n : 0.0, ve.ids.size(),
                ve.rows > 0 ? std::sqrt(ve.sum_sq / ve.rows) : 0.0, ve.max_err,
                main_id >= 0 && ve.instants > 0 ? ve.id_last.at(main_id) - ve.last_in_field : 0.0);
  }
  if (rows == 0) throw InputError(a.estimate + ": no usable estimate row");
}

void Run(const EvaluateArgs& a) {
  const CsvTable est = CsvTable::Read(a.estimate);
  const CsvTable truth = CsvTable::Read(a.truth);
  const Xyz pe = PositionColumns(est), pt = PositionColumns(truth);
  const std::size_t te = est.column("t"), tt = truth.column("t");
  // A row marked not valid (fixes) or not usable (tracks) is not scored.
  const auto valid_col = est.has_column("valid") ? est.find_column("valid") : est.find_column("usable");
  const bool has_sigma = est.has_column("sigma_x");
  const Xyz ps = has_sigma ? Xyz{est.column("sigma_x"), est.column("sigma_y"), est.column("sigma_z")} : Xyz{0, 0, 0};
  std::vector<Eigen::Vector3d> sensors;
  if (!a.sensors.empty() && !a.pass.empty()) throw InputError("give --sensors or --pass, not both");
  if (a.max_range_m > 0) {
    if (a.sensors.empty() && a.pass.empty()) {
      throw InputError("--max-range needs --sensors X,Y,Z[;X,Y,Z...] or --pass PASS.csv");
    }
    if (!a.sensors.empty()) {
      sensors = cli::ParseVec3List("--sensors", a.sensors);
    } else {
      std::map<std::uint32_t, Eigen::Vector3d> by_id;
      for (const auto& s : ReadGradiometerFile(a.pass).samples) by_id.emplace(s.sensor_id, s.p_SinW);
      for (const auto& [id, p] : by_id) sensors.push_back(p);
    }
  } else if (!a.sensors.empty() || !a.pass.empty()) {
    throw InputError("--sensors and --pass are used only with --max-range");
  }
  if (truth.has_column("vessel_id")) {
    RunMulti(a, est, truth, sensors);
    return;
  }
  // Truth by time, in ns to match exactly.
  std::map<long long, std::size_t> truth_at;
  for (std::size_t i = 0; i < truth.num_rows(); ++i) truth_at[std::llround(truth.number(i, tt) * 1e9)] = i;

  std::size_t rows = 0, used = 0, invalid = 0, unmatched = 0, out_of_range = 0;
  double sum_sq = 0, max_err = 0, sum_nees = 0;
  std::size_t nees_n = 0;
  for (std::size_t i = 0; i < est.num_rows(); ++i) {
    ++rows;
    if (valid_col && est.integer(i, *valid_col) == 0) {
      ++invalid;
      continue;
    }
    const auto it = truth_at.find(std::llround(est.number(i, te) * 1e9));
    if (it == truth_at.end()) {
      ++unmatched;
      continue;
    }
    const std::size_t j = it->second;
    const Eigen::Vector3d p_true(truth.number(j, pt.x), truth.number(j, pt.y), truth.number(j, pt.z));
    if (!sensors.empty()) {
      double best = 1e300;
      for (const auto& s : sensors) best = std::min(best, (p_true - s).head<2>().norm());
      if (best > a.max_range_m) {
        ++out_of_range;
        continue;
      }
    }
    const Eigen::Vector3d p(est.number(i, pe.x), est.number(i, pe.y), est.number(i, pe.z));
    const Eigen::Vector3d e = p - p_true;
    sum_sq += e.squaredNorm();
    max_err = std::max(max_err, e.norm());
    ++used;
    if (has_sigma) {
      const Eigen::Vector3d s(est.number(i, ps.x), est.number(i, ps.y), est.number(i, ps.z));
      if ((s.array() > 0).all()) {
        sum_nees += (e.array() / s.array()).square().sum();
        ++nees_n;
      }
    }
  }
  std::printf("rows %zu: used %zu, invalid %zu, no truth at that time %zu, beyond range %zu\n", rows, used, invalid,
              unmatched, out_of_range);
  if (used == 0) throw InputError(a.estimate + ": no estimate row could be compared with " + a.truth);
  std::printf("position error: RMS %.4g m, max %.4g m\n", std::sqrt(sum_sq / used), max_err);
  if (nees_n > 0) {
    std::printf("mean NEES (diagonal sigmas, 3 dof): %.3g over %zu epochs\n", sum_nees / nees_n, nees_n);
  }
}

}  // namespace

void AddEvaluateCommand(CLI::App& app) {
  auto args = std::make_shared<EvaluateArgs>();
  CLI::App* sub = app.add_subcommand("evaluate", "Position error of estimates (invert/track/record output) against truth");
  sub->add_option("--estimate", args->estimate, "CSV with t and dipole_x..z or x..z (and optional valid, sigma_x..z)")
      ->required();
  sub->add_option("--truth", args->truth, "truth CSV with t,x,y,z (e.g. magnav simulate --truth)")->required();
  sub->add_option("--max-range", args->max_range_m, "use only epochs within this horizontal range of a sensor, m")
      ->check(CLI::PositiveNumber);
  sub->add_option("--sensors", args->sensors, "sensor positions X,Y,Z[;X,Y,Z...] for --max-range");
  sub->add_option("--pass", args->pass, "pass file whose sensors are used for --max-range (instead of --sensors)");
  sub->add_option("--gate", args->gate_m,
                  "multi-vessel truth (vessel_id): a row farther than this from every vessel is a false row, m")
      ->check(CLI::PositiveNumber);
  sub->callback([args] { Run(*args); });
}

}  // namespace magnav::tools
