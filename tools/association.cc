#include "association.h"

#include <vector>

#include "magnav/core/assignment.h"

namespace magnav::tools {

std::optional<NearestVessel> FindNearestVessel(const std::map<long long, Eigen::Vector3d>& vessels_at_t,
                                               const Eigen::Vector3d& p) {
  std::optional<NearestVessel> best;
  for (const auto& [v, q] : vessels_at_t) {
    const double d = (p - q).norm();
    if (!best || d < best->distance_m) best = NearestVessel{v, d};
  }
  return best;
}

std::map<long long, long long> PairVesselsWithTracks(
    const std::map<long long, std::map<long long, std::size_t>>& rows) {
  std::vector<long long> vessels, tracks;
  std::map<long long, int> track_col;
  for (const auto& [v, by_track] : rows) {
    vessels.push_back(v);
    for (const auto& [id, n] : by_track) {
      if (track_col.emplace(id, static_cast<int>(tracks.size())).second) tracks.push_back(id);
    }
  }
  Eigen::MatrixXd cost = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(vessels.size()),
                                               static_cast<Eigen::Index>(tracks.size()));
  for (std::size_t i = 0; i < vessels.size(); ++i) {
    for (const auto& [id, n] : rows.at(vessels[i])) cost(static_cast<Eigen::Index>(i), track_col.at(id)) = -double(n);
  }
  const Assignment a = SolveAssignment(cost);
  std::map<long long, long long> out;
  for (std::size_t i = 0; i < vessels.size(); ++i) {
    const int j = i < a.row_to_col.size() ? a.row_to_col[i] : -1;
    if (j >= 0 && cost(static_cast<Eigen::Index>(i), j) < 0.0) out[vessels[i]] = tracks[static_cast<std::size_t>(j)];
  }
  return out;
}

}  // namespace magnav::tools
