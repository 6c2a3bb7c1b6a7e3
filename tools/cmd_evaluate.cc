// magnav evaluate: position error of an estimate file (magnav invert / track
// output, or a recorded dipole_fix / track topic) against a truth file.
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"

namespace magnav::tools {
namespace {

struct EvaluateArgs {
  std::string estimate, truth, sensors;
  double max_range_m = 0.0;  // 0 = every epoch
};

struct Xyz {
  std::size_t x, y, z;
};

Xyz PositionColumns(const CsvTable& t) {
  if (t.has_column("dipole_x")) return {t.column("dipole_x"), t.column("dipole_y"), t.column("dipole_z")};
  return {t.column("x"), t.column("y"), t.column("z")};
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
  if (a.max_range_m > 0) {
    if (a.sensors.empty()) throw InputError("--max-range needs --sensors X,Y,Z[;X,Y,Z...]");
    sensors = cli::ParseVec3List("--sensors", a.sensors);
  } else if (!a.sensors.empty()) {
    throw InputError("--sensors is used only with --max-range");
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
  sub->callback([args] { Run(*args); });
}

}  // namespace magnav::tools
