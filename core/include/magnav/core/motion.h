// Coordinated-turn vessel kinematics (constant speed, constant turn rate,
// constant depth), shared by the simulator, the tracker and the localizer.
//
// State, world NED: position p = (x, y, z) in m, speed v ≥ 0 in m/s, heading h
// in rad (from north, clockwise seen from above), turn rate ω in rad/s
// (positive = turning right). Velocity = v (cos h, sin h, 0).
//
// Exact propagation over dt:
//   h(t) = h + ω t
//   x(t) = x + v t cos(h + ω t/2) sinc(ω t/2)
//   y(t) = y + v t sin(h + ω t/2) sinc(ω t/2)
// using sin(a+b) − sin a = 2 cos(a + b/2) sin(b/2); sinc(u) = sin(u)/u is
// evaluated by its series near 0, so the ω → 0 limit (straight line) is exact
// and smooth (derivatives included). Templated so Ceres can differentiate it.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace magnav {

// sin(u)/u, smooth at 0 (Taylor series to u⁶ for |u| < 1e-3; error < 1e-22).
template <typename T>
T Sinc(const T& u) {
  using std::abs;
  using std::sin;
  if (abs(u) < T(1e-3)) {
    const T u2 = u * u;
    return T(1.0) - u2 / T(6.0) + u2 * u2 / T(120.0) - u2 * u2 * u2 / T(5040.0);
  }
  return sin(u) / u;
}

// d/du [sin(u)/u] = (u cos u − sin u)/u², smooth at 0 (series for |u| < 1e-3).
inline double SincDerivative(double u) {
  if (std::abs(u) < 1e-3) {
    const double u2 = u * u;
    return u * (-1.0 / 3.0 + u2 / 30.0 - u2 * u2 / 840.0);
  }
  return (u * std::cos(u) - std::sin(u)) / (u * u);
}

template <typename T>
struct CtState {
  T x, y, z;   // m, NED
  T v;         // m/s
  T heading;   // rad
  T turn_rate; // rad/s
};

// Propagates a coordinated-turn state by dt seconds (dt may be negative).
// The heading is not wrapped (wrap with WrapAngle where it is shown).
template <typename T>
CtState<T> PropagateCoordinatedTurn(const CtState<T>& s, double dt) {
  using std::cos;
  using std::sin;
  const T half = s.turn_rate * T(0.5 * dt);
  const T mid = s.heading + half;
  const T d = s.v * T(dt) * Sinc(half);
  CtState<T> o = s;
  o.x = s.x + d * cos(mid);
  o.y = s.y + d * sin(mid);
  o.heading = s.heading + s.turn_rate * T(dt);
  return o;
}

// Jacobian of PropagateCoordinatedTurn(s, dt) with respect to s, rows and
// columns in the order (x, y, z, v, heading, turn_rate). Analytic, exact at
// ω → 0 (used by the tracker's kinematic factor; as fast as needed for EKFs).
inline Eigen::Matrix<double, 6, 6> CoordinatedTurnJacobian(const CtState<double>& s, double dt) {
  const double half = s.turn_rate * 0.5 * dt;
  const double mid = s.heading + half;
  const double S = Sinc(half);
  const double d = s.v * dt * S;
  const double c = std::cos(mid), sn = std::sin(mid);
  // ∂d/∂ω = v dt S'(half) dt/2; ∂mid/∂ω = dt/2.
  const double dd_dw = s.v * dt * SincDerivative(half) * 0.5 * dt;
  Eigen::Matrix<double, 6, 6> F = Eigen::Matrix<double, 6, 6>::Identity();
  F(0, 3) = dt * S * c;
  F(0, 4) = -d * sn;
  F(0, 5) = dd_dw * c - d * sn * 0.5 * dt;
  F(1, 3) = dt * S * sn;
  F(1, 4) = d * c;
  F(1, 5) = dd_dw * sn + d * c * 0.5 * dt;
  F(4, 5) = dt;
  return F;
}

}  // namespace magnav
