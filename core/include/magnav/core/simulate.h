// Scenario simulator: a vessel (magnetic dipole fixed in its body) moving by
// coordinated-turn segments past fixed tensor gradiometers, with the noise
// model of the reference data (see tests/data/reference/README.md):
//   B noise N(0, σ_B²) per axis; T noise symmetric and trace-free: each
//   off-diagonal pair shares one N(0, σ_T²) draw, the diagonal gets three
//   N(0, 1.5 σ_T²) draws minus their mean (each element has std σ_T).
// Frames: world NED, metres, seconds, tesla; heading from north clockwise.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "magnav/core/gradiometer.h"

namespace magnav {

struct TurnSegment {
  double duration_s = 0.0;      // > 0
  double turn_rate_rps = 0.0;   // rad/s, positive = turning right
};

struct PassScenario {
  Eigen::Vector3d moment_body = {2000.0, 300.0, 800.0};  // A·m², body x fwd, y stbd, z down
  // Defaults: the reference AUV pass (tests/data/reference/track_truth_auv.csv).
  Eigen::Vector3d start_position = {-54.78629329738587, -51.37569529196478, -5.0};  // NED, m
  double speed_mps = 1.0;
  double start_heading_rad = 0.7;
  std::vector<TurnSegment> segments = {{80.0, 0.0}, {60.0, 0.02}, {60.0, 0.0}};
  double rate_hz = 10.0;                                  // samples per second
  std::vector<Eigen::Vector3d> sensors = {Eigen::Vector3d::Zero()};  // NED, m
  Eigen::Vector3d B0 = {2e-05, 1e-06, 4.5e-05};           // background field, T
  double sigma_B = 0.0;                                   // T per axis (0 = noise-free)
  double sigma_T = 0.0;                                   // T/m per element
  std::uint64_t seed = 1;

  bool IsValid(std::string* error) const;
  double duration_s() const;
};

// True vessel state at one instant.
struct VesselTruth {
  double t_s = 0.0;
  Eigen::Vector3d p_VinW = Eigen::Vector3d::Zero();  // vessel (dipole) position, NED, m
  Eigen::Vector2d v_VinW = Eigen::Vector2d::Zero();  // horizontal velocity (north, east), m/s
  double heading_rad = 0.0;                          // wrapped to (−π, π]
  double turn_rate_rps = 0.0;
  Eigen::Vector3d m_W = Eigen::Vector3d::Zero();     // world moment, A·m²
};

struct SimulatedPass {
  std::vector<VesselTruth> truth;            // one per instant
  std::vector<GradiometerSample> samples;    // ordered by t, then sensor id
};

// Throws InputError if the scenario is invalid (IsValid's message). The
// vessel must never come within 0.5 m of a sensor.
SimulatedPass SimulatePass(const PassScenario& scenario);

// A sensor field crossed by several vessels, each with its own moment,
// motion and time span (the reference field_pass_9sensor_fluxgate.csv is of
// this kind). B and T at a sensor are B0 plus the sum of the fields of the
// vessels present at that instant, plus the noise model above.
struct FieldVessel {
  std::uint32_t vessel_id = 1;                           // > 0, unique in the scenario
  Eigen::Vector3d moment_body = {2000.0, 300.0, 800.0};  // A·m²
  Eigen::Vector3d start_position = Eigen::Vector3d::Zero();  // NED, m, at t_start_s
  double speed_mps = 1.0;
  double start_heading_rad = 0.0;
  std::vector<TurnSegment> segments = {{200.0, 0.0}};  // the vessel exists for their total duration
  double t_start_s = 0.0;                               // s from scenario start, >= 0
  // Instead of start_position, start_heading_rad and segments (when it has
  // two or more points): straight legs through these points (NED, m) at
  // speed_mps (> 0, along the 3-D path), from the first point at t_start_s
  // until the last; heading along each leg's horizontal direction (each leg
  // must move horizontally), turn rate 0, the truth's velocity horizontal.
  std::vector<Eigen::Vector3d> waypoints;

  bool IsValid(std::string* error) const;
  double t_end_s() const;
};

struct FieldScenario {
  std::vector<FieldVessel> vessels;  // at least one
  double rate_hz = 10.0;
  std::vector<Eigen::Vector3d> sensors;  // NED, m; at least one
  Eigen::Vector3d B0 = {2e-05, 1e-06, 4.5e-05};
  double sigma_B = 0.0;
  double sigma_T = 0.0;
  std::uint64_t seed = 1;
  // Per-sensor background drift, T/s (NED): sensor j's background at time t
  // is B0 + background_drift_Tps[j]·t (the slow change of a far source or of
  // the sensor itself). Empty: none; otherwise one per sensor.
  std::vector<Eigen::Vector3d> background_drift_Tps;

  bool IsValid(std::string* error) const;
  double duration_s() const;  // until the last vessel's end
};

struct SimulatedField {
  std::vector<std::vector<VesselTruth>> truth;  // per vessel (scenario order), per instant while it exists
  std::vector<GradiometerSample> samples;       // every sensor at every instant, ordered by t then sensor id
};

// Throws InputError if the scenario is invalid or a vessel comes within
// 0.5 m of a sensor.
SimulatedField SimulateField(const FieldScenario& scenario);

// n drift vectors of magnitude rate_Tps each, in directions uniform on the
// sphere drawn from `seed` (the per-sensor drifts of a scenario file).
std::vector<Eigen::Vector3d> RandomDrifts(std::size_t n, double rate_Tps, std::uint64_t seed);

// A regular grid of nx × ny sensors at z = 0, `spacing_m` apart, centred on
// the origin, ids row by row (id = ny·ix + iy, x north) as the reference field.
std::vector<Eigen::Vector3d> SensorGrid(int nx, int ny, double spacing_m);

// Files in the reference formats (pass: t,sensor_id,sensor_*,B_*,T00..T22 with
// B0_T, moment_body_Am2, sigma_B_T, sigma_T_Tpm parameters; truth: t,x,y,z,
// vx,vy,heading,turn_rate,mw_x,mw_y,mw_z).
void WritePassCsv(const std::string& path, const PassScenario& scenario, const SimulatedPass& pass);
void WriteTruthCsv(const std::string& path, const PassScenario& scenario, const SimulatedPass& pass);
// A field: the pass file as above (no moment line: each vessel has its own;
// a `# vessel:` line per vessel, a `# background_drift_Tps:` line per
// sensor when there is drift), the truth with `vessel_id` after `t`, rows
// ordered by t then vessel_id (as field_truth.csv).
void WriteFieldPassCsv(const std::string& path, const FieldScenario& scenario, const SimulatedField& field);
void WriteFieldTruthCsv(const std::string& path, const FieldScenario& scenario, const SimulatedField& field);

}  // namespace magnav
