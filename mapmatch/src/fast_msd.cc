#include "magnav/mapmatch/fast_msd.h"

#include <cmath>
#include <vector>

#include "magnav/core/csv.h"
#include "magnav/core/option_check.h"
#include "magnav/mapmatch/correlation.h"
#include "match_common.h"

namespace magnav::mapmatch {

bool FastMsdOptions::IsValid(std::string* error) const {
  if (!PositiveFinite(lambda_nT2_per_deg2)) return Fail(error, "lambda_nT2_per_deg2 must be finite and > 0");
  if (!(std::isfinite(lambda_first_round_factor) && lambda_first_round_factor >= 1.0)) {
    return Fail(error, "lambda_first_round_factor must be finite and >= 1");
  }
  if (!PositiveFinite(epsilon_deg2)) return Fail(error, "epsilon_deg2 must be finite and > 0");
  if (max_iterations_per_round < 1) return Fail(error, "max_iterations_per_round must be >= 1");
  if (rounds < 1) return Fail(error, "rounds must be >= 1");
  if (!(min_on_map_fraction > 0.0 && min_on_map_fraction <= 1.0)) {
    return Fail(error, "min_on_map_fraction must be in (0, 1]");
  }
  if (!(std::isfinite(search_window_deg) && search_window_deg >= 0.0)) {
    return Fail(error, "search_window_deg must be finite and >= 0 (0 = no coarse stage)");
  }
  return true;
}

MatchResult MatchFastMsd(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                         const FastMsdOptions& options) {
  internal::CheckInputs(grid, layer, path, options, "fast-msd");
  MatchResult r = internal::StartResult("fast-msd", "msd at the matched points, nT^2", path);
  const std::vector<std::size_t> finite = internal::FiniteMeasurements(path, &r);
  if (!internal::EnoughPoints(finite, 2, &r)) return r;
  const std::size_t n = path.size();
  std::vector<double> ref_lat = path.lat_deg, ref_lon = path.lon_deg;
  if (options.search_window_deg > 0.0) {
    CorrelationOptions coarse;
    coarse.metric = CorrelationMetric::kMsd;
    coarse.search_window_deg = options.search_window_deg;
    coarse.min_on_map_fraction = options.min_on_map_fraction;
    const MatchResult c = MatchCorrelation(grid, layer, path, coarse);
    if (c.points_used == 0) {
      r.reason = "coarse stage: " + c.reason;
      return r;
    }
    ref_lat = c.lat_deg;
    ref_lon = c.lon_deg;
    r.notes = "coarse stage: " + c.notes + (c.converged ? "" : " (" + c.reason + ")");
  }
  std::vector<double> e_lat(n), e_lon(n), nxt_lat(n), nxt_lon(n);
  std::vector<double> g_lat(n), g_lon(n), resid(n);  // resid = m_i − l_i
  std::vector<char> data(n);
  bool all_converged = true;
  int rounds_done = 0;
  for (int round = 0; round < options.rounds; ++round) {
    std::size_t on = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto s = std::isfinite(path.measured_nT[i]) ? grid.Sample(layer, ref_lat[i], ref_lon[i]) : std::nullopt;
      data[i] = s.has_value();
      if (s) {
        g_lat[i] = s->dvalue_dlat_nT_per_deg;
        g_lon[i] = s->dvalue_dlon_nT_per_deg;
        resid[i] = s->value_nT - path.measured_nT[i];
        ++on;
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
        options.lambda_nT2_per_deg2 *
        (options.rounds > 1 ? std::pow(options.lambda_first_round_factor,
                                       static_cast<double>(options.rounds - 1 - round) / (options.rounds - 1))
                            : 1.0);
    std::fill(e_lat.begin(), e_lat.end(), 0.0);
    std::fill(e_lon.begin(), e_lon.end(), 0.0);
    bool round_converged = false;
    for (int it = 0; it < options.max_iterations_per_round; ++it) {
      ++r.iterations;
      double change2 = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        double mlat, mlon;  // ē_i
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
        if (data[i]) {
          const double k =
              (g_lat[i] * mlat + g_lon[i] * mlon + resid[i]) / (lambda + g_lat[i] * g_lat[i] + g_lon[i] * g_lon[i]);
          mlat -= g_lat[i] * k;
          mlon -= g_lon[i] * k;
        }
        const double dl = mlat - e_lat[i], dn = mlon - e_lon[i];
        change2 += dl * dl + dn * dn;
        nxt_lat[i] = mlat;
        nxt_lon[i] = mlon;
      }
      e_lat.swap(nxt_lat);
      e_lon.swap(nxt_lon);
      if (change2 / static_cast<double>(n) < options.epsilon_deg2) {
        round_converged = true;
        break;
      }
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
    if (lambda == options.lambda_nT2_per_deg2 && step2 / static_cast<double>(n) < options.epsilon_deg2) break;
  }
  r.lat_deg = ref_lat;
  r.lon_deg = ref_lon;
  double sum2 = 0.0;
  int on = 0;
  for (std::size_t p : finite) {
    if (const auto s = grid.Sample(layer, r.lat_deg[p], r.lon_deg[p])) {
      sum2 += (s->value_nT - path.measured_nT[p]) * (s->value_nT - path.measured_nT[p]);
      ++on;
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

}  // namespace magnav::mapmatch
