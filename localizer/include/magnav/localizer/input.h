// Input of the sensor localiser, checked at the door: the three files of
// `magnav localize` (measurements, deployment, GNSS) and the gate every live
// sample passes before an estimator sees it.
//
// Files (as ../shared/reference/localize_*.csv; frames and units as types.h):
//   measurements: t, sensor_id, B_x, B_y, B_z (T); "# moment_body_Am2: X, Y, Z",
//                 "# vessel_z_m: Z" and optionally "# sigma_B_T: S"; rows in time order
//   deployment:   sensor_id, x, y, z, sigma_xy (m)
//   GNSS:         t, x, y, sigma (m); rows in time order
// Every problem throws InputError naming the file, line and column.
#pragma once

#include "magnav/core/limits.h"

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "magnav/localizer/types.h"

namespace magnav::localizer {

// A pass read from files, with the noise level the measurements file states.
struct PassFile {
  Pass pass;
  std::optional<double> sigma_B_T;  // "# sigma_B_T:" of the measurements file
};

// Reads and checks a deployment file (the service takes only this one).
std::vector<SensorPrior> ReadDeploymentFile(const std::string& path);

// Time limits of the files (s; core/limits.h, the site's if it set them). A
// pass is minutes to hours long: a row more than kLimitTimeStep (1 h) after
// the previous row of its file, or a GNSS fix more than that outside the
// measurements' time span, is a broken time (1e300, a stamp in ns or from
// another clock), not a pass; |t| beyond kLimitTime (317 years: Unix and GPS
// seconds fit) is refused outright.

// Reads and checks the files. `moment_body_Am2` overrides the measurements
// file's "# moment_body_Am2:" line; without either the call refuses (no
// default moment). `gnss_path` may be empty (no fixes). Checks: finite
// numbers within the readers' limits (|B_i| ≤ 1 T, positions and σ ≤ 1e7 m,
// the time limits above), known sensor ids, time not going backwards, positive sigmas, no
// duplicate sensor in the deployment, every deployed sensor measured at least
// once, the vessel depth stated.
PassFile ReadPassFiles(const std::string& measurements_path, const std::string& deployment_path,
                       const std::string& gnss_path, const std::optional<Eigen::Vector3d>& moment_body_Am2);

// Why a live sample is refused.
// kOutOfRange: finite but a value no instrument gives, the limits the file
// readers hold to (core/gradiometer.h): |B_i| beyond kLimitB (1 T: nT or µT
// sent as T), a GNSS position or σ beyond kLimitPosition (1e7 m).
// kAlreadyConsumed: StreamingLocalizer only, an item a restored checkpoint
// has consumed already (older than its consumed-until time; a restarted
// service gets it again from the writers' history): not an error.
enum class SampleCheck { kOk, kNonFinite, kUnknownSensor, kTimeBackwards, kBadSigma, kOutOfRange, kAlreadyConsumed };
const char* SampleCheckName(SampleCheck check);

// The door for live samples (the service): a sample is accepted only if it is
// finite, within range, from a deployed sensor and not older than the last accepted sample
// of the same stream (per sensor; the GNSS is one stream). Accepting records
// its time. Not thread-safe.
class InputGate {
 public:
  explicit InputGate(const std::vector<SensorPrior>& sensors);
  SampleCheck Check(const MagSample& sample);
  SampleCheck Check(const GnssFix& fix);

 private:
  std::map<std::uint32_t, double> last_t_;  // per known sensor; −inf before the first
  double last_gnss_t_;
};

}  // namespace magnav::localizer
