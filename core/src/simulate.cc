#include "magnav/core/simulate.h"

#include <cmath>
#include <functional>
#include <algorithm>
#include <random>

#include "magnav/core/csv.h"
#include "magnav/core/dipole.h"
#include "magnav/core/error.h"
#include "magnav/core/frames.h"
#include "magnav/core/motion.h"
#include "magnav/core/units.h"

namespace magnav {

namespace {

// Symmetric trace-free tensor noise with per-element std sigma.
Eigen::Matrix3d TensorNoise(std::mt19937_64& rng, double sigma) {
  std::normal_distribution<double> off(0.0, sigma), diag(0.0, std::sqrt(1.5) * sigma);
  Eigen::Matrix3d N;
  const double a = off(rng), b = off(rng), c = off(rng);
  Eigen::Vector3d d(diag(rng), diag(rng), diag(rng));
  d.array() -= d.mean();
  N << d[0], a, b, a, d[1], c, b, c, d[2];
  return N;
}

}  // namespace

namespace {

// A vessel's exact coordinated-turn trajectory through its segments (state at
// the start of each segment, no accumulation per sample).
class SegmentedMotion {
 public:
  SegmentedMotion(const Eigen::Vector3d& p0, double speed, double heading, const std::vector<TurnSegment>& segments) {
    CtState<double> s{p0.x(), p0.y(), p0.z(), speed, heading, segments[0].turn_rate_rps};
    double t0 = 0.0;
    for (const auto& seg : segments) {
      s.turn_rate = seg.turn_rate_rps;
      seg_start_.push_back(s);
      seg_t0_.push_back(t0);
      s = PropagateCoordinatedTurn(s, seg.duration_s);
      t0 += seg.duration_s;
    }
  }
  // The truth at time t (s since the vessel's start); a time exactly at a
  // boundary belongs to the later segment.
  VesselTruth At(double t, const Eigen::Vector3d& moment_body) const {
    std::size_t i = 0;
    while (i + 1 < seg_t0_.size() && t >= seg_t0_[i + 1] - 1e-12) ++i;
    const CtState<double> st = PropagateCoordinatedTurn(seg_start_[i], t - seg_t0_[i]);
    VesselTruth tr;
    tr.t_s = t;
    tr.p_VinW = {st.x, st.y, st.z};
    tr.heading_rad = WrapAngle(st.heading);
    tr.v_VinW = {st.v * std::cos(st.heading), st.v * std::sin(st.heading)};
    tr.turn_rate_rps = st.turn_rate;
    tr.m_W = WorldMoment(moment_body, st.heading);
    return tr;
  }

 private:
  std::vector<CtState<double>> seg_start_;
  std::vector<double> seg_t0_;
};

// A vessel's straight legs through waypoints at constant speed.
class WaypointMotion {
 public:
  WaypointMotion(const std::vector<Eigen::Vector3d>& points, double speed) : points_(points), speed_(speed) {
    double t = 0.0;
    for (std::size_t i = 0; i + 1 < points.size(); ++i) {
      leg_t0_.push_back(t);
      t += (points[i + 1] - points[i]).norm() / speed;
    }
    leg_t0_.push_back(t);
  }
  VesselTruth At(double t, const Eigen::Vector3d& moment_body) const {
    std::size_t i = 0;
    while (i + 2 < leg_t0_.size() && t >= leg_t0_[i + 1] - 1e-12) ++i;
    const Eigen::Vector3d d = points_[i + 1] - points_[i];
    const Eigen::Vector3d u = d / d.norm();
    const double s = std::min(std::max(t - leg_t0_[i], 0.0), leg_t0_[i + 1] - leg_t0_[i]);
    VesselTruth tr;
    tr.t_s = t;
    tr.p_VinW = points_[i] + u * (speed_ * s);
    const double heading = std::atan2(d.y(), d.x());
    tr.heading_rad = WrapAngle(heading);
    tr.v_VinW = speed_ * u.head<2>();
    tr.turn_rate_rps = 0.0;
    tr.m_W = WorldMoment(moment_body, heading);
    return tr;
  }
  double duration_s() const { return leg_t0_.back(); }

 private:
  std::vector<Eigen::Vector3d> points_;
  double speed_;
  std::vector<double> leg_t0_;
};

double PathDuration(const std::vector<Eigen::Vector3d>& points, double speed) {
  double d = 0.0;
  for (std::size_t i = 0; i + 1 < points.size(); ++i) d += (points[i + 1] - points[i]).norm();
  return d / speed;
}

double TotalDuration(const std::vector<TurnSegment>& segments) {
  double d = 0.0;
  for (const auto& s : segments) d += s.duration_s;
  return d;
}

std::string CheckSegments(const std::vector<TurnSegment>& segments) {
  if (segments.empty()) return "at least one turn segment is needed";
  for (std::size_t i = 0; i < segments.size(); ++i) {
    if (!(segments[i].duration_s > 0.0) || !std::isfinite(segments[i].duration_s) ||
        !std::isfinite(segments[i].turn_rate_rps)) {
      return "segment " + std::to_string(i) + ": duration must be > 0 and values finite";
    }
  }
  return {};
}

// The sampling, sensors, background and noise of a scenario ("" if valid).
std::string CheckSensing(double rate_hz, const std::vector<Eigen::Vector3d>& sensors, const Eigen::Vector3d& B0,
                         double sigma_B, double sigma_T) {
  if (!(rate_hz > 0.0) || rate_hz > 1e4) return "rate_hz must be in (0, 10000]";
  if (sensors.empty()) return "at least one sensor is needed";
  for (const auto& s : sensors) {
    if (!s.allFinite()) return "sensor positions must be finite";
  }
  if (!B0.allFinite()) return "B0 must be finite";
  if (!(sigma_B >= 0.0) || !(sigma_T >= 0.0) || !std::isfinite(sigma_B) || !std::isfinite(sigma_T)) {
    return "sigma_B and sigma_T must be finite and >= 0";
  }
  return {};
}

// The field of a vessel at a sensor, added to g (throws within 0.5 m).
void AddVesselField(const VesselTruth& tr, std::size_t sensor, double t, GradiometerSample* g) {
  const Eigen::Vector3d r = g->p_SinW - tr.p_VinW;
  if (r.norm() < 0.5) {
    throw InputError("scenario: a vessel passes within 0.5 m of sensor " + std::to_string(sensor) +
                     " at t = " + FormatNumber(t) + " s");
  }
  Eigen::Vector3d B;
  Eigen::Matrix3d T;
  DipoleBT(r, tr.m_W, &B, &T);
  g->B += B;
  g->T += T;
}

}  // namespace

bool PassScenario::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!moment_body.allFinite()) return fail("moment_body must be finite");
  if (!start_position.allFinite() || !std::isfinite(start_heading_rad)) return fail("start state must be finite");
  if (!(speed_mps >= 0.0) || !std::isfinite(speed_mps)) return fail("speed_mps must be finite and >= 0");
  if (const std::string e = CheckSegments(segments); !e.empty()) return fail(e);
  if (const std::string e = CheckSensing(rate_hz, sensors, B0, sigma_B, sigma_T); !e.empty()) return fail(e);
  if (duration_s() * rate_hz > 1e7) return fail("more than 1e7 instants: shorten the scenario or lower the rate");
  return true;
}

double PassScenario::duration_s() const { return TotalDuration(segments); }

SimulatedPass SimulatePass(const PassScenario& sc) {
  std::string err;
  if (!sc.IsValid(&err)) throw InputError("scenario: " + err);
  FieldScenario field;
  FieldVessel v;
  v.moment_body = sc.moment_body;
  v.start_position = sc.start_position;
  v.speed_mps = sc.speed_mps;
  v.start_heading_rad = sc.start_heading_rad;
  v.segments = sc.segments;
  field.vessels = {v};
  field.rate_hz = sc.rate_hz;
  field.sensors = sc.sensors;
  field.B0 = sc.B0;
  field.sigma_B = sc.sigma_B;
  field.sigma_T = sc.sigma_T;
  field.seed = sc.seed;
  SimulatedField f = SimulateField(field);
  return {std::move(f.truth[0]), std::move(f.samples)};
}

bool FieldVessel::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = "vessel " + std::to_string(vessel_id) + ": " + m;
    return false;
  };
  if (vessel_id == 0) return fail("vessel_id must be > 0");
  if (!moment_body.allFinite()) return fail("moment_body must be finite");
  if (!start_position.allFinite() || !std::isfinite(start_heading_rad)) return fail("start state must be finite");
  if (!(speed_mps >= 0.0) || !std::isfinite(speed_mps)) return fail("speed_mps must be finite and >= 0");
  if (!(t_start_s >= 0.0) || !std::isfinite(t_start_s)) return fail("t_start_s must be finite and >= 0");
  if (waypoints.size() == 1) return fail("waypoints: give two or more points (or none)");
  if (!waypoints.empty()) {
    if (!(speed_mps > 0.0)) return fail("a vessel on waypoints needs speed_mps > 0");
    for (std::size_t i = 0; i < waypoints.size(); ++i) {
      if (!waypoints[i].allFinite()) return fail("waypoints must be finite");
      if (i > 0 && (waypoints[i] - waypoints[i - 1]).head<2>().norm() < 1e-6) {
        return fail("waypoint " + std::to_string(i) + " is not horizontally apart from the one before");
      }
    }
    if (PathDuration(waypoints, speed_mps) > 1e7) return fail("waypoints: the path takes more than 1e7 s");
    return true;
  }
  if (const std::string e = CheckSegments(segments); !e.empty()) return fail(e);
  return true;
}

double FieldVessel::t_end_s() const {
  return t_start_s + (waypoints.size() >= 2 ? PathDuration(waypoints, speed_mps) : TotalDuration(segments));
}

bool FieldScenario::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (vessels.empty()) return fail("at least one vessel is needed");
  for (std::size_t i = 0; i < vessels.size(); ++i) {
    if (!vessels[i].IsValid(error)) return false;
    for (std::size_t j = 0; j < i; ++j) {
      if (vessels[j].vessel_id == vessels[i].vessel_id) {
        return fail("vessel ids must be unique (" + std::to_string(vessels[i].vessel_id) + " twice)");
      }
    }
  }
  if (const std::string e = CheckSensing(rate_hz, sensors, B0, sigma_B, sigma_T); !e.empty()) return fail(e);
  if (!background_drift_Tps.empty()) {
    if (background_drift_Tps.size() != sensors.size()) {
      return fail("background_drift_Tps: one per sensor (" + std::to_string(sensors.size()) + "), got " +
                  std::to_string(background_drift_Tps.size()));
    }
    for (const auto& d : background_drift_Tps) {
      if (!d.allFinite()) return fail("background_drift_Tps must be finite");
    }
  }
  if (duration_s() * rate_hz * static_cast<double>(sensors.size()) > 2e7) {
    return fail("more than 2e7 samples: shorten the scenario, lower the rate or use fewer sensors");
  }
  return true;
}

double FieldScenario::duration_s() const {
  double d = 0.0;
  for (const auto& v : vessels) d = std::max(d, v.t_end_s());
  return d;
}

std::vector<Eigen::Vector3d> RandomDrifts(std::size_t n, double rate_Tps, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Eigen::Vector3d> out;
  out.reserve(n);
  while (out.size() < n) {
    const Eigen::Vector3d d(g(rng), g(rng), g(rng));
    if (d.norm() < 1e-6) continue;
    out.push_back(rate_Tps * d.normalized());
  }
  return out;
}

std::vector<Eigen::Vector3d> SensorGrid(int nx, int ny, double spacing_m) {
  std::vector<Eigen::Vector3d> out;
  for (int ix = 0; ix < nx; ++ix) {
    for (int iy = 0; iy < ny; ++iy) {
      out.push_back({(ix - 0.5 * (nx - 1)) * spacing_m, (iy - 0.5 * (ny - 1)) * spacing_m, 0.0});
    }
  }
  return out;
}

SimulatedField SimulateField(const FieldScenario& sc) {
  std::string err;
  if (!sc.IsValid(&err)) throw InputError("scenario: " + err);
  // Each vessel's motion: segments, or legs through waypoints.
  std::vector<std::function<VesselTruth(double)>> motion;
  for (const auto& v : sc.vessels) {
    if (v.waypoints.size() >= 2) {
      motion.emplace_back([w = WaypointMotion(v.waypoints, v.speed_mps), m = v.moment_body](double t) {
        return w.At(t, m);
      });
    } else {
      motion.emplace_back([s = SegmentedMotion(v.start_position, v.speed_mps, v.start_heading_rad, v.segments),
                           m = v.moment_body](double t) { return s.At(t, m); });
    }
  }
  const auto n = static_cast<std::size_t>(std::floor(sc.duration_s() * sc.rate_hz + 1e-9)) + 1;
  SimulatedField out;
  out.truth.resize(sc.vessels.size());
  out.samples.reserve(n * sc.sensors.size());
  std::mt19937_64 rng(sc.seed);
  std::normal_distribution<double> nB(0.0, 1.0);
  std::vector<VesselTruth> present;
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / sc.rate_hz;
    present.clear();
    for (std::size_t v = 0; v < sc.vessels.size(); ++v) {
      const FieldVessel& fv = sc.vessels[v];
      if (t < fv.t_start_s - 1e-9 || t > fv.t_end_s() + 1e-9) continue;
      VesselTruth tr = motion[v](t - fv.t_start_s);
      tr.t_s = t;
      out.truth[v].push_back(tr);
      present.push_back(tr);
    }
    for (std::size_t j = 0; j < sc.sensors.size(); ++j) {
      GradiometerSample g;
      g.sensor_id = static_cast<std::uint32_t>(j);
      g.t_s = t;
      g.p_SinW = sc.sensors[j];
      g.B = sc.B0;
      if (!sc.background_drift_Tps.empty()) g.B += sc.background_drift_Tps[j] * t;
      g.T.setZero();
      for (const auto& tr : present) AddVesselField(tr, j, t, &g);
      if (sc.sigma_B > 0.0) g.B += sc.sigma_B * Eigen::Vector3d(nB(rng), nB(rng), nB(rng));
      if (sc.sigma_T > 0.0) g.T += TensorNoise(rng, sc.sigma_T);
      g.sigma_B = sc.sigma_B;
      g.sigma_T = sc.sigma_T;
      out.samples.push_back(g);
    }
  }
  return out;
}

namespace {
std::string Vec3Param(const Eigen::Vector3d& v) {
  return FormatNumber(v.x()) + ", " + FormatNumber(v.y()) + ", " + FormatNumber(v.z());
}

void WriteSamples(CsvWriter* w, std::size_t num_columns, const std::vector<GradiometerSample>& samples) {
  std::vector<std::string> f(num_columns);
  for (const auto& g : samples) {
    f[0] = FormatNumber(g.t_s);
    f[1] = std::to_string(g.sensor_id);
    for (int i = 0; i < 3; ++i) f[2 + i] = FormatNumber(g.p_SinW[i]);
    for (int i = 0; i < 3; ++i) f[5 + i] = FormatNumber(g.B[i]);
    for (int k = 0; k < 9; ++k) f[8 + k] = FormatNumber(g.T(k / 3, k % 3));
    w->WriteRow(f);
  }
}

// A truth row; `vessel_id` (non-empty) goes after t.
std::vector<std::string> TruthRow(const VesselTruth& t, const std::string& vessel_id) {
  std::vector<std::string> row = {FormatNumber(t.t_s)};
  if (!vessel_id.empty()) row.push_back(vessel_id);
  for (const double v : {t.p_VinW.x(), t.p_VinW.y(), t.p_VinW.z(), t.v_VinW.x(), t.v_VinW.y(), t.heading_rad,
                         t.turn_rate_rps, t.m_W.x(), t.m_W.y(), t.m_W.z()}) {
    row.push_back(FormatNumber(v));
  }
  return row;
}
}  // namespace

void WritePassCsv(const std::string& path, const PassScenario& sc, const SimulatedPass& pass) {
  std::vector<std::string> header = {"t", "sensor_id"};
  for (std::string& c : GradiometerDataColumns()) header.push_back(std::move(c));
  CsvWriter w(path, header,
              {{"B0_T", Vec3Param(sc.B0)},
               {"moment_body_Am2", Vec3Param(sc.moment_body)},
               {"sigma_B_T", FormatNumber(sc.sigma_B)},
               {"sigma_T_Tpm", FormatNumber(sc.sigma_T)},
               {"seed", std::to_string(sc.seed)}});
  w.AddComment("simulated by magnav: vessel dipole pass over fixed gradiometers; NED m, s, T, T/m");
  WriteSamples(&w, header.size(), pass.samples);
  w.Close();
}

void WriteTruthCsv(const std::string& path, const PassScenario& sc, const SimulatedPass& pass) {
  CsvWriter w(path, {"t", "x", "y", "z", "vx", "vy", "heading", "turn_rate", "mw_x", "mw_y", "mw_z"},
              {{"moment_body_Am2", Vec3Param(sc.moment_body)}, {"B0_T", Vec3Param(sc.B0)}});
  for (const auto& t : pass.truth) w.WriteRow(TruthRow(t, ""));
  w.Close();
}

}  // namespace magnav

namespace magnav {

void WriteFieldPassCsv(const std::string& path, const FieldScenario& sc, const SimulatedField& field) {
  std::vector<std::string> header = {"t", "sensor_id"};
  for (std::string& c : GradiometerDataColumns()) header.push_back(std::move(c));
  std::vector<std::pair<std::string, std::string>> params = {{"B0_T", Vec3Param(sc.B0)},
                                                             {"sigma_B_T", FormatNumber(sc.sigma_B)},
                                                             {"sigma_T_Tpm", FormatNumber(sc.sigma_T)},
                                                             {"seed", std::to_string(sc.seed)}};
  for (const auto& v : sc.vessels) {
    params.push_back({"vessel", std::to_string(v.vessel_id) + ": t " + FormatNumber(v.t_start_s) + "-" +
                                    FormatNumber(v.t_end_s()) + " s, moment_body_Am2 " + Vec3Param(v.moment_body)});
  }
  for (std::size_t j = 0; j < sc.background_drift_Tps.size(); ++j) {
    params.push_back({"background_drift_Tps", std::to_string(j) + ": " + Vec3Param(sc.background_drift_Tps[j])});
  }
  CsvWriter w(path, header, params);
  w.AddComment("simulated by magnav: several vessel dipoles cross fixed gradiometers; NED m, s, T, T/m");
  WriteSamples(&w, header.size(), field.samples);
  w.Close();
}

void WriteFieldTruthCsv(const std::string& path, const FieldScenario& sc, const SimulatedField& field) {
  std::vector<std::pair<std::string, std::string>> params = {{"B0_T", Vec3Param(sc.B0)}};
  for (const auto& v : sc.vessels) {
    params.push_back({"vessel", std::to_string(v.vessel_id) + ": t " + FormatNumber(v.t_start_s) + "-" +
                                    FormatNumber(v.t_end_s()) + " s, moment_body_Am2 " + Vec3Param(v.moment_body)});
  }
  CsvWriter w(path, {"t", "vessel_id", "x", "y", "z", "vx", "vy", "heading", "turn_rate", "mw_x", "mw_y", "mw_z"},
              params);
  // Rows by t, then vessel_id.
  std::vector<std::pair<std::uint32_t, const VesselTruth*>> rows;
  for (std::size_t v = 0; v < field.truth.size(); ++v) {
    for (const auto& t : field.truth[v]) rows.push_back({sc.vessels[v].vessel_id, &t});
  }
  std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) {
    return a.second->t_s != b.second->t_s ? a.second->t_s < b.second->t_s : a.first < b.first;
  });
  for (const auto& [id, t] : rows) w.WriteRow(TruthRow(*t, std::to_string(id)));
  w.Close();
}

}  // namespace magnav
