// One plain struct per topic type: field for field what the message says
// (idl/magnav.idl), in the project's C++ types (Eigen vectors and matrices,
// enum classes), with nothing dropped or rounded — time stays in integer
// nanoseconds, sequence numbers and every enum value (also one this build
// does not know yet) are kept. dds::FromMsg / dds::ToMsg (convert.h) turn a
// message into its record and back exactly (tests/dds/convert_test.cc).
//
// Frames and units are the IDL's: world NED (x north, y east, z down) about
// the field's local origin, SI (m, s, T, T/m, A·m², rad), time stamps in ns
// since the scenario/epoch start, covariances in the units squared.
//
// No DDS header here: a record can be built and read without Fast DDS.
#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Dense>

namespace magnav::dds {

// The IDL enums, value for value (static_asserts in convert.cc). A value
// past the last one named here (a newer writer's appended one) is carried
// through unchanged.
enum class FixMethod : std::uint32_t {
  kTed = 0,      // tensor Euler deconvolution
  kTedEgt = 1,   // TED + eigenvector constraint
  kEgt = 2,      // eigen-analysis closed form
  kMc = 3,       // Monte-Carlo (particle filter) inversion
  kTracker = 4,  // refined by the tracker
  kOther = 5,
  kPf = 6,    // map matching: particle filter
  kAfpf = 7,  // map matching: adaptive fission particle filter
};
enum class MapFixStatus : std::uint32_t {
  kUnknown = 0,  // not filled (a publisher older than the field)
  kOk = 1,       // tracking: no lost-track alarm
  kLost = 2,     // the lost-track detector is raised: do not use the position
  kOffMap = 3,   // every particle off the map: dead-reckoning on the INS
  kPartlyObservable = 4,  // the map knows less than the INS prior along its least observed direction
  kConverging = 5,        // the filter has not settled yet: the position is not a trusted fix
};
// TrackEstimate.state (the wire's TrackState; tracker::TrackState in the library).
enum class TrackState : std::uint32_t {
  kUnknown = 0,    // not filled (a publisher older than the field)
  kConfirmed = 1,  // detected at this epoch
  kCoasting = 2,   // not detected: the motion model's prediction
};
enum class NavSource : std::uint32_t { kGnss = 0, kIns = 1, kOther = 2 };

// magnav/gradiometer.
struct GradiometerRecord {
  std::uint32_t sensor_id = 0;
  std::uint64_t stamp_ns = 0;
  std::uint64_t seq = 0;
  Eigen::Vector3d p_SinW_m = Eigen::Vector3d::Zero();  // sensor position
  Eigen::Vector3d B_T = Eigen::Vector3d::Zero();       // flux density incl. background (sensor axes = NED)
  Eigen::Matrix3d T_Tpm = Eigen::Matrix3d::Zero();     // gradient tensor, T(i, j) = ∂B_i/∂x_j
  double sigma_B_T = 0.0;                              // 0 = unknown
  double sigma_T_Tpm = 0.0;                            // 0 = unknown
};

// magnav/magnetometer.
struct MagnetometerRecord {
  std::uint32_t sensor_id = 0;
  std::uint64_t stamp_ns = 0;
  std::uint64_t seq = 0;
  Eigen::Vector3d p_SinW_m = Eigen::Vector3d::Zero();  // nominal / deployed; NaN if unknown
  Eigen::Vector3d B_T = Eigen::Vector3d::Zero();
  double sigma_B_T = 0.0;
};

// magnav/vessel_nav.
struct VesselNavRecord {
  std::uint32_t vessel_id = 0;
  std::uint64_t stamp_ns = 0;
  NavSource source = NavSource::kGnss;
  Eigen::Vector3d p_VinW_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_VinW_mps = Eigen::Vector3d::Zero();
  double heading_rad = 0.0;  // from north, clockwise seen from above
  Eigen::Vector3d sigma_p_m = Eigen::Vector3d::Zero();  // 1-σ per axis
  double sigma_v_mps = 0.0;
  double sigma_heading_rad = 0.0;
  Eigen::Vector3d geodetic = Eigen::Vector3d::Zero();  // WGS84 lat (deg), lon (deg), height (m); NaN if unknown
};

// magnav/dipole_fix.
struct DipoleFixRecord {
  std::uint32_t sensor_id = 0;
  std::uint64_t stamp_ns = 0;  // of the sample it came from
  std::uint64_t sample_seq = 0;
  FixMethod method = FixMethod::kTed;
  bool valid = false;
  std::string reason;  // at most 64 characters on the wire; "" when valid
  Eigen::Vector3d p_DinW_m = Eigen::Vector3d::Zero();
  bool has_moment = false;
  Eigen::Vector3d m_W_Am2 = Eigen::Vector3d::Zero();
  double condition_number = 0.0;
  Eigen::Matrix3d cov_p_m2 = Eigen::Matrix3d::Zero();  // all 0 = unknown
};

// magnav/track.
struct TrackRecord {
  std::uint32_t track_id = 0;
  std::uint64_t stamp_ns = 0;
  Eigen::Vector3d p_VinW_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_VinW_mps = Eigen::Vector3d::Zero();
  double heading_rad = 0.0;
  double turn_rate_radps = 0.0;  // positive = turning right
  Eigen::Matrix3d cov_p_m2 = Eigen::Matrix3d::Zero();
  Eigen::Vector3d m_B_Am2 = Eigen::Vector3d::Zero();  // body axes (x fwd, y starboard, z down)
  Eigen::Matrix3d cov_m_B = Eigen::Matrix3d::Zero();  // (A·m²)²
  std::uint32_t num_sensors = 0;
  bool usable = false;
  TrackState state = TrackState::kUnknown;
};

// magnav/sensor_position.
struct SensorPositionRecord {
  std::uint32_t sensor_id = 0;
  std::uint64_t stamp_ns = 0;
  Eigen::Vector3d p_SinW_m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov_m2 = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d crlb_m2 = Eigen::Matrix3d::Zero();
};

// magnav/map_fix.
struct MapFixRecord {
  std::uint32_t vehicle_id = 0;
  std::uint64_t stamp_ns = 0;
  FixMethod method = FixMethod::kOther;
  std::string method_name;  // at most 32 characters on the wire
  double lat_deg = 0.0;     // WGS84
  double lon_deg = 0.0;
  double score = 0.0;
  Eigen::Matrix2d cov_ne_m2 = Eigen::Matrix2d::Zero();  // (north, east)
  MapFixStatus status = MapFixStatus::kUnknown;
};

}  // namespace magnav::dds
