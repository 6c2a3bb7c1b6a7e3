// Correlation matching (MAGCOM, METHODS.md §5): the INS path is shifted over
// a grid of translations and scored against the map.
//
// Units: positions and the search window in degrees (WGS84), values in nT.
// The shifts are whole grid steps (lat step, lon step) within ±window, so
// the result is on the map's resolution; each point's bilinear weights stay
// the same for every shift, which makes the search a few loads per point.
//
// Scores over the points on the map at that shift (others excluded; a shift
// needs at least min_on_map_fraction of the usable points on the map):
//   MAD   = mean |M_S − M_M|                            (minimised)
//   MSD   = mean (M_S − M_M)²                           (minimised)
//   PROD  = mean M_S·M_M                                (maximised)
//   NPROD = Σ M_S M_M / (sqrt(Σ M_S²) sqrt(Σ M_M²))     (maximised; the paper's
//           printed formula drops the squares — not copied)
// with M_S the measurement and M_M the map value at the shifted point.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"

namespace magnav::mapmatch {

enum class CorrelationMetric { kMad, kMsd, kProd, kNprod };

// "mad", "msd", "prod", "nprod".
const char* CorrelationMetricName(CorrelationMetric metric);

struct CorrelationOptions {
  CorrelationMetric metric = CorrelationMetric::kMsd;
  // Half-width of the translation search in lat and lon (deg). No default:
  // it must cover the INS error, which only the caller knows (> 0 required).
  double search_window_deg = 0.0;
  // A shift counts only with at least this fraction of the usable points on the map.
  double min_on_map_fraction = 0.5;
  // Rotation search (a plus, not in the paper): the INS path is also turned
  // about the centroid of its usable points by every multiple of
  // rotation_step_deg within ±rotation_window_deg, each with the full
  // translation search. 0 = translations only.
  double rotation_window_deg = 0.0;
  double rotation_step_deg = 0.5;
  // Robust residuals: after the search, a point whose residual at the best
  // shift is beyond outlier_sigmas robust sigmas (1.4826·MAD, at least 1 nT)
  // of the median is left out and the search run again (at most 3 searches,
  // until the outliers repeat); counted in MatchResult::points_outlier. So one
  // spike cannot pull the shift towards where the map is high. 0 = off.
  double outlier_sigmas = 5.0;
  // MAD and MSD only, with outlier_sigmas > 0: a usable point off the map at a
  // shift counts as a reading the map cannot explain, i.e. with the truncated
  // loss's cap (outlier_sigmas · σ_l) as its residual, and the score is the
  // mean over every usable point. Without it (false, the default of the
  // correlation methods) the score is the mean over the points on the map
  // only, so a shift that leaves most of the path off the map is scored on a
  // few points and can win by chance on a flat stretch (a generated 0.1° path:
  // 56 of 150 points on the map, MSD 1.1 nT² against 121 nT² at the true
  // shift). Fast MSD's coarse stage turns it on (docs/ACCURACY.md, "Fast MSD
  // off the reference paths").
  bool off_map_as_unexplained = false;

  bool IsValid(std::string* error) const;
};

// The path shifted (and turned) by the best translation (and rotation).
// iterations = number of shifts (× rotations) scored; score = the metric at the best shift (nT for MAD, nT² for MSD and
// PROD, 1 for NPROD). Not converged (with the reason) when no shift has
// enough points on the map (path left as the INS gave it) or the best shift
// or rotation lies on the window's edge (the window may be too small).
//
// `peaks` (optional; translations only, no rotation search): the best local
// optima of the final search's score surface (a shift no worse than its 8
// neighbours), best first, each at least min_separation_deg (in lat or lon)
// from every better one, at most max_peaks; fast MSD's coarse stage refines
// each (fast_msd.h).
struct CorrelationPeak {
  double shift_lat_deg = 0.0, shift_lon_deg = 0.0;
  double score = 0.0;  // the metric at that shift
};
struct CorrelationPeaks {
  std::size_t max_peaks = 3;
  double min_separation_deg = 0.0;
  std::vector<CorrelationPeak> found;  // output
};
MatchResult MatchCorrelation(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                             const CorrelationOptions& options, CorrelationPeaks* peaks = nullptr);

}  // namespace magnav::mapmatch
