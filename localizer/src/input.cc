#include "magnav/localizer/input.h"

#include <cmath>
#include <limits>
#include <set>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"

namespace magnav::localizer {

namespace {

std::string Where(const CsvTable& c, std::size_t row, const std::string& column) {
  return c.source() + ":" + std::to_string(c.line_of(row)) + ": column '" + column + "': ";
}

// A position or length (m) within the readers' limit, else an error naming the cell.
double Metres(const CsvTable& c, std::size_t row, std::size_t col) {
  const double v = c.number(row, col);
  if (!WithinLimit(kLimitPosition, v)) throw InputError(Where(c, row, c.header()[col]) + OutOfRange(kLimitPosition, v));
  return v;
}

bool BInRange(const Eigen::Vector3d& B_T) { return B_T.cwiseAbs().maxCoeff() <= MaxAbs(kLimitB); }

// A time (s) within kLimitTime, not going backwards and at most
// kLimitTimeStep after `previous` (NaN: the first row), else an error naming the cell.
double Time(const CsvTable& c, std::size_t row, std::size_t col, double previous) {
  const double t = c.number(row, col);
  const std::string& name = c.header()[col];
  if (!WithinLimit(kLimitTime, t)) throw InputError(Where(c, row, name) + OutOfRange(kLimitTime, t));
  if (std::isnan(previous)) return t;
  if (t < previous) {
    throw InputError(Where(c, row, name) + "time goes backwards (" + FormatNumber(t) + " s after " +
                     FormatNumber(previous) + " s; rows must be ordered by t)");
  }
  if (t - previous > MaxAbs(kLimitTimeStep)) {
    throw InputError(Where(c, row, name) + "time jumps " + FormatNumber(t - previous) + " s ahead of the previous row (" +
                     FormatNumber(t) + " s after " + FormatNumber(previous) + " s; more than " +
                     FormatNumber(MaxAbs(kLimitTimeStep)) + " s: a broken time, or two passes in one file)");
  }
  return t;
}

}  // namespace

int Pass::SensorIndex(std::uint32_t sensor_id) const {
  for (std::size_t i = 0; i < sensors.size(); ++i) {
    if (sensors[i].sensor_id == sensor_id) return static_cast<int>(i);
  }
  return -1;
}

std::vector<SensorPrior> ReadDeploymentFile(const std::string& path) {
  const CsvTable d = CsvTable::Read(path);
  Pass pass;
  const std::size_t id = d.column("sensor_id"), x = d.column("x"), y = d.column("y"), z = d.column("z"),
                    s = d.column("sigma_xy");
  for (std::size_t i = 0; i < d.num_rows(); ++i) {
    SensorPrior p;
    p.sensor_id = d.uint32(i, id);
    p.p_SinW_m = {Metres(d, i, x), Metres(d, i, y), Metres(d, i, z)};
    p.sigma_xy_m = Metres(d, i, s);
    if (!(p.sigma_xy_m > 0.0)) throw InputError(Where(d, i, "sigma_xy") + "must be > 0");
    if (pass.SensorIndex(p.sensor_id) >= 0) {
      throw InputError(Where(d, i, "sensor_id") + "sensor " + std::to_string(p.sensor_id) + " listed twice");
    }
    pass.sensors.push_back(p);
  }
  if (pass.sensors.empty()) throw InputError(path + ": no sensor");
  return pass.sensors;
}

PassFile ReadPassFiles(const std::string& measurements_path, const std::string& deployment_path,
                       const std::string& gnss_path, const std::optional<Eigen::Vector3d>& moment_body_Am2) {
  PassFile out;
  Pass& pass = out.pass;

  pass.sensors = ReadDeploymentFile(deployment_path);
  const CsvTable d = CsvTable::Read(deployment_path);  // for line numbers in errors below

  // Measurements.
  const CsvTable m = CsvTable::Read(measurements_path);
  if (moment_body_Am2) {
    pass.vessel.m_B_Am2 = *moment_body_Am2;
  } else if (const auto v = m.param_vec3("moment_body_Am2")) {
    pass.vessel.m_B_Am2 = *v;
  } else {
    throw InputError(measurements_path +
                     ": no vessel moment: give --moment-body MX,MY,MZ or a '# moment_body_Am2: MX, MY, MZ' line "
                     "(A*m^2, body frame)");
  }
  if (!pass.vessel.m_B_Am2.allFinite() || pass.vessel.m_B_Am2.norm() == 0.0) {
    throw InputError(measurements_path + ": the vessel moment must be finite and non-zero");
  }
  if (const auto z = m.param_number("vessel_z_m")) {
    pass.vessel.z_m = *z;
  } else {
    throw InputError(measurements_path + ": no vessel depth: give a '# vessel_z_m: Z' line (m, NED z)");
  }
  out.sigma_B_T = m.param_number("sigma_B_T");
  if (out.sigma_B_T && !(*out.sigma_B_T > 0.0)) {
    throw InputError(measurements_path + ": parameter 'sigma_B_T' must be > 0");
  }
  {
    const std::size_t t = m.column("t"), id = m.column("sensor_id"), bx = m.column("B_x"), by = m.column("B_y"),
                      bz = m.column("B_z");
    std::vector<char> seen(pass.sensors.size(), 0);
    pass.samples.reserve(m.num_rows());
    for (std::size_t i = 0; i < m.num_rows(); ++i) {
      MagSample s;
      s.t_s = Time(m, i, t, pass.samples.empty() ? NAN : pass.samples.back().t_s);
      s.sensor_id = m.uint32(i, id);
      s.B_T = {m.number(i, bx), m.number(i, by), m.number(i, bz)};
      for (int k = 0; k < 3; ++k) {
        if (!WithinLimit(kLimitB, s.B_T[k])) {
          throw InputError(Where(m, i, std::string("B_") + "xyz"[k]) + OutOfRange(kLimitB, s.B_T[k]));
        }
      }
      const int k = pass.SensorIndex(s.sensor_id);
      if (k < 0) {
        throw InputError(Where(m, i, "sensor_id") + "sensor " + std::to_string(s.sensor_id) +
                         " is not in the deployment file " + deployment_path);
      }
      seen[static_cast<std::size_t>(k)] = 1;
      pass.samples.push_back(s);
    }
    for (std::size_t k = 0; k < seen.size(); ++k) {
      if (!seen[k]) {
        throw InputError(Where(d, k, "sensor_id") + "sensor " + std::to_string(pass.sensors[k].sensor_id) +
                         " has no sample in " + measurements_path);
      }
    }
  }

  // GNSS.
  if (!gnss_path.empty()) {
    const CsvTable g = CsvTable::Read(gnss_path);
    const std::size_t t = g.column("t"), x = g.column("x"), y = g.column("y"), s = g.column("sigma");
    for (std::size_t i = 0; i < g.num_rows(); ++i) {
      GnssFix f;
      f.t_s = Time(g, i, t, pass.gnss.empty() ? NAN : pass.gnss.back().t_s);
      const double first = pass.samples.front().t_s, last = pass.samples.back().t_s;
      const double max_step = MaxAbs(kLimitTimeStep);
      if (f.t_s < first - max_step || f.t_s > last + max_step) {
        throw InputError(Where(g, i, "t") + FormatNumber(f.t_s) + " s is more than " + FormatNumber(max_step) +
                         " s outside the measurements' time span [" + FormatNumber(first) + ", " +
                         FormatNumber(last) + "] s (" + measurements_path + ")");
      }
      f.p_xy_m = {Metres(g, i, x), Metres(g, i, y)};
      f.sigma_m = Metres(g, i, s);
      if (!(f.sigma_m > 0.0)) throw InputError(Where(g, i, "sigma") + "must be > 0");
      pass.gnss.push_back(f);
    }
  }
  return out;
}

const char* SampleCheckName(SampleCheck check) {
  switch (check) {
    case SampleCheck::kOk:
      return "ok";
    case SampleCheck::kNonFinite:
      return "non-finite value";
    case SampleCheck::kUnknownSensor:
      return "unknown sensor id";
    case SampleCheck::kTimeBackwards:
      return "time goes backwards";
    case SampleCheck::kBadSigma:
      return "sigma not > 0";
    case SampleCheck::kOutOfRange:
      return "value out of range";
    case SampleCheck::kAlreadyConsumed:
      return "already in the checkpoint";
  }
  return "?";
}

InputGate::InputGate(const std::vector<SensorPrior>& sensors)
    : last_gnss_t_(-std::numeric_limits<double>::infinity()) {
  for (const auto& s : sensors) last_t_[s.sensor_id] = -std::numeric_limits<double>::infinity();
}

SampleCheck InputGate::Check(const MagSample& sample) {
  if (!std::isfinite(sample.t_s) || !sample.B_T.allFinite()) return SampleCheck::kNonFinite;
  if (!BInRange(sample.B_T)) return SampleCheck::kOutOfRange;
  const auto it = last_t_.find(sample.sensor_id);
  if (it == last_t_.end()) return SampleCheck::kUnknownSensor;
  if (sample.t_s < it->second) return SampleCheck::kTimeBackwards;
  it->second = sample.t_s;
  return SampleCheck::kOk;
}

SampleCheck InputGate::Check(const GnssFix& fix) {
  if (!std::isfinite(fix.t_s) || !fix.p_xy_m.allFinite() || !std::isfinite(fix.sigma_m)) {
    return SampleCheck::kNonFinite;
  }
  if (!(fix.sigma_m > 0.0)) return SampleCheck::kBadSigma;
  if (fix.p_xy_m.cwiseAbs().maxCoeff() > MaxAbs(kLimitPosition) || fix.sigma_m > MaxAbs(kLimitPosition)) {
    return SampleCheck::kOutOfRange;
  }
  if (fix.t_s < last_gnss_t_) return SampleCheck::kTimeBackwards;
  last_gnss_t_ = fix.t_s;
  return SampleCheck::kOk;
}

}  // namespace magnav::localizer
