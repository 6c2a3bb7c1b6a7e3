#include "magnav/localizer/crlb.h"

#include "graph.h"
#include "magnav/core/error.h"

namespace magnav::localizer {

std::vector<double> EpochTimes(const Pass& pass, const LocalizerOptions& options) {
  return internal::BuildTimeline(pass, options.epoch_tolerance_s).t;
}

CrlbResult ComputeCrlb(const Pass& pass, const LocalizerOptions& options, const std::vector<VesselVector>& trajectory,
                       const std::vector<Eigen::Vector2d>& sensors_xy) {
  const internal::Graph g = internal::BuildGraph(pass, options);
  if (trajectory.size() != static_cast<std::size_t>(g.num_epochs) ||
      sensors_xy.size() != static_cast<std::size_t>(g.num_sensors)) {
    throw InputError("ComputeCrlb: expected " + std::to_string(g.num_epochs) + " states and " +
                     std::to_string(g.num_sensors) + " sensors, got " + std::to_string(trajectory.size()) +
                     " and " + std::to_string(sensors_xy.size()));
  }
  CrlbResult out;
  const std::size_t m = sensors_xy.size();
  out.joint.assign(m, Eigen::Matrix2d::Zero());
  out.known_trajectory.assign(m, Eigen::Matrix2d::Zero());
  Eigen::SparseMatrix<double> H;
  if (!internal::Information(g, internal::Pack(g, trajectory, sensors_xy), nullptr, nullptr, &H)) return out;
  if (!internal::SensorMarginalCovariance(g, H, &out.joint_full)) return out;
  if (!internal::KnownTrajectoryCovariances(g, H, &out.known_trajectory)) return out;
  for (std::size_t j = 0; j < m; ++j) {
    out.joint[j] = out.joint_full.block<2, 2>(2 * static_cast<int>(j), 2 * static_cast<int>(j));
  }
  out.ok = true;
  return out;
}

CrlbResult AttachCrlb(const Pass& pass, const LocalizerOptions& options, const std::vector<VesselVector>& trajectory,
                      std::vector<SensorEstimate>* sensors) {
  std::vector<Eigen::Vector2d> s_xy;
  for (const auto& e : *sensors) s_xy.push_back(e.p_SinW_m.head<2>());
  CrlbResult b = ComputeCrlb(pass, options, trajectory, s_xy);
  for (std::size_t j = 0; j < sensors->size(); ++j) {
    (*sensors)[j].crlb_joint_m2 = b.joint[j];
    (*sensors)[j].crlb_known_trajectory_m2 = b.known_trajectory[j];
  }
  return b;
}

}  // namespace magnav::localizer
