// The path a matcher corrects and what every matcher returns.
//
// Units: latitude/longitude in degrees (WGS84), measured field in nT.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace magnav::mapmatch {

// An INS / dead-reckoning path with one measured map value per point.
// A non-finite measurement is allowed here: matchers leave such a point out
// of the fit (counted in MatchResult::points_bad_measurement) and move it
// with the path's correction.
struct MatchPath {
  std::vector<long long> k;            // point index from the file (0.. if not given)
  std::vector<double> lat_deg;         // INS latitude
  std::vector<double> lon_deg;         // INS longitude
  std::vector<double> measured_nT;     // the measured value of the map's layer

  std::size_t size() const { return lat_deg.size(); }
  // Throws InputError if the vectors differ in size, the path is empty, a
  // position is not finite or beyond the limits of core/limits.h (|lat| > 90,
  // |lon| > 360 deg), or a finite measurement is beyond |1e6| nT.
  void Check() const;
};

// Reads `k,ins_lat,ins_lon` and the measurement column (by name; other
// columns ignored). Every bad field is an InputError with file, line, column:
// text, NaN or inf, and values beyond the limits of core/limits.h (|lat| > 90,
// |lon| > 360 deg, |measurement| > 1e6 nT).
MatchPath ReadMatchPath(const std::string& path, const std::string& meas_column);

struct MatchResult {
  std::string method;
  std::vector<double> lat_deg;  // matched position of every path point
  std::vector<double> lon_deg;
  int iterations = 0;
  // The method's own score (named in score_name, with its unit).
  double score = std::numeric_limits<double>::quiet_NaN();
  std::string score_name;
  bool converged = false;
  std::string reason;  // why not converged, or why the path was left as it was
  // Points in the fit; left out because off the map (at the final position
  // or, for correlation, in the best window); left out for a bad measurement.
  int points_used = 0;
  int points_off_map = 0;
  int points_bad_measurement = 0;
  // Points whose residual was beyond the method's outlier threshold (robust
  // residuals: their data term was dropped; not in points_used).
  int points_outlier = 0;
  // Settings the method derived rather than took (e.g. the field scale), for the summary.
  std::string notes;
  // Per-point covariance of the matched position (lat, lon), deg², for the
  // methods that publish one (fast-msd: fast_msd.h); empty = none published.
  std::vector<double> cov_lat_lat, cov_lat_lon, cov_lon_lon;
  // What the map observes of the INS error at the path's end against the
  // prior (observability.h; set by Match): the summary's line, and the map's
  // information along the least observed direction as a fraction of the
  // prior's (NaN = not computed).
  std::string observability;
  double observability_ratio = std::numeric_limits<double>::quiet_NaN();

  // "method icp, iterations 12, score 0.0123 (rms distance, deg), converged, used 60/60, off map 0,
  // bad measurement 0, outliers 0; <notes>; <observability>"
  std::string BriefReport() const;
};

}  // namespace magnav::mapmatch
