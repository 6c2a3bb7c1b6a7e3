// What a map can observe of the INS error along a matched path, compared with
// the prior on that error (issue 23 item 5): one computation used by every
// method through Match (match.h).
//
// Frames and units: positions latitude/longitude in degrees (WGS84, used as a
// plane, as every matcher here); map values and readings in nT, map gradients
// g in nT/deg; covariances in deg² of (lat, lon); information (inverse
// covariance) in 1/deg²; directions are unit vectors in (lat, lon) degrees,
// bearings in degrees clockwise from north, taken modulo 180 (an axis).
//
// Model (linear-Gaussian, no truth used): the INS error x_i of point i (2-D,
// deg) starts as N(0, start_sd² I) at the first point and walks,
// x_{i+1} = x_i + N(0, drift_sd² I); a measured point on the map at its
// matched position reads g_iᵀ x_i + N(0, σ²), g_i the map gradient there and
// σ the matched residuals' rms (at least min_noise_sd_nT). A Kalman filter and
// its Rauch–Tung–Striebel smoother over the path give, per point, what the map
// and the prior together can know of the INS error (filtered: the readings up
// to the point; smoothed: all of them). At the path's end, where a fix is
// used, the map's information is I_map = P_end⁻¹ − P_prior,end⁻¹ (the posterior
// information less the prior's); along its least informed eigen-direction
// (the iso-line of a main-field map: a plane gradient gives exactly 0 there)
// the ratio I_map / I_prior says how much the map adds to the prior. A total
// field map on a smooth main field observes the error across its iso-lines and
// hardly at all along them (docs/ACCURACY.md, "Why >= 60 % is out of reach").
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"

namespace magnav::mapmatch {

// The prior on the INS error, 1 sigma per axis (deg). Both 0 = not given:
// Match derives one (ResolvedInsPrior, match.h): pf/afpf their own prior
// square and drift; the others a constant offset of 1/3 of the plausible
// correction (PlausibleCorrectionDeg, --max-correction: its 3 sigma).
struct InsErrorPrior {
  double start_sd_deg = 0.0;  // at the path's first point
  double drift_sd_deg = 0.0;  // random walk per path step (0 = one constant offset)
  bool given() const { return start_sd_deg > 0.0 || drift_sd_deg > 0.0; }
  // At most 90 deg each (a σ beyond a quarter turn of latitude is no prior:
  // --ins-drift-sd 1e308 overflowed the filter's variance to inf).
  static constexpr double kMaxSdDeg = 90.0;
  bool IsValid(std::string* error) const;  // finite, >= 0
};

struct ObservabilityOptions {
  InsErrorPrior prior;
  // A result whose map information along the least informed direction at the
  // path's end is below this fraction of the prior's there is "partly
  // observable", not "converged": below 1 the map knows less than the INS
  // already did along it (it removes less than half the prior's variance, 29 %
  // of its sigma). Fixed before any path was counted; 0 = never.
  double min_information_ratio = 1.0;
  // Floor of the reading noise σ (nT) when the matched residuals are smaller
  // (a noise-free synthetic path).
  double min_noise_sd_nT = 0.1;
  bool IsValid(std::string* error) const;
};

// A 2×2 covariance of (lat, lon), deg².
struct Cov2 {
  double lat_lat = 0.0, lat_lon = 0.0, lon_lon = 0.0;
};

struct PathObservability {
  bool valid = false;  // false: no prior variance at the end (start and drift both 0) or an empty path
  std::vector<Cov2> filtered;  // per point: prior + readings up to it (what a causal filter can know)
  std::vector<Cov2> smoothed;  // per point: prior + all readings (what a batch method can know)
  // At the path's end.
  double weak_lat = 1.0, weak_lon = 0.0;  // least informed direction of the map (unit, (lat, lon))
  double map_info_weak = 0.0;             // 1/deg², >= 0
  double map_info_strong = 0.0;           // 1/deg², along the perpendicular
  double prior_info = 0.0;                // 1/deg², the prior's at the end (isotropic)
  double noise_sd_nT = 0.0;               // σ used
  int points = 0;                         // measured points on the map at their matched positions
  double ratio_weak() const { return prior_info > 0.0 ? map_info_weak / prior_info : 0.0; }
  double ratio_strong() const { return prior_info > 0.0 ? map_info_strong / prior_info : 0.0; }
  double weak_bearing_deg() const;  // [0, 180)
  // "map information at the path's end: along the least observed direction
  // (bearing B deg) X of the prior's, across it Y of the prior's (sigma S nT, N
  // points)".
  std::string Summary() const;
};

// The map's information at one point of a path against the prior's there
// (what PathObservability reports at the path's end).
struct MapInformation {
  bool valid = false;                     // false: no prior variance (start and drift both 0)
  double weak_lat = 1.0, weak_lon = 0.0;  // least informed direction of the map (unit, (lat, lon))
  double map_info_weak = 0.0;             // 1/deg², >= 0
  double map_info_strong = 0.0;           // 1/deg², along the perpendicular
  double prior_info = 0.0;                // 1/deg², the prior's there (isotropic)
  double ratio_weak() const { return prior_info > 0.0 ? map_info_weak / prior_info : 0.0; }
  double ratio_strong() const { return prior_info > 0.0 ? map_info_strong / prior_info : 0.0; }
  double weak_bearing_deg() const;  // [0, 180)
};

// The Kalman filter of the INS error above, one step at a time (causal: what
// a live matcher can know at each step; ObservePath's filtered pass runs it).
// Start: P = start_sd² I. Per path step after the first: Predict() adds
// drift_sd² I; then Update(g, σ) for a reading with map gradient g (nT/deg,
// (d/dlat, d/dlon) at the matched position) and noise σ (nT, > 0).
class ObservabilityFilter {
 public:
  explicit ObservabilityFilter(const InsErrorPrior& prior);
  void Predict();
  void Update(double dvalue_dlat_nT_per_deg, double dvalue_dlon_nT_per_deg, double sigma_nT);
  Cov2 covariance() const { return p_; }             // deg², prior + readings so far
  double prior_variance_deg2() const { return prior_var_; }  // the prior alone's, per axis
  int updates() const { return updates_; }
  // The map's information now (posterior information less the prior's) along
  // its least informed direction, against the prior's.
  MapInformation Information() const;

 private:
  InsErrorPrior prior_;
  Cov2 p_;
  double prior_var_ = 0.0;
  int updates_ = 0;
};

// The review Match makes at a path's end (ReviewObservability, match.h), made
// live at every step of a sequential matcher (magnav-matcher): an
// ObservabilityFilter fed, at each step, the map gradient at the step's
// matched position when its reading is finite and that position is on the
// map, with σ = the rms of map − reading at the matched positions so far (2
// degrees of freedom counted, as MatchedResidualRms; at least
// min_noise_sd_nT). Match's σ is the whole path's rms, so on one path the two
// differ by the σ of the early steps only. Partly observable: the map's
// information along its least informed direction is below
// min_information_ratio of the prior's (a plane gradient gives exactly 0
// along its iso-lines); then Floor raises a covariance (deg²) along the
// filter's least known direction to the filter's variance there.
class StepObservability {
 public:
  StepObservability(const GeoGrid& grid, std::size_t layer, const InsErrorPrior& prior,
                    const ObservabilityOptions& options);
  // One path step: the matched position (deg) after it and the reading (nT; NaN = none).
  void Step(double lat_deg, double lon_deg, double measured_nT);
  MapInformation Information() const { return filter_.Information(); }
  Cov2 covariance() const { return filter_.covariance(); }  // deg², what the map and the prior can know
  double noise_sd_nT() const;                                 // σ of the next update
  bool partly_observable() const;
  // When partly observable: FloorAlongLeastKnown(covariance(), c); returns true when it raised c.
  bool Floor(Cov2* c) const;

 private:
  const GeoGrid& grid_;
  std::size_t layer_;
  ObservabilityOptions options_;
  ObservabilityFilter filter_;
  bool started_ = false;
  double residual_ss_ = 0.0;
  int residuals_ = 0;
};

// The observability of the INS error along the matched positions (lat, lon)
// of `path` (gradients sampled there; points off the map or with a non-finite
// reading carry no reading). noise_sd_nT: σ of the readings.
PathObservability ObservePath(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                              const std::vector<double>& lat_deg, const std::vector<double>& lon_deg,
                              const InsErrorPrior& prior, double noise_sd_nT);

// The rms of map − reading at the matched positions over the measured points
// on the map, with 2 degrees of freedom counted (at least 1 point); NaN if none.
double MatchedResidualRms(const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                          const std::vector<double>& lat_deg, const std::vector<double>& lon_deg);

// Raises the variance of c along the least known direction of `floor` (its
// largest eigenvalue's eigenvector e) to eᵀ·floor·e when c's is smaller, by
// adding a multiple of e eᵀ (c stays positive semi-definite; other directions
// can only grow). Returns true when it raised it. The posterior cannot know
// more than the data and the prior along the direction they know least.
bool FloorAlongLeastKnown(const Cov2& floor, Cov2* c);

}  // namespace magnav::mapmatch
