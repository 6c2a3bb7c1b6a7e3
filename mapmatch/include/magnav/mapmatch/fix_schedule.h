// When a sequential matcher publishes a fix, and a filter's covariance in
// metres (what magnav-matcher puts in a MapFix). Pure, no DDS.
//
// Distances: WGS84, metres per degree at the latitude (meridional radius M and
// prime-vertical radius N: π/180·M north, π/180·N·cos(lat) east); an increment
// is the local-plane length of the INS step, which is exact enough for steps of
// up to a few km.
#pragma once

#include <array>

#include "magnav/mapmatch/particle_filter.h"

namespace magnav::mapmatch {

// Metres per degree of latitude / of longitude at a latitude (deg).
double MetresPerDegreeLat(double lat_deg);
double MetresPerDegreeLon(double lat_deg);

// A fix every `every_m` metres travelled along the INS positions (the paper
// corrects once per km: 1000), or at every step with every_m = 0. The first
// step never is due (unless every_m = 0); the distance restarts from 0 at each
// fix. A non-finite position or an increment the filter treats as a jump
// (longer than max_step_deg) adds nothing.
class FixSchedule {
 public:
  explicit FixSchedule(double every_m, double max_step_deg = ParticleFilterOptions{}.max_step_deg);
  // One step's INS position; true when a fix is due after this step.
  bool Step(double ins_lat_deg, double ins_lon_deg);
  double travelled_m() const { return travelled_m_; }

 private:
  double every_m_, max_step_deg_;
  bool has_last_ = false;
  double last_lat_ = 0.0, last_lon_ = 0.0, travelled_m_ = 0.0;
};

// The (north, east) covariance in m², row-major 2×2, of a step's diagnostics.
std::array<double, 4> CovarianceNorthEast_m2(const StepDiagnostics& d);

}  // namespace magnav::mapmatch
