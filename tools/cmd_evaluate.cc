// magnav evaluate: position error of an estimate file (magnav invert / track
// output, or a recorded dipole_fix / track topic) against a truth file; with a
// multi-vessel truth (vessel_id column), multi-track scores per vessel.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include <Eigen/Cholesky>

#include "association.h"
#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gospa.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/nees.h"

namespace magnav::tools {
namespace {

struct EvaluateArgs {
  std::string estimate, truth, sensors, pass;
  double max_range_m = 0.0;  // 0 = every epoch
  double reach_m = 15.0;     // NEES regimes: "inside" within this of a sensor (horizontal)
  double gate_m = 5.0;       // multi-track: a row farther than this from every vessel is false
  double gospa_c_m = 10.0, gospa_p = 2.0;
  std::string gospa_csv;     // per-epoch GOSPA, if given
  std::string nees;          // --nees: NEES rows (run,epoch,regime,nees[,error_sq]) instead of estimate/truth
  int dof = 0;               // --dof: degrees of freedom of those NEES values
};

struct Xyz {
  std::size_t x, y, z;
};

Xyz PositionColumns(const CsvTable& t) {
  if (t.has_column("dipole_x")) return {t.column("dipole_x"), t.column("dipole_y"), t.column("dipole_z")};
  return {t.column("x"), t.column("y"), t.column("z")};
}

// The 3-D position covariance of an estimate row, for its NEES eᵀ P⁻¹ e:
// the full 3×3 from sigma_x..z and cov_xy, cov_xz, cov_yz when the file has
// those columns and the row fills them (magnav track, magnav invert, a
// recorded track or dipole_fix topic), the diagonal of sigma_x..z otherwise.
class PositionCovariance {
 public:
  explicit PositionCovariance(const CsvTable& est) : est_(est) {
    if (est.has_column("sigma_x")) sigma_ = Xyz{est.column("sigma_x"), est.column("sigma_y"), est.column("sigma_z")};
    if (sigma_ && est.has_column("cov_xy") && est.has_column("cov_xz") && est.has_column("cov_yz")) {
      cov_ = Xyz{est.column("cov_xy"), est.column("cov_xz"), est.column("cov_yz")};
    }
  }
  bool has_sigma() const { return sigma_.has_value(); }
  // "full 3x3 covariance" or "diagonal sigmas", as the NEES lines say.
  const char* kind() const { return cov_ ? "full 3x3 covariance" : "diagonal sigmas"; }
  // NEES of error e at row i; nullopt when the row has no usable covariance
  // (a σ not > 0, or a full P that is not positive definite).
  std::optional<double> Nees(std::size_t i, const Eigen::Vector3d& e) const {
    if (!sigma_) return std::nullopt;
    const Eigen::Vector3d s(est_.number(i, sigma_->x), est_.number(i, sigma_->y), est_.number(i, sigma_->z));
    if (!(s.array() > 0).all()) return std::nullopt;
    if (!cov_ || est_.text(i, cov_->x).empty()) return (e.array() / s.array()).square().sum();
    Eigen::Matrix3d P = s.array().square().matrix().asDiagonal();
    P(0, 1) = P(1, 0) = est_.number(i, cov_->x);
    P(0, 2) = P(2, 0) = est_.number(i, cov_->y);
    P(1, 2) = P(2, 1) = est_.number(i, cov_->z);
    const Eigen::LLT<Eigen::Matrix3d> llt(P);
    if (llt.info() != Eigen::Success) return std::nullopt;
    return e.dot(llt.solve(e));
  }

 private:
  const CsvTable& est_;
  std::optional<Xyz> sigma_, cov_;
};

// Mean NEES (3 dof, PositionCovariance) of the scored rows per regime (issue 24
// item 6): "coasting" = a track row whose `state` is coasting (magnav track:
// not detected at that epoch); every other row (confirmed, or start: a
// back-filled start row) "inside" (its true position
// within --reach of a sensor, horizontally) or "outside"; without sensor
// positions "not coasting". A file without a `state` column (older track
// files, fixes, a recorded track topic) has no coasting rows.
class RegimeNees {
 public:
  RegimeNees(const EvaluateArgs& a, const CsvTable& est, const std::vector<Eigen::Vector3d>& sensors)
      : est_(est), cov_(est), sensors_(sensors), reach_m_(a.reach_m), state_(est.find_column("state")) {}
  // Row i of the estimate, error e against the true position p_true.
  void Add(std::size_t i, const Eigen::Vector3d& e, const Eigen::Vector3d& p_true) {
    const std::optional<double> nees = cov_.Nees(i, e);
    if (!nees) return;
    Sum& r = sums_[Regime(i, p_true)];
    r.nees += *nees;
    r.error_sq += e.squaredNorm();
    ++r.n;
  }
  void Print() const {
    if (!cov_.has_sigma()) return;
    std::printf("mean NEES per regime (%s, 3 dof; %s):\n", cov_.kind(),
                !state_ ? "no state column: no coasting rows"
                        : "coasting: state = coasting, the others by the true position");
    for (const char* name : {"inside", "outside", "not coasting", "coasting"}) {
      const auto it = sums_.find(name);
      if (it == sums_.end()) continue;
      const Sum& r = it->second;
      std::printf("  regime %s: %.3g over %zu rows, RMS %.4g m\n", name, r.nees / r.n, r.n,
                  std::sqrt(r.error_sq / r.n));
    }
  }

 private:
  struct Sum {
    double nees = 0.0, error_sq = 0.0;
    std::size_t n = 0;
  };
  std::string Regime(std::size_t i, const Eigen::Vector3d& p_true) const {
    if (state_) {
      const std::string_view v = est_.text(i, *state_);
      if (v == "coasting") return "coasting";
      if (v != "confirmed" && v != "start") {
        throw InputError(est_.source() + ":" + std::to_string(est_.line_of(i)) +
                         ": column 'state': expected confirmed, coasting or start, got '" + std::string(v) + "'");
      }
    }
    if (sensors_.empty()) return "not coasting";
    double best = 1e300;
    for (const auto& s : sensors_) best = std::min(best, (p_true - s).head<2>().norm());
    return best <= reach_m_ ? "inside" : "outside";
  }
  const CsvTable& est_;
  PositionCovariance cov_;
  const std::vector<Eigen::Vector3d>& sensors_;
  double reach_m_;
  std::optional<std::size_t> state_;
  std::map<std::string, Sum> sums_;
};

// Multi-vessel scoring (truth with vessel_id). Track files (t, track_id,
// x..z, usable): each usable row goes to the nearest vessel at its time (3-D)
// or, farther than the gate from all, counts as false. Per vessel over its
// in-field instants (within max_range of a sensor, horizontally; all without
// --max-range): coverage = share of instants with a row assigned to it,
// purity = share of its rows carrying its most frequent track_id, RMS/max of
// its in-field rows' errors; overrun = time of the last row of its main track
// − its last in-field instant (> 0: the track went on after the vessel left
// the sensors' reach; < 0: it ended before). GOSPA per truth epoch (at the
// end; core/gospa.h). Fix files (magnav invert: a `valid` column, several fixes per
// instant): a rejected fix (valid = 0, position possibly empty) is counted,
// not scored; each valid fix is scored against the nearest vessel at its time.
// `est` null: a track file with no row whose summary says "no track" (magnav
// track found nothing to track): every vessel in scope is missed.
void RunMulti(const EvaluateArgs& a, const CsvTable* est, const CsvTable& truth,
              const std::vector<Eigen::Vector3d>& sensors) {
  const Xyz pt = PositionColumns(truth);
  const std::size_t tt = truth.column("t"), vid = truth.column("vessel_id");
  const bool fix_file = est != nullptr && est->has_column("valid");
  // Truth: time (ns) -> vessel -> position.
  std::map<long long, std::map<long long, Eigen::Vector3d>> truth_at;
  std::map<long long, double> truth_t_s;  // the time as the truth file writes it
  for (std::size_t i = 0; i < truth.num_rows(); ++i) {
    const long long t_ns = std::llround(truth.number(i, tt) * 1e9);
    truth_at[t_ns][truth.integer(i, vid)] =
        Eigen::Vector3d(truth.number(i, pt.x), truth.number(i, pt.y), truth.number(i, pt.z));
    truth_t_s.emplace(t_ns, truth.number(i, tt));
  }
  const auto in_field = [&](const Eigen::Vector3d& p) {
    if (sensors.empty() || a.max_range_m <= 0) return true;
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
  // GOSPA's estimates per truth time: every scored row except those whose
  // vessel (nearest, within the gate) is beyond --max-range.
  std::map<long long, std::vector<Eigen::Vector3d>> gospa_est;
  std::size_t rows = 0, false_rows = 0, unmatched = 0, skipped = 0;
  const std::size_t num_rows = est != nullptr ? est->num_rows() : 0;
  const Xyz pe = est != nullptr ? PositionColumns(*est) : Xyz{0, 0, 0};
  const std::size_t te = est != nullptr ? est->column("t") : 0;
  const auto tid = est != nullptr ? est->find_column("track_id") : std::nullopt;
  const auto usable =
      est == nullptr ? std::nullopt : fix_file ? est->find_column("valid") : est->find_column("usable");
  std::optional<RegimeNees> regimes;
  if (est != nullptr && !fix_file) regimes.emplace(a, *est, sensors);
  for (std::size_t i = 0; i < num_rows; ++i) {
    if (usable && est->integer(i, *usable) == 0) {
      ++skipped;
      continue;
    }
    ++rows;
    const long long t = std::llround(est->number(i, te) * 1e9);
    const auto it = truth_at.find(t);
    if (it == truth_at.end()) {
      ++unmatched;
      continue;
    }
    const Eigen::Vector3d p(est->number(i, pe.x), est->number(i, pe.y), est->number(i, pe.z));
    const auto nearest = FindNearestVessel(it->second, p);  // association.h, shared with magnav plot
    const long long best_v = nearest ? nearest->vessel_id : -1;
    const double best = nearest ? nearest->distance_m : 1e300;
    if (best > a.gate_m) {
      ++false_rows;
      gospa_est[t].push_back(p);
      continue;
    }
    Vessel& ve = vessels[best_v];
    const long long id = tid ? est->integer(i, *tid) : 0;
    ++ve.ids[id];
    ve.id_last[id] = std::max(ve.id_last.count(id) ? ve.id_last[id] : -1e300, t * 1e-9);
    if (!in_field(it->second.at(best_v))) continue;
    if (regimes) regimes->Add(i, p - it->second.at(best_v), it->second.at(best_v));
    gospa_est[t].push_back(p);
    ++ve.rows;
    ve.sum_sq += best * best;
    ve.max_err = std::max(ve.max_err, best);
    if (ve.covered_at.insert(t).second) ++ve.covered;
  }
  if (fix_file) {
    std::printf("fixes %zu: valid %zu, rejected %zu (valid = 0: counted, not scored); each valid fix scored against "
                "the nearest truth vessel at its time: %zu false (farther than %.3g m from every vessel, %.2f %%), "
                "%zu at no truth time\n",
                rows + skipped, rows, skipped, false_rows, a.gate_m,
                rows > 0 ? 100.0 * false_rows / rows : 0.0, unmatched);
    for (const auto& [v, ve] : vessels) {
      std::printf("vessel %lld: in-field instants %zu, fixes %zu at %zu of them (coverage %.4f), RMS %.4g m, "
                  "max %.4g m\n",
                  v, ve.instants, ve.rows, ve.covered,
                  ve.instants > 0 ? static_cast<double>(ve.covered) / ve.instants : 0.0,
                  ve.rows > 0 ? std::sqrt(ve.sum_sq / ve.rows) : 0.0, ve.max_err);
    }
    std::printf("GOSPA: not computed for single-sample fixes (one per sensor and instant, not one per vessel)\n");
    if (rows == 0) throw InputError(a.estimate + ": no valid fix");
    return;
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
  if (regimes) regimes->Print();
  if (rows == 0 && est != nullptr) throw InputError(a.estimate + ": no usable estimate row");
  if (est == nullptr) {
    std::printf("the track file has no row (its summary: no track): every vessel in scope is missed\n");
  }
  // GOSPA per truth epoch: the vessels in scope (within --max-range of a
  // sensor; all without it) against the rows above. Epochs with neither are
  // left out (as Stone Soup scores only times at which some state exists).
  const GospaOptions go{a.gospa_c_m, a.gospa_p};
  std::unique_ptr<CsvWriter> csv;
  if (!a.gospa_csv.empty()) {
    csv = std::make_unique<CsvWriter>(
        a.gospa_csv, std::vector<std::string>{"t", "gospa", "localisation", "missed", "false"},
        std::vector<std::pair<std::string, std::string>>{
            {"source", a.estimate + " against " + a.truth},
            {"gospa", "c = " + FormatNumber(go.c_m) + " m, p = " + FormatNumber(go.p) +
                          ", alpha = 2; gospa in m; localisation, missed, false in m^p (gospa^p is their sum)"}});
  }
  std::size_t epochs = 0;
  double sum_g = 0.0, sum_loc = 0.0, sum_miss = 0.0, sum_false = 0.0, max_g = 0.0;
  std::size_t n_missed = 0, n_false = 0;
  const std::vector<Eigen::Vector3d> none;
  for (const auto& [t, vs] : truth_at) {
    std::vector<Eigen::Vector3d> x;
    for (const auto& [v, p] : vs) {
      if (in_field(p)) x.push_back(p);
    }
    const auto e = gospa_est.find(t);
    const std::vector<Eigen::Vector3d>& y = e == gospa_est.end() ? none : e->second;
    if (x.empty() && y.empty()) continue;
    const GospaResult g = ComputeGospa(x, y, go);
    ++epochs;
    sum_g += g.gospa;
    max_g = std::max(max_g, g.gospa);
    sum_loc += g.localisation;
    sum_miss += g.missed;
    sum_false += g.false_;
    n_missed += static_cast<std::size_t>(g.num_missed);
    n_false += static_cast<std::size_t>(g.num_false);
    if (csv) {
      csv->WriteRow({FormatNumber(truth_t_s.at(t)), FormatNumber(g.gospa), FormatNumber(g.localisation),
                     FormatNumber(g.missed), FormatNumber(g.false_)});
    }
  }
  if (csv) csv->Close();
  const double n = epochs > 0 ? static_cast<double>(epochs) : 1.0;
  std::printf("GOSPA (c %.3g m, p %.3g, alpha 2) over %zu epochs: mean %.4g m, max %.4g m; per epoch, mean "
              "localisation %.4g m^%.3g, missed %.4g m^%.3g (%.4g vessels), false %.4g m^%.3g (%.4g estimates)\n",
              go.c_m, go.p, epochs, sum_g / n, max_g, sum_loc / n, go.p, sum_miss / n, go.p, n_missed / n,
              sum_false / n, go.p, n_false / n);
}

// The `# summary:` of a file CsvTable refused for having no data row, if it
// says "no track" (magnav track's file when nothing was to track); else "".
std::string NoTrackSummary(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  for (int n = 0; n < 10000 && std::getline(in, line); ++n) {
    if (line.rfind("# summary: no track", 0) == 0) return line.substr(11);
  }
  return "";
}

// Sensor positions (magnav localize / magnav-localizer: sensor_id, x, y,
// sigma_x, sigma_y, crlb_x, crlb_y, and cov_xy when written) against the true sensors (sensor_id, x,
// y): horizontal errors (z is the known deployment depth), per sensor and
// overall, against the estimate's own sigma and the Cramér–Rao bound.
void RunSensors(const EvaluateArgs& a, const CsvTable& est, const CsvTable& truth) {
  if (a.max_range_m > 0 || !a.gospa_csv.empty()) {
    throw InputError("--max-range and --gospa do not apply to sensor positions");
  }
  const std::size_t ie = est.column("sensor_id"), xe = est.column("x"), ye = est.column("y");
  const std::size_t it = truth.column("sensor_id"), xt = truth.column("x"), yt = truth.column("y");
  const bool has_sigma = est.has_column("sigma_x") && est.has_column("sigma_y");
  const bool has_crlb = est.has_column("crlb_x") && est.has_column("crlb_y");
  const bool has_cov_xy = est.has_column("cov_xy");  // magnav localize: the full 2x2 with sigma_x, sigma_y
  std::map<std::uint32_t, Eigen::Vector2d> truth_of;
  for (std::size_t j = 0; j < truth.num_rows(); ++j) {
    if (!truth_of.emplace(truth.uint32(j, it), Eigen::Vector2d(truth.number(j, xt), truth.number(j, yt))).second) {
      throw InputError(a.truth + ": sensor " + std::to_string(truth.uint32(j, it)) + " is listed twice");
    }
  }
  std::map<std::uint32_t, std::size_t> last_row;  // a recorded topic has many rows per sensor: the last counts
  for (std::size_t i = 0; i < est.num_rows(); ++i) last_row[est.uint32(i, ie)] = i;
  double sum_sq = 0, max_err = 0, sum_nees = 0, sum_bound_sq = 0;
  std::size_t n = 0, nees_n = 0, within_2sigma = 0, unknown = 0;
  std::printf("sensor  error_m  sigma_m  error/sigma  bound_m  error/bound\n");
  for (const auto& [id, i] : last_row) {
    const auto t = truth_of.find(id);
    if (t == truth_of.end()) {
      ++unknown;
      continue;
    }
    const Eigen::Vector2d e = Eigen::Vector2d(est.number(i, xe), est.number(i, ye)) - t->second;
    const double err = e.norm();
    sum_sq += e.squaredNorm();
    max_err = std::max(max_err, err);
    ++n;
    double sigma = std::nan(""), bound = std::nan("");
    if (has_sigma) {
      const Eigen::Vector2d s(est.number(i, est.column("sigma_x")), est.number(i, est.column("sigma_y")));
      sigma = s.norm();
      const double cxy = has_cov_xy ? est.number(i, est.column("cov_xy")) : 0.0;
      const double det = s.x() * s.x() * s.y() * s.y() - cxy * cxy;
      if ((s.array() > 0).all() && det > 0) {
        sum_nees += (s.y() * s.y() * e.x() * e.x() - 2.0 * cxy * e.x() * e.y() + s.x() * s.x() * e.y() * e.y()) / det;
        ++nees_n;
        within_2sigma += (e.array().abs() <= 2.0 * s.array()).all() ? 1 : 0;
      }
    }
    if (has_crlb) {
      bound = Eigen::Vector2d(est.number(i, est.column("crlb_x")), est.number(i, est.column("crlb_y"))).norm();
      sum_bound_sq += bound * bound;
    }
    std::printf("%6u  %7.4f  %7.4f  %11.2f  %7.4f  %11.2f\n", id, err, sigma, err / sigma, bound, err / bound);
  }
  std::printf("sensors %zu scored, %zu not in the truth, %zu true sensors without an estimate\n", n, unknown,
              truth_of.size() > n ? truth_of.size() - n : 0);
  if (n == 0) throw InputError(a.estimate + ": no sensor could be compared with " + a.truth);
  std::printf("position error (horizontal): RMSE %.4g m, max %.4g m\n", std::sqrt(sum_sq / n), max_err);
  if (has_crlb) std::printf("Cramer-Rao bound (RMS over sensors): %.4g m\n", std::sqrt(sum_bound_sq / n));
  if (nees_n > 0) {
    std::printf("mean NEES (%s, 2 dof): %.3g over %zu sensors; both axes within 2 sigma: %zu of %zu\n",
                has_cov_xy ? "full 2x2 covariance" : "diagonal sigmas", sum_nees / nees_n, nees_n, within_2sigma,
                nees_n);
  }
}

// --nees: covariance consistency over Monte-Carlo runs (core/nees.h), per
// regime: ANEES and its [0.5, 2] x dof acceptance, the share of epochs whose
// run-averaged NEES is inside its two-sided 95 % chi-square interval, RMS.
void RunNees(const EvaluateArgs& a) {
  if (!a.estimate.empty() || !a.truth.empty()) throw InputError("--nees: give no --estimate or --truth");
  if (a.dof < 1) throw InputError("--nees needs --dof N (N >= 1: the dimension of the estimate)");
  const CsvTable t = CsvTable::Read(a.nees);
  const std::size_t run = t.column("run"), epoch = t.column("epoch"), regime = t.column("regime"),
                    nees = t.column("nees");
  const auto e2 = t.find_column("error_sq");
  std::vector<NeesSample> samples;
  samples.reserve(t.num_rows());
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    NeesSample s{t.integer(i, run), t.integer(i, epoch), std::string(t.text(i, regime)), 0.0, 0.0};
    // "inf": a singular covariance (counted, makes the ANEES infinite); any other value must be finite and >= 0.
    const std::string v(t.text(i, nees));
    s.nees = v == "inf" ? std::numeric_limits<double>::infinity() : t.number(i, nees);
    if (!(s.nees >= 0.0)) {
      throw InputError(t.source() + ":" + std::to_string(t.line_of(i)) + ": column 'nees': must be >= 0 or inf");
    }
    if (e2) {
      s.error_sq = t.number(i, *e2);
      if (!(s.error_sq >= 0.0)) {
        throw InputError(t.source() + ":" + std::to_string(t.line_of(i)) + ": column 'error_sq': must be >= 0");
      }
    }
    samples.push_back(std::move(s));
  }
  if (samples.empty()) throw InputError(a.nees + ": no data rows");
  const auto stats = ComputeNeesStats(samples, a.dof);
  std::printf("NEES over runs, %d dof: ANEES accepted within [%.3g, %.3g]; per epoch, the run-averaged NEES against "
              "its two-sided 95 %% chi-square interval (epochs with >= 2 runs)\n",
              a.dof, 0.5 * a.dof, 2.0 * a.dof);
  for (const auto& [name, r] : stats) {
    std::printf("regime %s: runs %zu, epochs %zu, values %zu, ANEES %.4g (%s), inside 95 %% %zu of %zu epochs "
                "(%.1f %%)",
                name.c_str(), r.runs, r.epochs, r.samples, r.anees, r.anees_accepted ? "accepted" : "NOT accepted",
                r.epochs_inside, r.epochs_tested, 100.0 * r.share_inside());
    if (e2) std::printf(", RMS %.4g", r.rms);
    std::printf("\n");
  }
}

void Run(const EvaluateArgs& a) {
  if (!a.nees.empty()) {
    RunNees(a);
    return;
  }
  if (a.estimate.empty() || a.truth.empty()) throw InputError("give --estimate and --truth (or --nees)");
  const CsvTable truth = CsvTable::Read(a.truth);
  std::optional<CsvTable> est_or_none;
  try {
    est_or_none = CsvTable::Read(a.estimate);
  } catch (const InputError& e) {
    // An empty track file is a result against a multi-vessel truth.
    if (std::string(e.what()).find(": no data rows") == std::string::npos || !truth.has_column("vessel_id") ||
        NoTrackSummary(a.estimate).empty()) {
      throw;
    }
  }
  std::vector<Eigen::Vector3d> sensors;
  if (!a.sensors.empty() && !a.pass.empty()) throw InputError("give --sensors or --pass, not both");
  if (a.max_range_m > 0 && a.sensors.empty() && a.pass.empty()) {
    throw InputError("--max-range needs --sensors X,Y,Z[;X,Y,Z...] or --pass PASS.csv");
  }
  // Sensor positions: for --max-range and the NEES regimes (inside/outside --reach).
  if (!a.sensors.empty()) {
    sensors = cli::ParseVec3List("--sensors", a.sensors);
  } else if (!a.pass.empty()) {
    std::map<std::uint32_t, Eigen::Vector3d> by_id;
    for (const auto& s : ReadGradiometerFile(a.pass).samples) by_id.emplace(s.sensor_id, s.p_SinW);
    for (const auto& [id, p] : by_id) sensors.push_back(p);
  }
  if (!a.gospa_csv.empty()) {
    RefuseOutputOverInput(a.gospa_csv, {a.estimate, a.truth, a.pass});
    if (!truth.has_column("vessel_id") || (est_or_none && est_or_none->has_column("valid"))) {
      throw InputError("--gospa needs a track file (not single-sample fixes) and a multi-vessel truth (vessel_id)");
    }
  }
  if (truth.has_column("vessel_id")) {
    RunMulti(a, est_or_none ? &*est_or_none : nullptr, truth, sensors);
    return;
  }
  if (truth.has_column("sensor_id") && !truth.has_column("t")) {
    if (!est_or_none) throw InputError(a.estimate + ": no data rows");
    RunSensors(a, *est_or_none, truth);
    return;
  }
  const CsvTable& est = *est_or_none;
  const Xyz pe = PositionColumns(est), pt = PositionColumns(truth);
  const std::size_t te = est.column("t"), tt = truth.column("t");
  // A row marked not valid (fixes) or not usable (tracks) is not scored.
  const auto valid_col = est.has_column("valid") ? est.find_column("valid") : est.find_column("usable");
  const PositionCovariance cov(est);
  // Truth by time, in ns to match exactly.
  std::map<long long, std::size_t> truth_at;
  for (std::size_t i = 0; i < truth.num_rows(); ++i) truth_at[std::llround(truth.number(i, tt) * 1e9)] = i;

  RegimeNees regimes(a, est, sensors);
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
    if (a.max_range_m > 0) {
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
    regimes.Add(i, e, p_true);
    if (const std::optional<double> nees = cov.Nees(i, e)) {
      sum_nees += *nees;
      ++nees_n;
    }
  }
  std::printf("rows %zu: used %zu, invalid %zu, no truth at that time %zu, beyond range %zu\n", rows, used, invalid,
              unmatched, out_of_range);
  if (used == 0) throw InputError(a.estimate + ": no estimate row could be compared with " + a.truth);
  std::printf("position error: RMS %.4g m, max %.4g m\n", std::sqrt(sum_sq / used), max_err);
  if (nees_n > 0) {
    std::printf("mean NEES (%s, 3 dof): %.3g over %zu epochs\n", cov.kind(), sum_nees / nees_n, nees_n);
  }
  regimes.Print();
}

// What every printed figure means (--help; docs/ACCURACY.md "Scoring").
constexpr const char* kEvaluateFigures = R"(Figures printed:
One-vessel truth (t,x,y,z), estimate = fixes (magnav invert) or a track:
  rows: estimate rows; used: compared with the truth (same t to 1 ns, valid/usable,
    within --max-range); invalid: valid = 0 or usable = 0; no truth at that time;
    beyond range: the true position farther than --max-range (horizontal) from every sensor.
  position error RMS / max: sqrt(mean |p - p_true|^2) and the largest |p - p_true| over used rows, m.
  mean NEES (full 3x3 covariance | diagonal sigmas, 3 dof): mean over used rows with sigma_x..z > 0
    of e' P^-1 e, P the full 3x3 from sigma_x..z and cov_xy, cov_xz, cov_yz when the file has them
    (magnav track, magnav invert, a recorded track topic; rows whose P is not positive definite left
    out), else diag(sigma_x^2, sigma_y^2, sigma_z^2); 3 when the covariance is honest.
  mean NEES per regime (also for a multi-vessel truth, over the rows scored): coasting = rows whose
    state column (magnav track) says coasting (the track not detected at that epoch); the other rows
    inside = the true position within --reach (15 m) of a sensor horizontally (--pass or --sensors),
    outside = farther; without sensor positions "not coasting". RMS per regime, m. A file without a
    state column (older track files, a recorded track topic) has no coasting rows.
Sensor positions (estimate: magnav localize output or a recorded sensor_position topic, the last row
of each sensor; truth: sensor_id,x,y[,z], e.g. localize_truth_sensors.csv), horizontal only (z is the
known deployment depth):
  per sensor: error_m = |(x,y) - truth|; sigma_m = |(sigma_x, sigma_y)|; bound_m = |(crlb_x, crlb_y)|
    (the joint Cramer-Rao bound); error/sigma and error/bound their ratios.
  RMSE / max over sensors, m; the bound's RMS over sensors, m.
  mean NEES (diagonal sigmas, 2 dof): mean over sensors of (e_x/sigma_x)^2 + (e_y/sigma_y)^2 (2 when honest;
    one pass gives one draw per sensor: a loose check); both axes within 2 sigma: count of sensors.
Multi-vessel truth (vessel_id), track file (track_id):
  rows (+ not usable): usable rows scored; each goes to the nearest vessel at its time (3-D);
  false: farther than --gate from every vessel (share of the rows); at no truth time: no truth row at its t.
  in-field instants: truth instants of the vessel within --max-range of a sensor (all without it).
  coverage: share of its in-field instants with at least one row assigned to it.
  track / purity / track ids: its most frequent track_id among its rows, that id's share of its rows,
    the number of distinct ids among them.
  RMS / max: error of its rows at in-field instants, m.
  overrun: time of the last row of its main track minus its last in-field instant, s
    (> 0: the track went on after the vessel left the sensors' reach; < 0: it ended before;
    0 when the vessel has no row or no in-field instant).
  GOSPA (c, p, alpha 2; Stone Soup's convention): per truth epoch, vessels in scope (in field) X against
    the rows Y at that time (rows of an out-of-field vessel left out; false rows kept):
    GOSPA = (min over one-to-one pairings of sum min(d,c)^p + c^p/2 per unpaired vessel or row)^(1/p), m;
    a pair with d >= c counts as one missed vessel and one false row. localisation = sum d^p over pairs
    with d < c, missed = c^p/2 per missed vessel, false = c^p/2 per false row (m^p, sum = GOSPA^p).
    Printed: mean and max of GOSPA over epochs with a vessel in scope or a row, and the mean of each
    component per epoch (with the mean number of missed vessels and false rows). --gospa FILE: per epoch.
--nees FILE --dof N (no estimate or truth; scripts/calibration writes FILE): columns run,epoch,regime,nees
[,error_sq] (nees = e' P^-1 e of one estimate, "inf" for a singular P; error_sq = |e|^2), per regime and "all":
  runs / epochs / values: distinct runs, distinct epochs, rows.
  ANEES: mean NEES over every row (Bar-Shalom's average over runs and time); accepted within [0.5, 2] x N.
  inside 95 %: epochs (with >= 2 runs) whose run-averaged NEES lies in [chi2inv(0.025, n N), chi2inv(0.975, n N)] / n,
    n = the runs with a value at that epoch (about 95 % when the covariance is right).
  RMS: sqrt(mean error_sq), in the unit of the estimate.
Multi-vessel truth, fix file (valid column, magnav invert):
  fixes: valid and rejected (valid = 0, counted, not scored); each valid fix scored against the nearest
  vessel at its time: false as above; per vessel: fixes at in-field instants, the instants they cover
  (coverage), RMS / max error, m. No GOSPA (several fixes per instant).)";

}  // namespace

void AddEvaluateCommand(CLI::App& app) {
  auto args = std::make_shared<EvaluateArgs>();
  CLI::App* sub = app.add_subcommand("evaluate", "Position error of estimates (invert/track/record output) against truth");
  sub->add_option("--estimate", args->estimate,
                  "fixes (magnav invert: t, dipole_x..z, valid, sigma_x..z), a track (magnav track: t, track_id, "
                  "x..z, sigma_x..z) or a recorded dipole_fix / track topic (required unless --nees)");
  sub->add_option("--truth", args->truth,
                  "truth CSV with t,x,y,z, or t,vessel_id,x,y,z for several vessels (magnav simulate --truth), or "
                  "sensor_id,x,y,z for sensor positions (magnav localize output as the estimate); required unless --nees");
  sub->add_option("--nees", args->nees,
                  "instead of --estimate/--truth: NEES rows run,epoch,regime,nees[,error_sq] (scripts/calibration): "
                  "ANEES per regime, its [0.5, 2] x dof acceptance and the share of epochs inside the 95 % "
                  "chi-square interval");
  sub->add_option("--dof", args->dof, "with --nees: degrees of freedom of each NEES value")->check(CLI::PositiveNumber);
  sub->add_option("--max-range", args->max_range_m, "use only epochs within this horizontal range of a sensor, m")
      ->check(CLI::PositiveNumber);
  sub->add_option("--sensors", args->sensors,
                  "sensor positions X,Y,Z[;X,Y,Z...] for --max-range and the NEES regimes (--reach)");
  sub->add_option("--pass", args->pass,
                  "pass file whose sensors are used for --max-range and the NEES regimes (instead of --sensors)");
  sub->add_option("--reach", args->reach_m,
                  "NEES regimes: a row is 'inside' when its true position is within this horizontal range of a "
                  "sensor, 'outside' when farther (coasting rows apart), m")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  sub->add_option("--gate", args->gate_m,
                  "multi-vessel truth (vessel_id): a row farther than this from every vessel is a false row, m")
      ->check(CLI::PositiveNumber);
  sub->add_option("--gospa", args->gospa_csv,
                  "multi-vessel truth, track file: write the GOSPA of every epoch to this CSV "
                  "(t,gospa,localisation,missed,false)");
  sub->add_option("--gospa-c", args->gospa_c_m, "GOSPA cut-off distance c, m")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  sub->add_option("--gospa-p", args->gospa_p, "GOSPA order p (>= 1)")
      ->check(CLI::Range(1.0, 1e3))
      ->capture_default_str();
  sub->footer(kEvaluateFigures);
  sub->callback([args] { Run(*args); });
}

}  // namespace magnav::tools
