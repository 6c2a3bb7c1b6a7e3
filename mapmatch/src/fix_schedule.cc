#include "magnav/mapmatch/fix_schedule.h"

#include <cmath>
#include <numbers>

#include "magnav/core/error.h"

namespace magnav::mapmatch {
namespace {
constexpr double kA = 6378137.0;              // WGS84 semi-major axis, m
constexpr double kE2 = 6.69437999014e-3;      // first eccentricity squared
constexpr double kDeg = std::numbers::pi / 180.0;
}  // namespace

double MetresPerDegreeLat(double lat_deg) {
  const double s = std::sin(lat_deg * kDeg);
  const double w = 1.0 - kE2 * s * s;
  return kDeg * kA * (1.0 - kE2) / (w * std::sqrt(w));
}

double MetresPerDegreeLon(double lat_deg) {
  const double s = std::sin(lat_deg * kDeg);
  return kDeg * kA / std::sqrt(1.0 - kE2 * s * s) * std::cos(lat_deg * kDeg);
}

FixSchedule::FixSchedule(double every_m, double max_step_deg) : every_m_(every_m), max_step_deg_(max_step_deg) {
  if (!(std::isfinite(every_m) && every_m >= 0.0)) throw InputError("fix schedule: metres must be finite and >= 0");
}

bool FixSchedule::Step(double lat, double lon) {
  if (std::isfinite(lat) && std::isfinite(lon)) {
    if (has_last_) {
      const double dlat = lat - last_lat_, dlon = lon - last_lon_;
      if (std::hypot(dlat, dlon) <= max_step_deg_) {
        travelled_m_ += std::hypot(dlat * MetresPerDegreeLat(lat), dlon * MetresPerDegreeLon(lat));
      }
    }
    has_last_ = true;
    last_lat_ = lat;
    last_lon_ = lon;
  }
  if (every_m_ == 0.0) return true;
  if (travelled_m_ < every_m_) return false;
  travelled_m_ = 0.0;
  return true;
}

std::array<double, 4> CovarianceNorthEast_m2(const StepDiagnostics& d) {
  const double n = MetresPerDegreeLat(d.lat_deg), e = MetresPerDegreeLon(d.lat_deg);
  return {d.cov_lat_lat * n * n, d.cov_lat_lon * n * e, d.cov_lat_lon * n * e, d.cov_lon_lon * e * e};
}

}  // namespace magnav::mapmatch
