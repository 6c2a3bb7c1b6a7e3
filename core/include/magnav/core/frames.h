// Frames: heading rotation of a body-fixed moment, and geodetic <-> local NED.
//
// Heading ψ is measured from north, clockwise seen from above, i.e. a rotation
// about +z (down). Body axes: x forward, y starboard, z down.
// m_W = Rz(ψ) m_B with Rz = [[cos ψ, −sin ψ, 0], [sin ψ, cos ψ, 0], [0, 0, 1]].
#pragma once

#include <memory>

#include <Eigen/Core>

namespace magnav {

// Rz(ψ) and its derivative dRz/dψ (optional).
Eigen::Matrix3d HeadingRotation(double heading_rad, Eigen::Matrix3d* dR_dpsi = nullptr);

// World (NED) moment of a body-fixed moment at a heading; optional ∂m_W/∂ψ.
Eigen::Vector3d WorldMoment(const Eigen::Vector3d& m_B, double heading_rad,
                            Eigen::Vector3d* J_mW_psi = nullptr);

// Geodetic position on the WGS84 ellipsoid: degrees, metres above the ellipsoid.
struct Geodetic {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double height_m = 0.0;
};

// Local tangent plane (NED, metres) about a geodetic origin; exact ellipsoidal
// conversion by GeographicLib::LocalCartesian (which works in ENU; this class
// converts). Valid anywhere on Earth; the plane is tangent at the origin.
class LocalTangentPlane {
 public:
  explicit LocalTangentPlane(const Geodetic& origin);
  ~LocalTangentPlane();
  LocalTangentPlane(LocalTangentPlane&&) noexcept;
  LocalTangentPlane& operator=(LocalTangentPlane&&) noexcept;

  const Geodetic& origin() const { return origin_; }
  // NED (m) of a geodetic point.
  Eigen::Vector3d ToNed(const Geodetic& p) const;
  // Geodetic point of an NED position (m).
  Geodetic ToGeodetic(const Eigen::Vector3d& p_ned) const;

 private:
  struct Impl;
  Geodetic origin_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace magnav
