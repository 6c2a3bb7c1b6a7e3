// Which truth vessel an estimate belongs to, as `magnav evaluate` scores it
// and `magnav plot` colours it (one rule for both): a row at a truth time
// goes to the nearest vessel at that time (3-D distance); the scorer counts
// it as false if that vessel is farther than its gate. Tracks are then paired
// with vessels one to one so that the pairs share the most rows (core/
// assignment.h, the Hungarian method).
#pragma once

#include <cstddef>
#include <map>
#include <optional>

#include <Eigen/Core>

namespace magnav::tools {

struct NearestVessel {
  long long vessel_id = -1;
  double distance_m = 0.0;  // 3-D, m
};

// The nearest of the vessels at one time (vessel_id -> position, m), or
// nullopt if there is none.
std::optional<NearestVessel> FindNearestVessel(const std::map<long long, Eigen::Vector3d>& vessels_at_t,
                                               const Eigen::Vector3d& p);

// rows[vessel_id][track_id]: how many rows of the track went to the vessel.
// Returns vessel_id -> track_id, one to one, maximising the rows shared by
// the pairs; a vessel that shares no row with any track is left out.
std::map<long long, long long> PairVesselsWithTracks(
    const std::map<long long, std::map<long long, std::size_t>>& rows);

}  // namespace magnav::tools
