#include "magnav/tracker/initialize.h"


#include <algorithm>
#include <cmath>
#include <map>

#include "magnav/core/csv.h"
#include "magnav/core/dipole.h"
#include "magnav/core/frames.h"
#include "magnav/core/tensor.h"
#include "magnav/inversion/analytic.h"
#include "magnav/inversion/fix_line.h"
#include "magnav/inversion/inverter.h"

namespace magnav::tracker {

DipoleFix MakeFix(double t_s, std::uint32_t sensor_id, const Eigen::Vector3d& p_DinW, bool valid) {
  DipoleFix f;
  f.t_s = t_s;
  f.sensor_id = sensor_id;
  f.p_DinW = p_DinW;
  f.valid = valid;
  return f;
}


namespace {

double Median(std::vector<double> v) {
  const std::size_t n = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n), v.end());
  return v[n];
}

// The inverter's least-squares line, flown at the fixes' mean depth (the
// tracker's vessel keeps its depth).
struct LineFit {
  inversion::FixLine line;
  double t_ref = 0.0;
  Eigen::Vector3d p_ref = Eigen::Vector3d::Zero();  // z: mean depth
  Eigen::Vector2d v = Eigen::Vector2d::Zero();      // horizontal velocity
  Eigen::Vector3d At(double t) const {
    return {p_ref.x() + v.x() * (t - t_ref), p_ref.y() + v.y() * (t - t_ref), p_ref.z()};
  }
};

LineFit FitLine(const std::vector<DipoleFix>& fixes, const std::vector<bool>& use) {
  LineFit f;
  f.line = inversion::FitFixLine(fixes, use);
  f.t_ref = f.line.t_ref_s;
  f.p_ref = f.line.p_ref;
  f.v = f.line.v.head<2>();
  return f;
}

// A fix and the sample it was computed from.
struct Candidate {
  DipoleFix fix;
  const GradiometerSample* sample = nullptr;
};

std::vector<DipoleFix> FixesOf(const std::vector<Candidate>& c) {
  std::vector<DipoleFix> out;
  out.reserve(c.size());
  for (const auto& x : c) out.push_back(x.fix);
  return out;
}

}  // namespace

double SigmaB(const GradiometerSample& s, const TrackerOptions& o) {
  return s.sigma_B > 0.0 ? s.sigma_B : o.default_sigma_B_T;
}
double SigmaT(const GradiometerSample& s, const TrackerOptions& o) {
  return s.sigma_T > 0.0 ? s.sigma_T : o.default_sigma_T_Tpm;
}

std::optional<Eigen::Vector3d> SingleSampleOffset(const Eigen::Vector3d& dB_W, const Eigen::Matrix3d& T) {
  // The inverter's TED+EGT (scaled 4×3 pseudo-inverse), with its default
  // eigenvector-row weight.
  inversion::AnalyticSolution sol;
  if (!inversion::SolveTedEgt(T, dB_W, inversion::InverterOptions{}.egt_row_weight, inversion::NoiseSigmas{}, &sol) ||
      !sol.r_DtoS.allFinite() || sol.r_DtoS.squaredNorm() == 0.0) {
    return std::nullopt;
  }
  return sol.r_DtoS;
}

namespace {

double Snr(const GradiometerSample& s, const TrackerOptions& options) { return s.T.norm() / SigmaT(s, options); }

std::vector<Candidate> StrongCandidates(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                        const TrackerOptions& options) {
  std::vector<Candidate> out;
  for (const Epoch& e : epochs) {
    for (const GradiometerSample& s : e.samples) {
      const double snr = Snr(s, options);
      if (!(snr >= options.init.min_tensor_snr)) continue;
      const auto r = SingleSampleOffset(s.B - B0_W, s.T);
      if (!r) continue;
      DipoleFix fix = MakeFix(e.t_s, s.sensor_id, s.p_SinW - *r);
      fix.snr = snr;
      out.push_back({fix, &s});
    }
  }
  return out;
}

std::vector<Candidate> MatchCandidates(const std::vector<Epoch>& epochs, const std::vector<DipoleFix>& fixes,
                                       const TrackerOptions& options) {
  const double tol = options.epoch_tolerance_s;
  std::vector<Candidate> out;
  for (const DipoleFix& f : fixes) {
    if (!f.valid || !std::isfinite(f.t_s) || !f.p_DinW.allFinite()) continue;
    const auto e = std::lower_bound(epochs.begin(), epochs.end(), f.t_s - tol,
                                    [](const Epoch& a, double t) { return a.t_s < t; });
    if (e == epochs.end() || std::abs(e->t_s - f.t_s) > tol) continue;
    const auto s = std::find_if(e->samples.begin(), e->samples.end(),
                                [&](const GradiometerSample& x) { return x.sensor_id == f.sensor_id; });
    if (s == e->samples.end()) continue;
    const double snr = Snr(*s, options);
    if (!(snr >= options.init.min_tensor_snr)) continue;
    DipoleFix fix = MakeFix(e->t_s, f.sensor_id, f.p_DinW);
    fix.snr = snr;
    out.push_back({fix, &*s});
  }
  std::stable_sort(out.begin(), out.end(), [](const Candidate& a, const Candidate& b) {
    return a.fix.t_s != b.fix.t_s ? a.fix.t_s < b.fix.t_s : a.fix.sensor_id < b.fix.sensor_id;
  });
  // One fix per sample: a repeated fix (the same sample published twice) counts once.
  out.erase(std::unique(out.begin(), out.end(),
                        [](const Candidate& a, const Candidate& b) { return a.sample == b.sample; }),
            out.end());
  return out;
}

}  // namespace

std::vector<DipoleFix> StrongFixes(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                   const TrackerOptions& options) {
  return FixesOf(StrongCandidates(epochs, B0_W, options));
}

std::vector<DipoleFix> MatchFixes(const std::vector<Epoch>& epochs, const std::vector<DipoleFix>& fixes,
                                  const TrackerOptions& options) {
  return FixesOf(MatchCandidates(epochs, fixes, options));
}

std::string NoTrackMessage(const TrackerOptions& options, bool have_external_fixes) {
  const InitSource src = options.init.source;
  if (src == InitSource::kExternal && !have_external_fixes) {
    return "no track: the initialiser takes only fixes from outside (init source dipole_fix) and none were given";
  }
  const std::string need = " (at least " + std::to_string(options.init.min_fixes) +
                           " on a line near the strongest signal, spanning " +
                           FormatNumber(options.init.min_span_s) + " s)";
  if (src == InitSource::kExternal) return "no track: too few of the given fixes match a strong sample" + need;
  if (src == InitSource::kAuto && have_external_fixes) {
    return "no track: neither the given fixes nor the tracker's own single-sample fixes suffice" + need;
  }
  return "no track: too few strong single-sample fixes to initialise" + need;
}

namespace {

// Robust line fit: refit without fixes far from the line (bad samples, or
// ill-conditioned single-sample inversions) until the inlier set `use`
// settles. False if fewer than min_fixes remain.
bool RobustLine(const std::vector<DipoleFix>& fixes, const InitOptions& io, std::vector<bool>* use) {
  LineFit line = FitLine(fixes, *use);
  for (int iter = 0; iter < 10; ++iter) {
    std::vector<double> d(fixes.size()), d_in;
    for (std::size_t i = 0; i < fixes.size(); ++i) {
      d[i] = (fixes[i].p_DinW - line.At(fixes[i].t_s)).norm();
      if ((*use)[i]) d_in.push_back(d[i]);
    }
    const double sigma = 1.4826 * Median(d_in);
    const double limit = std::max(io.outlier_threshold_mad * sigma, 1e-9);
    std::vector<bool> next(fixes.size());
    int n = 0;
    for (std::size_t i = 0; i < fixes.size(); ++i) {
      next[i] = d[i] <= limit;
      n += next[i] ? 1 : 0;
    }
    if (n < io.min_fixes) return false;
    if (next == *use) break;
    *use = next;
    line = FitLine(fixes, *use);
  }
  return true;
}

// The initial track from one set of fixes (see the header).
std::optional<InitialTrack> InitializeFrom(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                           const TrackerOptions& options, const std::vector<Candidate>& all,
                                           bool external) {
  const InitOptions& io = options.init;
  if (static_cast<int>(all.size()) < io.min_fixes) return std::nullopt;
  // Strongest signal: largest running median over ±1 s of the SNR of all
  // samples of one sensor (weak ones included, so an isolated bad sample
  // cannot win).
  // Per sensor, in time order: (t, SNR).
  std::map<std::uint32_t, std::vector<std::pair<double, double>>> snr_by_sensor;
  for (const Epoch& e : epochs) {
    for (const GradiometerSample& s : e.samples) {
      snr_by_sensor[s.sensor_id].emplace_back(e.t_s, Snr(s, options));
    }
  }
  double t_peak = all.front().fix.t_s, best = -1.0;
  std::uint32_t peak_sensor = all.front().fix.sensor_id;
  for (const auto& [id, snr_t] : snr_by_sensor) {
    for (std::size_t i = 0, lo = 0, hi = 0; i < snr_t.size(); ++i) {
      while (snr_t[lo].first < snr_t[i].first - 1.0) ++lo;
      while (hi < snr_t.size() && snr_t[hi].first <= snr_t[i].first + 1.0) ++hi;
      std::vector<double> snr;
      for (std::size_t j = lo; j < hi; ++j) snr.push_back(snr_t[j].second);
      const double med = Median(snr);
      if (med > best) {
        best = med;
        t_peak = snr_t[i].first;
        peak_sensor = id;
      }
    }
  }
  std::vector<Candidate> candidates;
  for (const Candidate& c : all) {
    if (std::abs(c.fix.t_s - t_peak) <= 0.5 * io.span_s) candidates.push_back(c);
  }
  if (static_cast<int>(candidates.size()) < io.min_fixes) return std::nullopt;
  // Several vessels: seed the line with the peak sensor's fixes and keep
  // only the fixes near it.
  if (io.cluster_gate_m > 0.0) {
    std::vector<DipoleFix> seed;
    for (const Candidate& c : candidates) {
      if (c.fix.sensor_id == peak_sensor) seed.push_back(c.fix);
    }
    std::vector<bool> seed_use(seed.size(), true);
    if (static_cast<int>(seed.size()) >= io.min_fixes && RobustLine(seed, io, &seed_use)) {
      const LineFit seed_line = FitLine(seed, seed_use);
      std::vector<Candidate> near;
      for (const Candidate& c : candidates) {
        if ((c.fix.p_DinW - seed_line.At(c.fix.t_s)).norm() <= io.cluster_gate_m) near.push_back(c);
      }
      candidates = std::move(near);
    }
  }
  const std::vector<DipoleFix> fixes = FixesOf(candidates);
  if (static_cast<int>(fixes.size()) < io.min_fixes) return std::nullopt;

  std::vector<bool> use(fixes.size(), true);
  if (!RobustLine(fixes, io, &use)) return std::nullopt;
  const LineFit line = FitLine(fixes, use);

  InitialTrack init;
  init.from_external_fixes = external;
  double t_min = 1e300, t_max = -1e300;
  std::vector<const GradiometerSample*> inlier_samples;
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    if (!use[i]) continue;
    init.fixes.push_back(fixes[i]);
    inlier_samples.push_back(candidates[i].sample);
    t_min = std::min(t_min, fixes[i].t_s);
    t_max = std::max(t_max, fixes[i].t_s);
  }
  if (t_max - t_min < io.min_span_s) return std::nullopt;

  init.t_ref_s = line.t_ref;
  init.t_first_s = t_min;
  init.t_last_s = t_max;
  const double heading = std::atan2(line.v.y(), line.v.x());
  init.state = CtState<double>{line.p_ref.x(), line.p_ref.y(), line.p_ref.z(), line.v.norm(), heading, 0.0};

  // Body moment: median over the inlier fixes of Rz(h)ᵀ m_W, m_W fitted from
  // each fix's sample with the dipole on the line (less noisy than the fixes).
  const Eigen::Matrix3d R_WtoB = HeadingRotation(heading).transpose();
  std::vector<double> mx, my, mz;
  for (std::size_t k = 0; k < init.fixes.size(); ++k) {
    const GradiometerSample& s = *inlier_samples[k];
    Eigen::Vector3d m_W;
    if (!FitDipoleMoment(s.p_SinW - line.At(init.fixes[k].t_s), s.B - B0_W, s.T, SigmaB(s, options),
                         SigmaT(s, options), &m_W)) {
      continue;
    }
    const Eigen::Vector3d m_B = R_WtoB * m_W;
    mx.push_back(m_B.x());
    my.push_back(m_B.y());
    mz.push_back(m_B.z());
  }
  if (mx.empty()) return std::nullopt;
  init.m_B_Am2 = {Median(mx), Median(my), Median(mz)};
  return init;
}

}  // namespace

std::optional<InitialTrack> InitializeTrack(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                            const TrackerOptions& options,
                                            const std::vector<DipoleFix>* external_fixes) {
  const InitSource src = options.init.source;
  if (external_fixes != nullptr && src != InitSource::kSamples) {
    auto init = InitializeFrom(epochs, B0_W, options, MatchCandidates(epochs, *external_fixes, options), true);
    if (init || src == InitSource::kExternal) return init;
  }
  if (src == InitSource::kExternal) return std::nullopt;
  return InitializeFrom(epochs, B0_W, options, StrongCandidates(epochs, B0_W, options), false);
}

}  // namespace magnav::tracker
