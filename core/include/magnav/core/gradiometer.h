// One gradiometer sample as the libraries see it (the DDS adapter converts its
// IDL type to this), and the reader of gradiometer files.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "magnav/core/limits.h"

namespace magnav {

struct GradiometerSample {
  std::uint32_t sensor_id = 0;
  double t_s = 0.0;                            // time, s (scenario time)
  Eigen::Vector3d p_SinW = Eigen::Vector3d::Zero();  // sensor position, world NED, m
  Eigen::Vector3d B = Eigen::Vector3d::Zero();       // field incl. background, sensor axes = NED, T
  Eigen::Matrix3d T = Eigen::Matrix3d::Zero();       // gradient tensor, T/m
  double sigma_B = 0.0;                        // 1-σ noise per axis, T (0 = unknown)
  double sigma_T = 0.0;                        // 1-σ noise per element, T/m (0 = unknown)
};

// Largest magnitudes a sample may hold (per element): kLimitPosition,
// kLimitB, kLimitT of the project's one table of limits (core/limits.h; a
// site may set its own, LoadSiteLimits). Beyond them a value is not a reading (1e308, or nT/µT/km
// written where T/m are meant). B up to 1 T (a dipole 1 m away gives 1e-2 T:
// the reference cases reach 5e-3 T), a gradient up to 10 T/m, positions up to
// 10 000 km. Files (ReadGradiometerFile) and the wire (CheckSample) apply the
// same limits.

// What is wrong with a sample, checked at the door before any estimator sees
// it (CheckSample). Stable snake_case names (SampleDefectName): "" for kNone.
enum class SampleDefect {
  kNone = 0,
  kNonFiniteTime,  // t_s NaN or ±inf
  kNonFinite,      // B, T or the sensor position not finite (NaN, ±inf)
  kBadSigma,       // sigma_B or sigma_T negative or not finite (0 = unknown is fine)
  kZeroTensor,     // every element of T is exactly 0: a dead or unwired gradiometer
  kOutOfRange,     // finite but beyond the limits in force (core/limits.h): a sensor position, B or T no instrument gives
};
const char* SampleDefectName(SampleDefect defect);

// The checks every consumer of samples (inverter, trackers, estimators of B0)
// applies first. Does not judge signal strength, symmetry or the dipole's
// range: those are the estimators' own gates.
SampleDefect CheckSample(const GradiometerSample& sample);

// Everything a gradiometer file holds: the samples plus its parameters.
struct GradiometerFile {
  std::string path;
  std::vector<GradiometerSample> samples;
  std::vector<long long> case_ids;        // from a `case_id` column, else empty
  bool has_time = false;                  // the file has a `t` column
  bool has_sensor_id = false;             // the file has a `sensor_id` column
  std::vector<int> lines;                 // source line of each sample
  std::optional<Eigen::Vector3d> B0;           // "# B0_T:" (T)
  std::optional<Eigen::Vector3d> moment_body;  // "# moment_body_Am2:" (A·m²)
  std::optional<double> sigma_B;               // "# sigma_B_T:"
  std::optional<double> sigma_T;               // "# sigma_T_Tpm:"
};

// Column names of the field and tensor in files: B_x,B_y,B_z and T00..T22.
// `prefix_B`/`prefix_T` select other sets (the reference dipole cases carry
// noisy copies as Bn_*, Tn*).
struct GradiometerColumns {
  std::string B = "B_";
  std::string T = "T";
};

// Name of the tensor column (i, j) in files: prefix + "ij", e.g. "T01".
std::string TensorColumnName(const std::string& prefix, int i, int j);

// The 15 data columns of a gradiometer row, in file order:
// sensor_x,sensor_y,sensor_z, B_x,B_y,B_z, T00..T22.
std::vector<std::string> GradiometerDataColumns();

// Reads columns sensor_x,sensor_y,sensor_z, B_x..B_z, T00..T22, t (or, for
// rows that are independent cases, case_id) and, if present, sensor_id.
// Every value must be within the limits above. Sample sigmas come from per-row
// sigma_B, sigma_T columns if present (as magnav record writes them), else
// the file's sigma parameters (0 = unknown when absent). Throws InputError naming file, line and
// column on any problem.
GradiometerFile ReadGradiometerFile(const std::string& path, const GradiometerColumns& cols = {});

}  // namespace magnav
