#include "magnav/mapmatch/fast_msd.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "magnav/core/csv.h"
#include "magnav/core/option_check.h"
#include "magnav/mapmatch/correlation.h"
#include "fast_msd_basins.h"
#include "fast_msd_covariance.h"
#include "match_common.h"

namespace magnav::mapmatch {

namespace {

// One round's linearisation around the reference path.
struct Linearisation {
  explicit Linearisation(std::size_t n) : g_lat(n), g_lon(n), resid(n), data(n) {}
  std::vector<double> g_lat, g_lon;  // ∇m at r_i, nT/deg
  std::vector<double> resid;         // m_i − l_i, nT
  std::vector<char> data;            // point has a data term (on the map, finite measurement)
};

// The paper's Jacobi iteration from e = 0 until the mean squared change < ε:
// e_i ← ē_i − g (g·ē_i + m_i − l_i)/(λ + |g|²). Returns (iterations, converged).
std::pair<int, bool> JacobiRound(const Linearisation& lin, double lambda, const FastMsdOptions& options,
                                 std::vector<double>* e_lat_out, std::vector<double>* e_lon_out) {
  std::vector<double>& e_lat = *e_lat_out;
  std::vector<double>& e_lon = *e_lon_out;
  const std::size_t n = e_lat.size();
  std::vector<double> nxt_lat(n), nxt_lon(n);
  for (int it = 1; it <= options.max_iterations_per_round; ++it) {
    double change2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      double mlat, mlon;  // ē_i; the end points have one neighbour
      if (n == 1) {
        mlat = e_lat[i];
        mlon = e_lon[i];
      } else if (i == 0) {
        mlat = e_lat[1];
        mlon = e_lon[1];
      } else if (i == n - 1) {
        mlat = e_lat[n - 2];
        mlon = e_lon[n - 2];
      } else {
        mlat = 0.5 * (e_lat[i - 1] + e_lat[i + 1]);
        mlon = 0.5 * (e_lon[i - 1] + e_lon[i + 1]);
      }
      if (lin.data[i]) {
        const double gl = lin.g_lat[i], gn = lin.g_lon[i];
        const double k = (gl * mlat + gn * mlon + lin.resid[i]) / (lambda + gl * gl + gn * gn);
        mlat -= gl * k;
        mlon -= gn * k;
      }
      const double dl = mlat - e_lat[i], dn = mlon - e_lon[i];
      change2 += dl * dl + dn * dn;
      nxt_lat[i] = mlat;
      nxt_lon[i] = mlon;
    }
    e_lat.swap(nxt_lat);
    e_lon.swap(nxt_lon);
    if (change2 / static_cast<double>(n) < options.epsilon_deg2) return {it, true};
  }
  return {options.max_iterations_per_round, false};
}

// The fixed point of the same iteration solved directly: the equations
//   (λ I + g gᵀ) e_i − λ ē_i = −g (m_i − l_i)
// are block-tridiagonal (2 × 2 blocks) in the path order: block Thomas
// elimination, O(N).
void DirectRound(const Linearisation& lin, double lambda, std::vector<double>* e_lat,
                 std::vector<double>* e_lon) {
  using M2 = Eigen::Matrix2d;
  using V2 = Eigen::Vector2d;
  const std::size_t n = e_lat->size();
  if (n == 1) {  // no neighbour: ē = e, so g gᵀ e = −g r, the least-norm e
    const V2 g(lin.g_lat[0], lin.g_lon[0]);
    const V2 e = lin.data[0] && g.squaredNorm() > 0.0 ? V2(-g * lin.resid[0] / g.squaredNorm()) : V2::Zero();
    (*e_lat)[0] = e(0);
    (*e_lon)[0] = e(1);
    return;
  }
  // Row i: A_i e_{i-1} + B_i e_i + C_i e_{i+1} = d_i (A, C multiples of I).
  std::vector<M2> c_prime(n);
  std::vector<V2> d_prime(n);
  for (std::size_t i = 0; i < n; ++i) {
    const V2 g(lin.g_lat[i], lin.g_lon[i]);
    M2 B = lambda * M2::Identity();
    V2 d = V2::Zero();
    if (lin.data[i]) {
      B += g * g.transpose();
      d = -g * lin.resid[i];
    }
    const double a = i == 0 ? 0.0 : (i == n - 1 ? -lambda : -0.5 * lambda);
    const double c = i == n - 1 ? 0.0 : (i == 0 ? -lambda : -0.5 * lambda);
    if (i > 0) {
      B -= a * c_prime[i - 1];
      d -= a * d_prime[i - 1];
    }
    const Eigen::PartialPivLU<M2> lu(B);
    c_prime[i] = lu.solve(c * M2::Identity());
    d_prime[i] = lu.solve(d);
  }
  V2 next = d_prime[n - 1];
  (*e_lat)[n - 1] = next(0);
  (*e_lon)[n - 1] = next(1);
  for (std::size_t i = n - 1; i-- > 0;) {
    next = d_prime[i] - c_prime[i] * next;
    (*e_lat)[i] = next(0);
    (*e_lon)[i] = next(1);
  }
}

}  // namespace

bool FastMsdOptions::IsValid(std::string* error) const {
  if (!PositiveFinite(lambda_nT2_per_deg2)) return Fail(error, "lambda_nT2_per_deg2 must be finite and > 0");
  if (lambda_from_path_iterations < 0) return Fail(error, "lambda_from_path_iterations must be >= 0 (0 = off)");
  if (!PositiveFinite(lambda_min_nT2_per_deg2) || !PositiveFinite(lambda_max_nT2_per_deg2) ||
      lambda_min_nT2_per_deg2 > lambda_max_nT2_per_deg2) {
    return Fail(error, "lambda_min_nT2_per_deg2 and lambda_max_nT2_per_deg2 must be finite, > 0 and min <= max");
  }
  if (!(std::isfinite(lambda_first_round_factor) && lambda_first_round_factor >= 1.0)) {
    return Fail(error, "lambda_first_round_factor must be finite and >= 1");
  }
  if (!PositiveFinite(epsilon_deg2)) return Fail(error, "epsilon_deg2 must be finite and > 0");
  if (max_iterations_per_round < 1) return Fail(error, "max_iterations_per_round must be >= 1");
  if (rounds < 1) return Fail(error, "rounds must be >= 1");
  if (!internal::ValidOnMapFraction(min_on_map_fraction, error)) return false;
  if (!internal::ValidOutlierSigmas(outlier_sigmas, error)) return false;
  if (!(std::isfinite(search_window_deg) && search_window_deg >= 0.0)) {
    return Fail(error, "search_window_deg must be finite and >= 0 (0 = no coarse stage)");
  }
  if (!(std::isfinite(ambiguity_ratio) && ambiguity_ratio >= 0.0)) {
    return Fail(error, "ambiguity_ratio must be finite and >= 0 (0 = no ambiguity check)");
  }
  if (!(std::isfinite(peak_separation_deg) && peak_separation_deg >= 0.0)) {
    return Fail(error, "peak_separation_deg must be finite and >= 0");
  }
  if (!(std::isfinite(basin_half_width_deg) && basin_half_width_deg >= 0.0)) {
    return Fail(error, "basin_half_width_deg must be finite and >= 0 (0 = off)");
  }
  if (!PositiveFinite(basin_step_cells)) return Fail(error, "basin_step_cells must be finite and > 0");
  if (basin_full_mean && !basin_mean_shift) {
    return Fail(error, "basin_full_mean needs basin_mean_shift (it changes that shift's move)");
  }
  if (!(std::isfinite(basin_max_half_width_deg) && basin_max_half_width_deg >= 0.0)) {
    return Fail(error, "basin_max_half_width_deg must be finite and >= 0 (<= basin_half_width_deg = never widen)");
  }
  return true;
}

namespace {

constexpr double kChi2Two99 = 9.2103;  // 99 % point of χ² with 2 degrees of freedom
// basin_mean_shift: the largest posterior mass on the offset grid's outermost ring at which the grid is
// taken to hold the posterior (fast_msd.h). On the tuning and held-out paths (501-520, 601-640, 0.5 and
// 3 nT) the largest was 4.4e-4 but on one, 626 at 3 nT (0.085, its start 0.019 deg off, beyond the grid's
// 0.012 deg); any value in [1e-3, 5e-2] separates them alike.
constexpr double kMaxEdgeMass = 0.01;

// The map's Hessian (nT/deg²) at a point: central second differences of the
// grid at the nearest node (one node in from the edge), the curvature the
// bilinear interpolation's piecewise-constant gradient steps through.
void MapHessian(const GeoGrid& grid, std::size_t layer, double lat_deg, double lon_deg, double* h_ll, double* h_ln,
                double* h_nn) {
  const GridAxis& la = grid.lat();
  const GridAxis& lo = grid.lon();
  if (la.count < 3 || lo.count < 3) return;
  const int i = std::clamp(static_cast<int>(std::lround((lat_deg - la.first_deg) / la.step_deg)), 1, la.count - 2);
  const int j = std::clamp(static_cast<int>(std::lround((lon_deg - lo.first_deg) / lo.step_deg)), 1, lo.count - 2);
  const auto f = [&](int a, int b) { return grid.node(layer, a, b); };
  *h_ll = (f(i + 1, j) - 2.0 * f(i, j) + f(i - 1, j)) / (la.step_deg * la.step_deg);
  *h_nn = (f(i, j + 1) - 2.0 * f(i, j) + f(i, j - 1)) / (lo.step_deg * lo.step_deg);
  *h_ln = (f(i + 1, j + 1) - f(i + 1, j - 1) - f(i - 1, j + 1) + f(i - 1, j - 1)) / (4.0 * la.step_deg * lo.step_deg);
}

// basin_mean_shift's move of each point (deg, (lat, lon)), empty = none, and the points the score is over.
struct MeanShift {
  std::vector<Eigen::Vector2d> d;
  std::vector<char> scored;
  // The covariance about the moved point, deg² (basin_full_mean: the whole posterior's own spread).
  std::vector<Eigen::Matrix2d> cov;
};

// The rounds (and the robust refit) from one start path; `r` carries the
// counts so far; `mean_shift` (may be null) receives basin_mean_shift's move.
MatchResult Refine(const GeoGrid& grid, std::size_t layer, const MatchPath& path, const FastMsdOptions& options,
                  const std::vector<std::size_t>& finite, std::vector<char> usable,
                  const internal::RobustSpread& readings, const std::vector<double>& start_lat,
                  const std::vector<double>& start_lon, MatchResult r, MeanShift* mean_shift) {
  const std::size_t n = path.size();
  std::vector<double> ref_lat = start_lat, ref_lon = start_lon;
  // The last round's λ (nT²/deg²): the option's, or the path's own (lambda_from_path_iterations).
  double final_lambda = options.lambda_nT2_per_deg2;
  // The rounds from the start with the points of `use` (returns whether every round converged).
  int rounds_done = 0;
  const auto run_rounds = [&](const std::vector<char>& use) {
    ref_lat = start_lat;
    ref_lon = start_lon;
    rounds_done = 0;
    r.reason.clear();
    std::vector<double> e_lat(n), e_lon(n);
    Linearisation lin(n);
    bool all_converged = true;
    for (int round = 0; round < options.rounds; ++round) {
      std::size_t on = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const auto s = use[i] ? grid.Sample(layer, ref_lat[i], ref_lon[i]) : std::nullopt;
        lin.data[i] = s.has_value();
        if (s) {
          lin.g_lat[i] = s->dvalue_dlat_nT_per_deg;
          lin.g_lon[i] = s->dvalue_dlon_nT_per_deg;
          lin.resid[i] = s->value_nT - path.measured_nT[i];
          ++on;
        }
      }
      // Robust residuals (match_common.h rule 2): a residual beyond
      // outlier_sigmas · σ_l (the readings' spread) is no position error: that
      // point has no data term this round (it follows its neighbours, like a
      // point off the map).
      if (options.outlier_sigmas > 0.0) {
        for (std::size_t i = 0; i < n; ++i) {
          if (lin.data[i] && std::abs(lin.resid[i]) > options.outlier_sigmas * readings.sigma) lin.data[i] = 0;
        }
      }
      if (static_cast<double>(on) < options.min_on_map_fraction * static_cast<double>(finite.size()) || on == 0) {
        all_converged = false;
        r.reason = "round " + std::to_string(round + 1) + ": only " + std::to_string(on) + " of " +
                   std::to_string(finite.size()) + " points on the map (needs " +
                   FormatNumber(options.min_on_map_fraction) + "); stopped there";
        break;
      }
      const double lambda =
          final_lambda *
          (options.rounds > 1 ? std::pow(options.lambda_first_round_factor,
                                         static_cast<double>(options.rounds - 1 - round) / (options.rounds - 1))
                              : 1.0);
      std::fill(e_lat.begin(), e_lat.end(), 0.0);
      std::fill(e_lon.begin(), e_lon.end(), 0.0);
      bool round_converged = true;
      if (options.solver == FastMsdSolver::kJacobi) {
        const auto [iterations, converged] = JacobiRound(lin, lambda, options, &e_lat, &e_lon);
        r.iterations += iterations;
        round_converged = converged;
      } else {
        DirectRound(lin, lambda, &e_lat, &e_lon);
        ++r.iterations;
      }
      ++rounds_done;
      double step2 = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        ref_lat[i] += e_lat[i];
        ref_lon[i] += e_lon[i];
        step2 += e_lat[i] * e_lat[i] + e_lon[i] * e_lon[i];
      }
      if (!round_converged) {
        all_converged = false;
        r.reason = "round " + std::to_string(round + 1) + ": Jacobi change still >= epsilon after " +
                   std::to_string(options.max_iterations_per_round) + " iterations";
      }
      // Nothing left to re-linearise (only once λ has reached its final value).
      if (lambda == final_lambda && step2 / static_cast<double>(n) < options.epsilon_deg2) break;
    }
    return all_converged;
  };
  bool all_converged = run_rounds(usable);
  // Robust residuals (match_common.h rule 3): each point's leave-one-out
  // residual — its reading against the map at the mean of its neighbours'
  // matched positions (the path is smooth; a point's own data term can bend
  // the path onto a wrong reading, its neighbours' positions cannot) — beyond
  // outlier_sigmas robust sigmas (1.4826·MAD, at least 1 nT) of their median:
  // the point is left out and the rounds run again, once, from the same start.
  if (options.outlier_sigmas > 0.0 && n >= 3) {
    std::vector<std::pair<std::size_t, double>> resid;
    // Where the neighbours put point p: their mean inside, a straight-line extrapolation at the ends.
    const auto from_neighbours = [&](const std::vector<double>& x, std::size_t p) {
      if (p == 0) return 2.0 * x[1] - x[2];
      if (p == n - 1) return 2.0 * x[n - 2] - x[n - 3];
      return 0.5 * (x[p - 1] + x[p + 1]);
    };
    for (std::size_t p : finite) {
      if (const auto s = grid.Sample(layer, from_neighbours(ref_lat, p), from_neighbours(ref_lon, p))) {
        resid.emplace_back(p, s->value_nT - path.measured_nT[p]);
      }
    }
    std::vector<double> values;
    for (const auto& pr : resid) values.push_back(pr.second);
    const internal::RobustSpread spread = internal::RobustSpreadOf(values, internal::kOutlierSigmaFloor_nT);
    std::vector<char> use = usable;
    int dropped = 0;
    for (const auto& [p, d] : resid) {
      if (internal::IsOutlier(d, spread, options.outlier_sigmas)) use[p] = 0, ++dropped;
    }
    if (dropped > 0) {
      all_converged = run_rounds(use);
      usable = use;
      r.points_outlier += dropped;
      r.notes += std::string(r.notes.empty() ? "" : "; ") + "refit without " + std::to_string(dropped) +
                 " outlier" + (dropped == 1 ? "" : "s");
    }
  }
  // The linearisation at the rounds' solution over the usable points on the map; residuals beyond
  // k·σ_l have no data term (counted in *outliers).
  const auto linearise_solution = [&](int* outliers) {
    Linearisation lin(n);
    for (std::size_t p : finite) {
      if (!usable[p]) continue;
      if (const auto s = grid.Sample(layer, ref_lat[p], ref_lon[p])) {
        const double d = s->value_nT - path.measured_nT[p];
        if (options.outlier_sigmas > 0.0 && std::abs(d) > options.outlier_sigmas * readings.sigma) {
          ++*outliers;
          continue;
        }
        lin.data[p] = 1;
        lin.g_lat[p] = s->dvalue_dlat_nT_per_deg;
        lin.g_lon[p] = s->dvalue_dlon_nT_per_deg;
        lin.resid[p] = d;
      }
    }
    return lin;
  };
  // λ from the path (fast_msd.h, lambda_from_path_iterations): λ = 2σ²/τ² from the solution, the rounds again.
  int lambda_updates = 0;
  bool lambda_clamped = false;
  for (int k = 0; k < options.lambda_from_path_iterations; ++k) {
    int ignored = 0;
    const Linearisation lin = linearise_solution(&ignored);
    std::vector<double> e_lat(n), e_lon(n);
    for (std::size_t i = 0; i < n; ++i) {
      e_lat[i] = ref_lat[i] - start_lat[i];
      e_lon[i] = ref_lon[i] - start_lon[i];
    }
    const internal::PathScales scales =
        internal::EstimatePathScales(lin.g_lat, lin.g_lon, lin.resid, lin.data, e_lat, e_lon, final_lambda);
    if (!(scales.s2_nT2 > 0.0) || !(scales.tau2_deg2 > 0.0)) break;
    const double raw = 2.0 * scales.s2_nT2 / scales.tau2_deg2;
    const double next = std::clamp(raw, options.lambda_min_nT2_per_deg2, options.lambda_max_nT2_per_deg2);
    lambda_clamped = next != raw;
    if (std::abs(next - final_lambda) < 0.01 * final_lambda) break;
    final_lambda = next;
    all_converged = run_rounds(usable);
    ++lambda_updates;
  }
  if (options.lambda_from_path_iterations > 0) {
    r.notes += std::string(r.notes.empty() ? "" : "; ") + "smoothing weight lambda " + FormatNumber(final_lambda) +
               " nT^2/deg^2 (2 sigma^2/tau^2 from the path, " + std::to_string(lambda_updates) + " re-solve" +
               (lambda_updates == 1 ? "" : "s") + (lambda_clamped ? ", held to its range" : "") + ")";
  }
  r.lat_deg = ref_lat;
  r.lon_deg = ref_lon;
  // Score over the points on the map (the refit's outliers and residuals beyond k·σ_l left out, counted).
  const Linearisation final_lin = linearise_solution(&r.points_outlier);  // at the solution, for the covariance
  double sum2 = 0.0;
  int on = 0;
  for (std::size_t p = 0; p < n; ++p) {
    if (!final_lin.data[p]) continue;
    sum2 += final_lin.resid[p] * final_lin.resid[p];
    ++on;
  }
  // Covariance (fast_msd_covariance.h): the final λ smoother's error covariance, its noise and INS-drift
  // scales estimated from the path, with the map's curvature at each point.
  {
    std::vector<double> e_lat(n), e_lon(n), h_ll(n, 0.0), h_ln(n, 0.0), h_nn(n, 0.0), map_var;
    double map_var_sum = 0.0;
    if (options.map_error_in_covariance) map_var.assign(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      e_lat[i] = r.lat_deg[i] - start_lat[i];
      e_lon[i] = r.lon_deg[i] - start_lon[i];
      if (!final_lin.data[i]) continue;
      MapHessian(grid, layer, r.lat_deg[i], r.lon_deg[i], &h_ll[i], &h_ln[i], &h_nn[i]);
      if (options.map_error_in_covariance) {
        Eigen::Matrix2d H;
        H << h_ll[i], h_ln[i], h_ln[i], h_nn[i];
        const double b = internal::BilinearErrorBound(H, grid.lat().step_deg, grid.lon().step_deg);
        map_var[i] = b * b;
        map_var_sum += b * b;
      }
    }
    // The prior the method starts from: the coarse search's ±window, uniform (w²/3 per axis); none
    // without a coarse stage.
    const double prior_var = options.search_window_deg > 0.0
                                 ? options.search_window_deg * options.search_window_deg / 3.0
                                 : 0.0;
    const internal::ErrorCovariance c =
        internal::FastMsdErrorCovariance(final_lin.g_lat, final_lin.g_lon, final_lin.resid, final_lin.data, e_lat,
                                         e_lon, h_ll, h_ln, h_nn, final_lambda, 6, prior_var,
                                         map_var);
    r.cov_lat_lat = c.lat_lat;
    r.cov_lat_lon = c.lat_lon;
    r.cov_lon_lon = c.lon_lon;
    // The other basins (fast_msd_basins.h): the posterior mass outside each point's published basin.
    int basin_points = 0;
    double max_edge_mass = 0.0;
    if (options.basin_half_width_deg > 0.0 && c.tau2_deg2 > 0.0 && c.curvature_limited.size() == n) {
      // At most kMaxBasinRadius offsets each side (the grid's memory and time grow as its square): a wider
      // half width for the map's step coarsens the grid instead.
      constexpr int kMaxBasinRadius = 400;
      std::vector<Eigen::Matrix2d> cov(n);
      for (std::size_t i = 0; i < n; ++i) cov[i] << c.lat_lat[i], c.lat_lon[i], c.lat_lon[i], c.lon_lon[i];
      const double cap = options.outlier_sigmas > 0.0 ? options.outlier_sigmas * readings.sigma
                                                      : std::numeric_limits<double>::infinity();
      // The grid over ± half_width; while the posterior's mass on its outermost ring reaches kMaxEdgeMass
      // (the grid truncates it), twice as wide, up to basin_max_half_width_deg (fast_msd.h).
      const auto spread_over = [&](double half_width) {
        double step = options.basin_step_cells * std::min(grid.lat().step_deg, grid.lon().step_deg);
        int radius = std::max(1, static_cast<int>(std::ceil(half_width / step)));
        if (radius > kMaxBasinRadius) {
          radius = kMaxBasinRadius;
          step = half_width / radius;
        }
        internal::BasinSpread spread = internal::FastMsdBasinSpread(
            grid, layer, r.lat_deg, r.lon_deg, path.measured_nT, final_lin.data, e_lat, e_lon, cov, c.s2_nT2,
            map_var, c.tau2_deg2, cap, step, radius);
        max_edge_mass = 0.0;
        for (double x : spread.edge_mass) max_edge_mass = std::max(max_edge_mass, x);
        return spread;
      };
      double half_width = options.basin_half_width_deg;
      internal::BasinSpread bs = spread_over(half_width);
      while (max_edge_mass >= kMaxEdgeMass && half_width < options.basin_max_half_width_deg) {
        half_width = std::min(2.0 * half_width, options.basin_max_half_width_deg);
        bs = spread_over(half_width);
      }
      if (half_width > options.basin_half_width_deg) {
        r.notes += std::string(r.notes.empty() ? "" : "; ") + "offset grid widened to " + FormatNumber(half_width) +
                   " deg (the posterior reached its edge)";
      }
      // The mixture's mean (applied by MatchFastMsd, after the ambiguity check). The mean of a posterior the
      // grid truncates is not the posterior's mean: no point moves when the mass on the grid's outermost
      // ring reaches kMaxEdgeMass anywhere along the path (fast_msd.h).
      const bool shift = mean_shift != nullptr && options.basin_mean_shift && max_edge_mass < kMaxEdgeMass;
      if (shift) {
        mean_shift->d = options.basin_full_mean ? bs.mean : bs.far_mean;
        mean_shift->scored = final_lin.data;
        mean_shift->cov.assign(n, Eigen::Matrix2d::Zero());
      }
      for (std::size_t i = 0; i < n; ++i) {
        Eigen::Matrix2d m = cov[i] + bs.far_moment[i];
        internal::CapAtPrior(&m, prior_var);
        r.cov_lat_lat[i] = m(0, 0);
        r.cov_lat_lon[i] = m(0, 1);
        r.cov_lon_lon[i] = m(1, 1);
        if (bs.far_mass[i] > 0.05) ++basin_points;
        if (shift) {
          // basin_mean_shift: the mixture's second moment about far_mean f, m − f fᵀ; basin_full_mean: the
          // whole posterior's second moment about its mean (fast_msd.h).
          const Eigen::Vector2d& f = bs.far_mean[i];
          if (options.basin_full_mean) {
            mean_shift->cov[i] = bs.spread[i];
            internal::CapAtPrior(&mean_shift->cov[i], prior_var);
          } else {
            mean_shift->cov[i] = m - f * f.transpose();
          }
        }
      }
    }
    r.notes += std::string(r.notes.empty() ? "" : "; ") + "covariance: residual sigma " +
               FormatNumber(std::sqrt(c.s2_nT2)) + " nT, INS drift " + FormatNumber(std::sqrt(c.tau2_deg2)) +
               " deg per point, " + FormatNumber(c.edf) + " effective parameters";
    if (options.map_error_in_covariance && on > 0) {
      r.notes += ", map interpolation error bound " + FormatNumber(std::sqrt(map_var_sum / on)) + " nT rms";
    }
    // Points whose linearisation could not carry the map's curvature (fast_msd_covariance.h).
    if (c.curvature_limited_points > 0) {
      r.notes += "; curvature-limited points: " + std::to_string(c.curvature_limited_points);
    }
    if (basin_points > 0) {
      r.notes += "; other basins hold > 5 % of the posterior at " + std::to_string(basin_points) + " points";
    }
    if (options.basin_mean_shift && max_edge_mass >= kMaxEdgeMass) {
      r.notes += "; not moved to the posterior mean: its mass on the offset grid's edge reaches " +
                 FormatNumber(max_edge_mass);
    }
    if (c.prior_limited_points > 0) {
      r.notes += "; covariance capped at the search window's at " + std::to_string(c.prior_limited_points) +
                 " points";
    }
  }
  r.points_used = on;
  r.score = on > 0 ? sum2 / on : std::numeric_limits<double>::quiet_NaN();
  internal::CountOffMap(grid, &r);
  r.converged = all_converged && rounds_done > 0;
  const std::string rounds_note = std::to_string(rounds_done) + " rounds";
  r.notes = r.notes.empty() ? rounds_note : r.notes + "; " + rounds_note;
  return r;
}

}  // namespace

MatchResult MatchFastMsd(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                         const FastMsdOptions& options) {
  internal::CheckInputs(grid, layer, path, options, "fast-msd");
  MatchResult r = internal::StartResult("fast-msd", "msd at the matched points, nT^2", path);
  // Robust residuals (match_common.h): readings the map cannot explain
  // (rule 1) have no data term in any round; see the rounds for rule 2.
  const std::vector<std::size_t> all_finite = internal::FiniteMeasurements(path, &r);
  const std::vector<std::size_t> finite =
      internal::WithinMapRange(grid, layer, path, all_finite, options.outlier_sigmas, &r);
  if (!internal::EnoughPoints(finite, 2, &r)) return r;
  std::vector<char> usable(path.size(), 0);
  for (std::size_t p : finite) usable[p] = 1;
  const internal::RobustSpread readings = internal::ReadingSpread(path, finite);
  std::vector<double> start_lat = path.lat_deg, start_lon = path.lon_deg;
  CorrelationPeaks peaks;
  if (options.search_window_deg > 0.0) {
    CorrelationOptions coarse;
    coarse.metric = CorrelationMetric::kMsd;
    coarse.search_window_deg = options.search_window_deg;
    coarse.min_on_map_fraction = options.min_on_map_fraction;
    coarse.outlier_sigmas = options.outlier_sigmas;
    coarse.off_map_as_unexplained = true;
    peaks.max_peaks = 2;
    peaks.min_separation_deg =
        std::max(options.peak_separation_deg, 2.0 * std::max(grid.lat().step_deg, grid.lon().step_deg));
    const MatchResult c = MatchCorrelation(grid, layer, path, coarse, &peaks);
    if (c.points_used == 0) {
      r.reason = "coarse stage: " + c.reason;
      return r;
    }
    start_lat = c.lat_deg;
    start_lon = c.lon_deg;
    r.notes = "coarse stage: " + c.notes + (c.converged ? "" : " (" + c.reason + ")");
  }
  MeanShift mean_shift;
  MatchResult best =
      Refine(grid, layer, path, options, finite, usable, readings, start_lat, start_lon, r, &mean_shift);
  // Ambiguity: the coarse surface's second minimum (at least the separation
  // away) is not clearly worse than its best. Then the answer may be the wrong
  // peak: not converged, and the covariance covers both refined paths.
  bool ambiguous = false;
  MatchResult other;
  if (options.ambiguity_ratio > 0.0 && peaks.found.size() >= 2 &&
      peaks.found[1].score < options.ambiguity_ratio * peaks.found[0].score) {
    std::vector<double> lat2 = path.lat_deg, lon2 = path.lon_deg;
    for (std::size_t p = 0; p < path.size(); ++p) {
      lat2[p] += peaks.found[1].shift_lat_deg;
      lon2[p] += peaks.found[1].shift_lon_deg;
    }
    other = Refine(grid, layer, path, options, finite, usable, readings, lat2, lon2, r, nullptr);
    // The two refined paths, told apart by the best's covariance: the mean over
    // the points of dᵀ Σ⁻¹ d (d = other − best). Below the 99 % point of χ²(2)
    // the second minimum led to the same answer (a neighbour in the same basin).
    double apart = 0.0;
    if (best.cov_lat_lat.size() == path.size()) {
      for (std::size_t p = 0; p < path.size(); ++p) {
        const double da = other.lat_deg[p] - best.lat_deg[p], db = other.lon_deg[p] - best.lon_deg[p];
        const double a = best.cov_lat_lat[p], b = best.cov_lat_lon[p], c = best.cov_lon_lon[p];
        const double det = a * c - b * b;
        apart += det > 0.0 ? (c * da * da - 2.0 * b * da * db + a * db * db) / det
                           : std::numeric_limits<double>::infinity();
      }
      apart /= static_cast<double>(path.size());
    }
    ambiguous = !(apart < kChi2Two99);
    best.notes += "; second coarse minimum " + FormatNumber(peaks.found[1].score / peaks.found[0].score) +
                  "x the best, refined " + FormatNumber(apart) + " (mean squared Mahalanobis distance) from it";
  }
  if (ambiguous) {
    // Second moment about the published path of an equal mixture of the two
    // refined paths (each with its own covariance): ½Σ₁ + ½(Σ₂ + d dᵀ).
    if (best.cov_lat_lat.size() == path.size() && other.cov_lat_lat.size() == path.size()) {
      for (std::size_t p = 0; p < path.size(); ++p) {
        const double da = other.lat_deg[p] - best.lat_deg[p], db = other.lon_deg[p] - best.lon_deg[p];
        best.cov_lat_lat[p] = 0.5 * (best.cov_lat_lat[p] + other.cov_lat_lat[p] + da * da);
        best.cov_lat_lon[p] = 0.5 * (best.cov_lat_lon[p] + other.cov_lat_lon[p] + da * db);
        best.cov_lon_lon[p] = 0.5 * (best.cov_lon_lon[p] + other.cov_lon_lon[p] + db * db);
      }
    }
    const std::string why =
        "ambiguous: the coarse stage's second minimum (shift " + FormatNumber(peaks.found[1].shift_lat_deg) + ", " +
        FormatNumber(peaks.found[1].shift_lon_deg) + " deg, MSD " + FormatNumber(peaks.found[1].score) +
        " nT^2) is within " + FormatNumber(options.ambiguity_ratio) + "x of the best (shift " +
        FormatNumber(peaks.found[0].shift_lat_deg) + ", " + FormatNumber(peaks.found[0].shift_lon_deg) +
        " deg, MSD " + FormatNumber(peaks.found[0].score) + " nT^2) and refined elsewhere; the covariance covers both";
    best.reason = best.reason.empty() ? why : why + "; " + best.reason;
    best.converged = false;
  } else if (peaks.found.size() >= 2 && other.lat_deg.empty()) {
    best.notes += "; second coarse minimum " + FormatNumber(peaks.found[1].score / peaks.found[0].score) + "x the best";
  }
  // basin_mean_shift (fast_msd.h): each point to the mean of the other-basins mixture, its covariance the
  // mixture's second moment about it (C + S − d dᵀ); not when ambiguous (the covariance covers the second
  // peak's refined path about the published one, as before).
  if (!ambiguous && mean_shift.d.size() == path.size() && best.cov_lat_lat.size() == path.size()) {
    int moved = 0;
    double sum2 = 0.0;
    int on = 0;
    for (std::size_t p = 0; p < path.size(); ++p) {
      const Eigen::Vector2d& d = mean_shift.d[p];
      if (d.squaredNorm() > 0.0) ++moved;
      if (!grid.Contains(best.lat_deg[p], best.lon_deg[p])) --best.points_off_map;
      best.lat_deg[p] += d(0);
      best.lon_deg[p] += d(1);
      best.cov_lat_lat[p] = mean_shift.cov[p](0, 0);
      best.cov_lat_lon[p] = mean_shift.cov[p](0, 1);
      best.cov_lon_lon[p] = mean_shift.cov[p](1, 1);
      if (!grid.Contains(best.lat_deg[p], best.lon_deg[p])) ++best.points_off_map;
      if (!mean_shift.scored[p]) continue;
      if (const auto s = grid.Sample(layer, best.lat_deg[p], best.lon_deg[p])) {
        sum2 += (s->value_nT - path.measured_nT[p]) * (s->value_nT - path.measured_nT[p]);
        ++on;
      }
    }
    if (on > 0) best.score = sum2 / on;  // at the published (moved) points
    best.notes += "; moved to the posterior mean at " + std::to_string(moved) + " points";
  }
  return best;
}

}  // namespace magnav::mapmatch
