// The CSV `magnav record` writes per topic: its header and one row per
// message (every field; covariances as 9 row-major columns with sigma_x..z,
// the roots of their diagonals). `magnav export` writes the same from MCAP.
#pragma once

#include <string>
#include <vector>

#include "magnav/dds/topics.h"

namespace magnav::tools {

// `topic` without its "magnav/" prefix: gradiometer, dipole_fix, track, ...
std::vector<std::string> Header(const std::string& topic);
std::vector<std::string> Row(const dds::msg::GradiometerSample& m);
std::vector<std::string> Row(const dds::msg::MagnetometerSample& m);
std::vector<std::string> Row(const dds::msg::VesselNav& m);
std::vector<std::string> Row(const dds::msg::DipoleFix& m);
std::vector<std::string> Row(const dds::msg::TrackEstimate& m);
std::vector<std::string> Row(const dds::msg::SensorPositionEstimate& m);
std::vector<std::string> Row(const dds::msg::MapFix& m);

}  // namespace magnav::tools
