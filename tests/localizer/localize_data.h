// Test helpers of the localizer suites: the reference pass (localize_*.csv)
// and its truth, read independently of the library's estimators, and the
// error statistics every suite scores with.
#pragma once

#include <Eigen/Cholesky>
#include <cmath>
#include <string>
#include <vector>

#include "magnav/core/csv.h"
#include "magnav/localizer/crlb.h"
#include "magnav/localizer/input.h"
#include "test_data.h"

namespace magnav::localizer::test {

inline PassFile ReferencePass(const std::string& gnss = "localize_gnss_full.csv") {
  return ReadPassFiles(testing::ReferencePath("localize_measurements.csv"),
                       testing::ReferencePath("localize_deployment.csv"),
                       gnss.empty() ? "" : testing::ReferencePath(gnss), std::nullopt);
}

// True sensor (x, y) from localize_truth_sensors.csv, in deployment order.
inline std::vector<Eigen::Vector2d> TruthSensors(const Pass& pass) {
  const CsvTable t = CsvTable::Read(testing::ReferencePath("localize_truth_sensors.csv"));
  std::vector<Eigen::Vector2d> out(pass.sensors.size());
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    const int j = pass.SensorIndex(t.uint32(i, t.column("sensor_id")));
    if (j >= 0) out[static_cast<std::size_t>(j)] = {t.number(i, t.column("x")), t.number(i, t.column("y"))};
  }
  return out;
}

// True vessel state at every epoch (localize_truth_vessel.csv is at the
// measurement instants; the GNSS instants are among them), heading unwrapped.
inline std::vector<VesselVector> TruthTrajectory(const Pass& pass, const LocalizerOptions& options) {
  const CsvTable t = CsvTable::Read(testing::ReferencePath("localize_truth_vessel.csv"));
  const std::size_t ct = t.column("t"), cx = t.column("x"), cy = t.column("y"), ch = t.column("heading"),
                    cv = t.column("speed"), cw = t.column("turn_rate");
  std::vector<VesselVector> out;
  std::size_t r = 0;
  for (double time : EpochTimes(pass, options)) {
    while (r + 1 < t.num_rows() && t.number(r, ct) < time - 1e-6) ++r;
    VesselVector v;
    v << t.number(r, cx), t.number(r, cy), t.number(r, cv), t.number(r, ch), t.number(r, cw);
    if (!out.empty()) v[kHeading] = out.back()[kHeading] + std::remainder(v[kHeading] - out.back()[kHeading], 2 * M_PI);
    out.push_back(v);
  }
  return out;
}

struct Score {
  double rmse_m = 0.0;            // sqrt(mean ‖ŝ − s‖²) over sensors (horizontal)
  double rms_sigma_m = 0.0;       // sqrt(mean trace(cov))
  double rms_crlb_m = 0.0;        // sqrt(mean trace(joint bound))
  double rms_crlb_known_m = 0.0;  // sqrt(mean trace(known-trajectory bound))
  double mean_nees = 0.0;         // mean over sensors of dᵀ cov⁻¹ d (2 dof each)
};

inline Score ScoreSensors(const std::vector<SensorEstimate>& est, const std::vector<Eigen::Vector2d>& truth) {
  Score s;
  const double n = static_cast<double>(est.size());
  for (std::size_t j = 0; j < est.size(); ++j) {
    const Eigen::Vector2d d = est[j].p_SinW_m.head<2>() - truth[j];
    s.rmse_m += d.squaredNorm() / n;
    s.rms_sigma_m += est[j].cov_xy_m2.trace() / n;
    s.rms_crlb_m += est[j].crlb_joint_m2.trace() / n;
    s.rms_crlb_known_m += est[j].crlb_known_trajectory_m2.trace() / n;
    s.mean_nees += d.dot(est[j].cov_xy_m2.ldlt().solve(d)) / n;
  }
  s.rmse_m = std::sqrt(s.rmse_m);
  s.rms_sigma_m = std::sqrt(s.rms_sigma_m);
  s.rms_crlb_m = std::sqrt(s.rms_crlb_m);
  s.rms_crlb_known_m = std::sqrt(s.rms_crlb_known_m);
  return s;
}

// RMSE of the deployment guesses.
inline double DeploymentRmse(const Pass& pass, const std::vector<Eigen::Vector2d>& truth) {
  double se = 0.0;
  for (std::size_t j = 0; j < truth.size(); ++j) se += (pass.sensors[j].p_SinW_m.head<2>() - truth[j]).squaredNorm();
  return std::sqrt(se / static_cast<double>(truth.size()));
}

// NEES of all sensors at once against a full 2M×2M covariance.
inline double JointNees(const std::vector<SensorEstimate>& est, const std::vector<Eigen::Vector2d>& truth,
                        const Eigen::MatrixXd& cov) {
  Eigen::VectorXd d(2 * static_cast<int>(est.size()));
  for (std::size_t j = 0; j < est.size(); ++j) d.segment<2>(2 * static_cast<int>(j)) = est[j].p_SinW_m.head<2>() - truth[j];
  return d.dot(cov.ldlt().solve(d));
}

}  // namespace magnav::localizer::test
