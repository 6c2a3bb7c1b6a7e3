// Data of the sensor localiser: the vessel state, the measurements it takes,
// the deployment priors and the estimates it returns.
//
// Frames and units: world frame = local NED (x north, y east, z down), metres;
// time t in seconds from the scenario start; B in tesla, measured on sensor
// axes aligned with NED; moment in A·m² (body frame: x forward, y starboard,
// z down; world moment = Rz(heading) · body moment); heading in radians from
// north, clockwise seen from above; turn rate in rad/s (positive = right).
// Every sensor's depth z is known (from the deployment); its horizontal
// position (x, y) is estimated. The vessel moves at a known constant depth.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace magnav::localizer {

// Vessel state of the coordinated-turn model: [x (m), y (m), v (m/s),
// heading (rad, not wrapped), turn rate (rad/s)].
using VesselVector = Eigen::Matrix<double, 5, 1>;
using VesselCovariance = Eigen::Matrix<double, 5, 5>;
enum VesselIndex { kX = 0, kY = 1, kV = 2, kHeading = 3, kTurnRate = 4 };

// One triaxial magnetometer sample: the vessel's dipole field (Earth field
// removed) at sensor `sensor_id`, tesla, NED axes.
struct MagSample {
  double t_s = 0.0;
  std::uint32_t sensor_id = 0;
  Eigen::Vector3d B_T = Eigen::Vector3d::Zero();
};

// One GNSS fix of the vessel: horizontal position (m, NED) and its 1-σ per
// axis (m).
struct GnssFix {
  double t_s = 0.0;
  Eigen::Vector2d p_xy_m = Eigen::Vector2d::Zero();
  double sigma_m = 0.0;
};

// Deployment guess of one sensor: position p_SinW (m, NED; z is taken as
// known) and the 1-σ of the horizontal guess per axis (m).
struct SensorPrior {
  std::uint32_t sensor_id = 0;
  Eigen::Vector3d p_SinW_m = Eigen::Vector3d::Zero();
  double sigma_xy_m = 0.0;
};

// The known vessel: body moment (A·m²) and depth (m, NED z).
struct Vessel {
  Eigen::Vector3d m_B_Am2 = Eigen::Vector3d::Zero();
  double z_m = 0.0;
};

// One pass: everything an estimator needs. Samples and fixes in time order.
struct Pass {
  Vessel vessel;
  std::vector<SensorPrior> sensors;
  std::vector<MagSample> samples;
  std::vector<GnssFix> gnss;
  // Index in `sensors` of a sensor id; -1 if unknown.
  int SensorIndex(std::uint32_t sensor_id) const;
};

// Estimate of one sensor: position (z = the known depth), 2×2 covariance of
// (x, y) in m², and the Cramér–Rao lower bounds of (x, y): `crlb_joint` with
// the vessel trajectory unknown (estimated jointly), `crlb_known_trajectory`
// for a perfectly known trajectory. Bounds are evaluated at the estimate
// (trajectory and sensors) unless computed on a known truth.
struct SensorEstimate {
  std::uint32_t sensor_id = 0;
  Eigen::Vector3d p_SinW_m = Eigen::Vector3d::Zero();
  Eigen::Matrix2d cov_xy_m2 = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d crlb_joint_m2 = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d crlb_known_trajectory_m2 = Eigen::Matrix2d::Zero();
};

// What a solve did.
struct Summary {
  std::string method;  // "ekf" or "batch"
  bool converged = false;
  int iterations = 0;  // batch: solver iterations; ekf: 0
  double initial_cost = 0.0;  // ½ Σ ρ(‖e‖²), batch only
  double final_cost = 0.0;
  double solve_time_s = 0.0;  // wall time of the estimator (and its covariance)
  double crlb_time_s = 0.0;   // wall time of the bound
  int magnetometer_updates = 0;  // ekf: samples applied; batch: samples in the pass
  int gnss_updates = 0;          // ekf: fixes applied; batch: fixes in the pass
  // Outliers (LocalizerOptions::gate_probability). EKF: updates refused by
  // the NIS gate (not in the *_updates counts); batch: residuals beyond the
  // same χ² gate at the solution (down-weighted by the robust losses, not
  // removed).
  int magnetometer_outliers = 0;
  int gnss_outliers = 0;
  // EKF: updates applied although beyond the gate, their stream's gate
  // opened by a run of LocalizerOptions::gate_release_after refusals.
  int gate_releases = 0;
  double gate_probability = 0.0;  // the gate the outliers were counted with
  // The estimate is not where its covariance says (set by
  // MarkDivergence; `converged` is then false): the gate's refusals and
  // releases (EKF) or the residuals beyond the gate at the solution (batch)
  // are far more than a consistent estimate gives (1e-4 of the updates at
  // the default gate). BriefReport then says "diverged".
  bool diverged = false;
  // EKF checked against the batch smoother over the same pass
  // (CheckAgainstSmoother): the largest over the sensors of
  // (x_ekf − x_batch)ᵀ P_ekf⁻¹ (x_ekf − x_batch) (2 dof, P_ekf the sensor's
  // 2×2 EKF covariance) and that sensor's id; NaN / −1 when not checked.
  double smoother_nees = std::numeric_limits<double>::quiet_NaN();
  std::int64_t smoother_nees_sensor = -1;
  std::string message;
  // One line: "method batch, converged, iterations 7, cost 1.2e+05 -> 6.6e+04, magnetometer samples 44432,
  // gnss fixes 1111, outliers: magnetometer 0, gnss 1 (gate p 0.9999), time 0.41 s ...".
  std::string BriefReport() const;
  // "converged", "NOT converged" or "diverged".
  std::string Status() const;
};

// Sets summary->diverged (and clears converged) when the outlier counts show
// that the estimate is lost rather than the data wrong. EKF (method ekf,
// ekf-bounded): refused + released updates > max(10, 2 % of all updates);
// batch: magnetometer residuals beyond the gate > max(10, 1 % of the
// samples), or GNSS residuals beyond it > max(10, 1 % of the fixes). A
// consistent estimate has 1e-4 of them at the default gate; one wrong
// measurement, or a few, never trips it. docs/ACCURACY.md "Trust: honest
// status".
void MarkDivergence(Summary* summary);

struct Localization;

// Checks a filter's result (RunEkf, RunEkfBounded) against the batch
// smoother's over the same pass (SolveBatch): per sensor, the EKF's (x, y)
// error taken against the smoother's estimate, normalised by the EKF's own
// 2×2 covariance, d = x_ekf − x_batch, q = dᵀ P_ekf⁻¹ d. A filter whose
// covariance is honest has the smoother inside it (clean calibration runs: q
// ≤ 1.7); q > χ²₂(gate_probability) (18.4 at the default 0.9999) marks the
// filter's summary diverged (converged cleared): a sensor the filter is
// confident about while the smoother, with the whole pass relinearised,
// puts it elsewhere (calibration run 2116: 2.2 m off, NEES 48, q 29; the
// outlier counts of MarkDivergence do not show it). Not checked (summary
// left as is) when the smoother is not "converged" or the two do not hold
// the same sensors; a smoother lost with the filter (started from it, in
// the same wrong basin) agrees with it and is not caught.
// docs/ACCURACY.md "Trust: honest status".
void CheckAgainstSmoother(const Localization& smoother, double gate_probability, Localization* filter);

// Result of a localisation: one estimate per sensor (in the order of
// Pass::sensors) and the vessel trajectory at the estimator's epochs.
struct Localization {
  std::vector<SensorEstimate> sensors;
  // Full covariance and joint bound of all sensors' (x, y), 2M × 2M (m²),
  // ordered [x₁, y₁, x₂, y₂, ...]: the sensors' errors are correlated (a
  // common shift), which the per-sensor 2×2 blocks do not show.
  Eigen::MatrixXd cov_sensors_m2;
  Eigen::MatrixXd crlb_joint_m2;
  std::vector<double> trajectory_t_s;
  std::vector<VesselVector> trajectory;
  Summary summary;
};

}  // namespace magnav::localizer
