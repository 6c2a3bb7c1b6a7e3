#include "magnav/core/frames.h"

#include <cmath>

#include <GeographicLib/LocalCartesian.hpp>

#include "magnav/core/error.h"

namespace magnav {

Eigen::Matrix3d HeadingRotation(double psi, Eigen::Matrix3d* dR) {
  const double c = std::cos(psi), s = std::sin(psi);
  Eigen::Matrix3d R;
  R << c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0;
  if (dR) *dR << -s, -c, 0.0, c, -s, 0.0, 0.0, 0.0, 0.0;
  return R;
}

Eigen::Vector3d WorldMoment(const Eigen::Vector3d& m_B, double psi, Eigen::Vector3d* J_mW_psi) {
  Eigen::Matrix3d dR;
  const Eigen::Matrix3d R = HeadingRotation(psi, J_mW_psi ? &dR : nullptr);
  if (J_mW_psi) *J_mW_psi = dR * m_B;
  return R * m_B;
}

struct LocalTangentPlane::Impl {
  GeographicLib::LocalCartesian lc;
};

namespace {
const Geodetic& CheckedOrigin(const Geodetic& o) {
  if (!std::isfinite(o.lat_deg) || std::abs(o.lat_deg) > 90.0 || !std::isfinite(o.lon_deg) ||
      !std::isfinite(o.height_m)) {
    throw InputError("LocalTangentPlane: origin must have latitude in [-90, 90] deg and finite "
                     "longitude and height");
  }
  return o;
}
}  // namespace

LocalTangentPlane::LocalTangentPlane(const Geodetic& origin)
    : origin_(CheckedOrigin(origin)),
      impl_(std::make_unique<Impl>(
          Impl{GeographicLib::LocalCartesian(origin.lat_deg, origin.lon_deg, origin.height_m)})) {}
LocalTangentPlane::~LocalTangentPlane() = default;
LocalTangentPlane::LocalTangentPlane(LocalTangentPlane&&) noexcept = default;
LocalTangentPlane& LocalTangentPlane::operator=(LocalTangentPlane&&) noexcept = default;

Eigen::Vector3d LocalTangentPlane::ToNed(const Geodetic& p) const {
  double e, n, u;
  impl_->lc.Forward(p.lat_deg, p.lon_deg, p.height_m, e, n, u);
  return {n, e, -u};
}

Geodetic LocalTangentPlane::ToGeodetic(const Eigen::Vector3d& ned) const {
  Geodetic g;
  impl_->lc.Reverse(ned.y(), ned.x(), -ned.z(), g.lat_deg, g.lon_deg, g.height_m);
  return g;
}

}  // namespace magnav
