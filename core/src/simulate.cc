#include "magnav/core/simulate.h"

#include <cmath>
#include <random>

#include "magnav/core/csv.h"
#include "magnav/core/dipole.h"
#include "magnav/core/error.h"
#include "magnav/core/frames.h"
#include "magnav/core/motion.h"
#include "magnav/core/units.h"

namespace magnav {

bool PassScenario::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!moment_body.allFinite()) return fail("moment_body must be finite");
  if (!start_position.allFinite() || !std::isfinite(start_heading_rad)) return fail("start state must be finite");
  if (!(speed_mps >= 0.0) || !std::isfinite(speed_mps)) return fail("speed_mps must be finite and >= 0");
  if (segments.empty()) return fail("at least one turn segment is needed");
  for (std::size_t i = 0; i < segments.size(); ++i) {
    if (!(segments[i].duration_s > 0.0) || !std::isfinite(segments[i].duration_s) ||
        !std::isfinite(segments[i].turn_rate_rps)) {
      return fail("segment " + std::to_string(i) + ": duration must be > 0 and values finite");
    }
  }
  if (!(rate_hz > 0.0) || rate_hz > 1e4) return fail("rate_hz must be in (0, 10000]");
  if (sensors.empty()) return fail("at least one sensor is needed");
  for (const auto& s : sensors) {
    if (!s.allFinite()) return fail("sensor positions must be finite");
  }
  if (!B0.allFinite()) return fail("B0 must be finite");
  if (!(sigma_B >= 0.0) || !(sigma_T >= 0.0) || !std::isfinite(sigma_B) || !std::isfinite(sigma_T)) {
    return fail("sigma_B and sigma_T must be finite and >= 0");
  }
  if (duration_s() * rate_hz > 1e7) return fail("more than 1e7 instants: shorten the scenario or lower the rate");
  return true;
}

double PassScenario::duration_s() const {
  double d = 0.0;
  for (const auto& s : segments) d += s.duration_s;
  return d;
}

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

SimulatedPass SimulatePass(const PassScenario& sc) {
  std::string err;
  if (!sc.IsValid(&err)) throw InputError("scenario: " + err);
  // State at the start of each segment (exact, no accumulation per sample).
  std::vector<CtState<double>> seg_start;
  std::vector<double> seg_t0;
  CtState<double> s{sc.start_position.x(), sc.start_position.y(), sc.start_position.z(),
                    sc.speed_mps,          sc.start_heading_rad,  sc.segments[0].turn_rate_rps};
  double t0 = 0.0;
  for (const auto& seg : sc.segments) {
    s.turn_rate = seg.turn_rate_rps;
    seg_start.push_back(s);
    seg_t0.push_back(t0);
    s = PropagateCoordinatedTurn(s, seg.duration_s);
    t0 += seg.duration_s;
  }
  const double total = t0;
  const auto n = static_cast<std::size_t>(std::floor(total * sc.rate_hz + 1e-9)) + 1;

  SimulatedPass out;
  out.truth.reserve(n);
  out.samples.reserve(n * sc.sensors.size());
  std::mt19937_64 rng(sc.seed);
  std::normal_distribution<double> nB(0.0, 1.0);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / sc.rate_hz;
    // A sample exactly at a boundary belongs to the later segment.
    std::size_t i = 0;
    while (i + 1 < seg_t0.size() && t >= seg_t0[i + 1] - 1e-12) ++i;
    const CtState<double> st = PropagateCoordinatedTurn(seg_start[i], t - seg_t0[i]);
    VesselTruth tr;
    tr.t_s = t;
    tr.p_VinW = {st.x, st.y, st.z};
    tr.heading_rad = WrapAngle(st.heading);
    tr.v_VinW = {st.v * std::cos(st.heading), st.v * std::sin(st.heading)};
    tr.turn_rate_rps = st.turn_rate;
    tr.m_W = WorldMoment(sc.moment_body, st.heading);
    for (std::size_t j = 0; j < sc.sensors.size(); ++j) {
      GradiometerSample g;
      g.sensor_id = static_cast<std::uint32_t>(j);
      g.t_s = t;
      g.p_SinW = sc.sensors[j];
      const Eigen::Vector3d r = g.p_SinW - tr.p_VinW;
      if (r.norm() < 0.5) {
        throw InputError("scenario: the vessel passes within 0.5 m of sensor " + std::to_string(j) +
                         " at t = " + FormatNumber(t) + " s");
      }
      DipoleBT(r, tr.m_W, &g.B, &g.T);
      g.B += sc.B0;
      if (sc.sigma_B > 0.0) g.B += sc.sigma_B * Eigen::Vector3d(nB(rng), nB(rng), nB(rng));
      if (sc.sigma_T > 0.0) g.T += TensorNoise(rng, sc.sigma_T);
      g.sigma_B = sc.sigma_B;
      g.sigma_T = sc.sigma_T;
      out.samples.push_back(g);
    }
    out.truth.push_back(tr);
  }
  return out;
}

namespace {
std::string Vec3Param(const Eigen::Vector3d& v) {
  return FormatNumber(v.x()) + ", " + FormatNumber(v.y()) + ", " + FormatNumber(v.z());
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
  std::vector<std::string> f(header.size());
  for (const auto& g : pass.samples) {
    f[0] = FormatNumber(g.t_s);
    f[1] = std::to_string(g.sensor_id);
    for (int i = 0; i < 3; ++i) f[2 + i] = FormatNumber(g.p_SinW[i]);
    for (int i = 0; i < 3; ++i) f[5 + i] = FormatNumber(g.B[i]);
    for (int k = 0; k < 9; ++k) f[8 + k] = FormatNumber(g.T(k / 3, k % 3));
    w.WriteRow(f);
  }
  w.Close();
}

void WriteTruthCsv(const std::string& path, const PassScenario& sc, const SimulatedPass& pass) {
  CsvWriter w(path, {"t", "x", "y", "z", "vx", "vy", "heading", "turn_rate", "mw_x", "mw_y", "mw_z"},
              {{"moment_body_Am2", Vec3Param(sc.moment_body)}, {"B0_T", Vec3Param(sc.B0)}});
  for (const auto& t : pass.truth) {
    w.WriteRow({FormatNumber(t.t_s), FormatNumber(t.p_VinW.x()), FormatNumber(t.p_VinW.y()),
                FormatNumber(t.p_VinW.z()), FormatNumber(t.v_VinW.x()), FormatNumber(t.v_VinW.y()),
                FormatNumber(t.heading_rad), FormatNumber(t.turn_rate_rps), FormatNumber(t.m_W.x()),
                FormatNumber(t.m_W.y()), FormatNumber(t.m_W.z())});
  }
  w.Close();
}

}  // namespace magnav
