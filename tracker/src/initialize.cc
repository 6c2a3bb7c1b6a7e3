#include "magnav/tracker/initialize.h"


#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "magnav/core/csv.h"
#include "magnav/core/dipole.h"
#include "magnav/core/frames.h"
#include "magnav/core/motion.h"
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

// σ_B for the initiator's searches (the single-sample fixes, the pair
// start's and its refit's two-dipole fit): the sample's σ_B with
// InitOptions::fix_sigma_B_allowance_T taken out in quadrature (the
// allowance is for the track's fits, not for the misfit gates that decide
// whether a weak vessel is started).
double FixSigmaB(const GradiometerSample& s, const TrackerOptions& options) {
  const double sb = SigmaB(s, options), a = options.init.fix_sigma_B_allowance_T;
  if (!(a > 0.0) || !(sb > a)) return sb;
  return std::sqrt(sb * sb - a * a);
}

// √(Σr²/Σm²) of one dipole at offset r with its least-squares moment
// (InitOptions::max_dipole_misfit); +inf if no moment fits.
double DipoleMisfit(const GradiometerSample& s, const Eigen::Vector3d& dB_W, const Eigen::Vector3d& r_DtoS,
                    const TrackerOptions& options) {
  const double sb = FixSigmaB(s, options), st = SigmaT(s, options);
  Eigen::Vector3d m_W;
  if (!FitDipoleMoment(r_DtoS, dB_W, s.T, sb, st, &m_W)) return std::numeric_limits<double>::infinity();
  Eigen::Vector3d B;
  Eigen::Matrix3d T;
  DipoleBT(r_DtoS, m_W, &B, &T);
  const double r2 = (dB_W - B).squaredNorm() / (sb * sb) + (s.T - T).squaredNorm() / (st * st);
  const double m2 = dB_W.squaredNorm() / (sb * sb) + s.T.squaredNorm() / (st * st);
  const double misfit = std::sqrt(r2 / m2);
  return std::isfinite(misfit) ? misfit : std::numeric_limits<double>::infinity();
}

// A strong sample that one dipole does not explain (see
// InitOptions::max_dipole_misfit).
bool NotOneDipole(const GradiometerSample& s, const Eigen::Vector3d& dB_W, const Eigen::Vector3d& r_DtoS,
                  const TrackerOptions& options) {
  const double max = options.init.max_dipole_misfit;
  return max > 0.0 && !(DipoleMisfit(s, dB_W, r_DtoS, options) <= max);
}

}  // namespace

std::optional<DipoleFix> SampleFix(const GradiometerSample& s, double t_s, const Eigen::Vector3d& B0_W,
                                   const TrackerOptions& options) {
  const double snr = Snr(s, options);
  if (!(snr >= options.init.min_tensor_snr)) return std::nullopt;
  const Eigen::Vector3d dB = s.B - B0_W;
  // The offset as SingleSampleOffset, with the sample's σ for its covariance
  // (the offset does not depend on them).
  inversion::AnalyticSolution sol;
  const inversion::NoiseSigmas noise{FixSigmaB(s, options), SigmaT(s, options)};
  if (!inversion::SolveTedEgt(s.T, dB, inversion::InverterOptions{}.egt_row_weight, noise, &sol) ||
      !sol.r_DtoS.allFinite() || sol.r_DtoS.squaredNorm() == 0.0) {
    return std::nullopt;
  }
  if (NotOneDipole(s, dB, sol.r_DtoS, options)) return std::nullopt;
  DipoleFix fix = MakeFix(t_s, s.sensor_id, s.p_SinW - sol.r_DtoS);
  fix.snr = snr;
  fix.r_DtoS = sol.r_DtoS;
  fix.cov_p_DinW = sol.cov_r;
  fix.position_sigma_3d_m = sol.position_sigma_3d_m;
  return fix;
}

namespace {

std::vector<Candidate> StrongCandidates(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                        const TrackerOptions& options) {
  std::vector<Candidate> out;
  for (const Epoch& e : epochs) {
    for (const GradiometerSample& s : e.samples) {
      if (auto fix = SampleFix(s, e.t_s, B0_W, options)) out.push_back({*fix, &s});
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
  // A strong sample left out as not one dipole counts as 0.
  std::set<const GradiometerSample*> fixed;
  for (const Candidate& c : all) fixed.insert(c.sample);
  const double min_snr = io.min_tensor_snr;
  std::map<std::uint32_t, std::vector<std::pair<double, double>>> snr_by_sensor;
  for (const Epoch& e : epochs) {
    for (const GradiometerSample& s : e.samples) {
      double snr = Snr(s, options);
      if (!external && io.max_dipole_misfit > 0.0 && snr >= min_snr && fixed.count(&s) == 0) snr = 0.0;
      snr_by_sensor[s.sensor_id].emplace_back(e.t_s, snr);
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


namespace {

// A pair's samples: those of sensors within this many cluster gates
// (horizontally) of its line(s) (see InitializePair).
constexpr double kPairReachGates = 3.0;

// Two straight-line dipoles: per line x0, y0, z, vx, vy at t_ref.
using PairParams = Eigen::Matrix<double, 10, 1>;

struct PairSample {
  double dt = 0.0;  // t − t_ref
  Eigen::Vector3d p_S = Eigen::Vector3d::Zero();
  Eigen::Vector3d dB = Eigen::Vector3d::Zero();
  Eigen::Matrix3d T = Eigen::Matrix3d::Zero();
  double sb = 1.0, st = 1.0;
};

// The samples' whitened energy, Σ ‖ΔB‖²/σ_B² + ‖T‖²/σ_T²: what a fit's misfit is relative to.
double PairSignal(const std::vector<PairSample>& samples) {
  double signal = 0.0;
  for (const PairSample& s : samples) {
    signal += s.dB.squaredNorm() / (s.sb * s.sb) + s.T.squaredNorm() / (s.st * s.st);
  }
  return signal;
}

Eigen::Vector3d PairPosition(const PairParams& x, int k, double dt) {
  const int o = 5 * k;
  return {x(o) + x(o + 3) * dt, x(o + 1) + x(o + 4) * dt, x(o + 2)};
}

// The 12 whitened rows (B, T's 9 elements) of a sample per unit moment
// component of each dipole (12 × 6), and the whitened measurement.
void PairRows(const PairParams& x, const PairSample& s, Eigen::Matrix<double, 12, 6>* A,
              Eigen::Matrix<double, 12, 1>* z) {
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d r = s.p_S - PairPosition(x, k, s.dt);
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d B;
      Eigen::Matrix3d T;
      DipoleBT(r, Eigen::Vector3d::Unit(c), &B, &T);
      A->block<3, 1>(0, 3 * k + c) = B / s.sb;
      A->block<9, 1>(3, 3 * k + c) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(T.data()) / s.st;
    }
  }
  z->head<3>() = s.dB / s.sb;
  z->tail<9>() = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(s.T.data()) / s.st;
}

// Residual of the pair with its least-squares moments (variable projection).
Eigen::VectorXd PairResidual(const PairParams& x, const std::vector<PairSample>& samples, Eigen::Matrix<double, 6, 1>* m) {
  Eigen::Matrix<double, 6, 6> N = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
  std::vector<Eigen::Matrix<double, 12, 6>> As(samples.size());
  std::vector<Eigen::Matrix<double, 12, 1>> zs(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    PairRows(x, samples[i], &As[i], &zs[i]);
    N += As[i].transpose() * As[i];
    b += As[i].transpose() * zs[i];
  }
  *m = N.ldlt().solve(b);
  Eigen::VectorXd r(12 * samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) r.segment<12>(12 * static_cast<Eigen::Index>(i)) = zs[i] - As[i] * *m;
  return r;
}

// Levenberg–Marquardt on the 10 line parameters (forward differences).
double FitPair(const std::vector<PairSample>& samples, PairParams* x, Eigen::Matrix<double, 6, 1>* m) {
  Eigen::VectorXd r = PairResidual(*x, samples, m);
  double cost = r.squaredNorm(), lambda = 1e-3;
  for (int iter = 0; iter < 30; ++iter) {
    Eigen::MatrixXd J(r.size(), 10);
    Eigen::Matrix<double, 6, 1> mm;
    for (int j = 0; j < 10; ++j) {
      PairParams xp = *x;
      const double h = (j % 5 >= 3) ? 1e-4 : 1e-3;
      xp(j) += h;
      J.col(j) = (PairResidual(xp, samples, &mm) - r) / h;
    }
    const Eigen::Matrix<double, 10, 10> JtJ = J.transpose() * J;
    const Eigen::Matrix<double, 10, 1> g = J.transpose() * r;
    bool improved = false;
    for (int tries = 0; tries < 8 && !improved; ++tries) {
      Eigen::Matrix<double, 10, 10> H = JtJ;
      H.diagonal() += lambda * JtJ.diagonal().cwiseMax(1e-12);
      const PairParams xn = *x - H.ldlt().solve(g);
      Eigen::Matrix<double, 6, 1> mn;
      const Eigen::VectorXd rn = PairResidual(xn, samples, &mn);
      const double cn = rn.squaredNorm();
      if (std::isfinite(cn) && cn < cost) {
        improved = true;
        const bool small = cost - cn < 1e-6 * cost;
        *x = xn;
        *m = mn;
        r = rn;
        cost = cn;
        lambda = std::max(lambda / 10.0, 1e-9);
        if (small) return cost;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  return cost;
}

// The whitened residual of the pair at line parameters x and world moments
// m (the moments held, not projected out).
Eigen::VectorXd PairResidualAt(const PairParams& x, const Eigen::Matrix<double, 6, 1>& m,
                               const std::vector<PairSample>& samples) {
  Eigen::VectorXd r(12 * samples.size());
  Eigen::Matrix<double, 12, 6> A;
  Eigen::Matrix<double, 12, 1> z;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    PairRows(x, samples[i], &A, &z);
    r.segment<12>(12 * static_cast<Eigen::Index>(i)) = z - A * m;
  }
  return r;
}

// Each line's state covariance from the joint fit (InitialTrack::cov_state
// and cov_state_given_partner): Gauss–Newton information JᵀJ over all 16
// parameters [line a (x0 y0 z vx vy), line b, m_a (world), m_b] at the
// solution, line Jacobian by forward differences, moment columns exact.
// Marginal: the line's block of (JᵀJ)⁻¹; given the partner: the line's block
// of the inverse of its own 8 × 8 (line and moment) block. Mapped to
// [x y z v h ω] at t_ref. False if the information is singular or a line
// is at rest (heading undefined).
bool PairCovariances(const std::vector<PairSample>& samples, const PairParams& x,
                     const Eigen::Matrix<double, 6, 1>& m, std::vector<InitialTrack>* out) {
  const Eigen::VectorXd r = PairResidualAt(x, m, samples);
  Eigen::MatrixXd J(r.size(), 16);
  for (int j = 0; j < 10; ++j) {
    PairParams xp = x;
    const double h = (j % 5 >= 3) ? 1e-4 : 1e-3;
    xp(j) += h;
    J.col(j) = (PairResidualAt(xp, m, samples) - r) / h;
  }
  for (std::size_t i = 0; i < samples.size(); ++i) {
    Eigen::Matrix<double, 12, 6> A;
    Eigen::Matrix<double, 12, 1> z;
    PairRows(x, samples[i], &A, &z);
    J.block<12, 6>(12 * static_cast<Eigen::Index>(i), 10) = -A;
  }
  const Eigen::Matrix<double, 16, 16> H = J.transpose() * J;
  const Eigen::FullPivLU<Eigen::Matrix<double, 16, 16>> lu(H);
  if (!lu.isInvertible()) return false;
  const Eigen::Matrix<double, 16, 16> P = lu.inverse();
  for (int k = 0; k < 2; ++k) {
    const int o = 5 * k, mo = 10 + 3 * k;
    const Eigen::Vector2d v = x.segment<2>(o + 3);
    const double speed = v.norm();
    if (!(speed > 1e-3)) return false;
    std::array<int, 8> own{o, o + 1, o + 2, o + 3, o + 4, mo, mo + 1, mo + 2};
    Eigen::Matrix<double, 8, 8> Hk;
    for (int a = 0; a < 8; ++a) {
      for (int b = 0; b < 8; ++b) Hk(a, b) = H(own[a], own[b]);
    }
    const Eigen::FullPivLU<Eigen::Matrix<double, 8, 8>> luk(Hk);
    if (!luk.isInvertible()) return false;
    const Eigen::Matrix<double, 5, 5> given = luk.inverse().topLeftCorner<5, 5>();
    const Eigen::Matrix<double, 5, 5> marginal = P.block<5, 5>(o, o);
    // [x y z v h ω] from [x0 y0 z vx vy].
    Eigen::Matrix<double, 6, 5> G = Eigen::Matrix<double, 6, 5>::Zero();
    G.topLeftCorner<3, 3>().setIdentity();
    G(3, 3) = v.x() / speed;
    G(3, 4) = v.y() / speed;
    G(4, 3) = -v.y() / (speed * speed);
    G(4, 4) = v.x() / (speed * speed);
    InitialTrack& init = (*out)[static_cast<std::size_t>(k)];
    init.cov_state = G * marginal * G.transpose();
    init.cov_state_given_partner = G * given * G.transpose();
    init.has_pair_covariance = init.cov_state.allFinite() && init.cov_state_given_partner.allFinite();
  }
  return true;
}

// The pair fit's two tracks if it passes InitializePair's gates (misfit,
// separation, each dipole strong on its own); empty otherwise.
std::vector<InitialTrack> PairTracks(const std::vector<PairSample>& samples, double signal, double cost,
                                     const PairParams& best_x, const Eigen::Matrix<double, 6, 1>& best_m,
                                     double t_ref, double t_min, double t_max, const TrackerOptions& options,
                                     double min_separation_m, PairFitReport* report = nullptr) {
  const InitOptions& io = options.init;
  const Eigen::Vector2d a = best_x.segment<2>(0), b = best_x.segment<2>(5);
  // Each dipole's own strongest tensor (the strength gate below).
  // And its whole field's (B and tensor, as a track's gate SNR): the report.
  double max_snr[2] = {0.0, 0.0}, max_signal_snr[2] = {0.0, 0.0};
  for (int k = 0; k < 2; ++k) {
    for (const PairSample& s : samples) {
      Eigen::Vector3d B;
      Eigen::Matrix3d T;
      DipoleBT(s.p_S - PairPosition(best_x, k, s.dt), best_m.segment<3>(3 * k), &B, &T);
      max_snr[k] = std::max(max_snr[k], T.norm() / s.st);
      const double snr = std::sqrt(B.squaredNorm() / (s.sb * s.sb) + T.squaredNorm() / (s.st * s.st));
      if (std::isfinite(snr)) max_signal_snr[k] = std::max(max_signal_snr[k], snr);
    }
  }
  if (report != nullptr) {
    report->fitted = true;
    report->misfit = std::sqrt(cost / signal);
    report->separation_m = (a - b).norm();
    report->max_tensor_snr[0] = max_snr[0];
    report->max_tensor_snr[1] = max_snr[1];
    report->max_signal_snr[0] = max_signal_snr[0];
    report->max_signal_snr[1] = max_signal_snr[1];
    for (int k = 0; k < 2; ++k) {
      const auto q = best_x.segment<5>(5 * k);
      const double heading = std::atan2(q(4), q(3));
      InitialTrack& line = report->line[k];
      line.t_ref_s = t_ref;
      line.t_first_s = t_min;
      line.t_last_s = t_max;
      line.state = CtState<double>{q(0), q(1), q(2), std::hypot(q(3), q(4)), heading, 0.0};
      line.m_B_Am2 = HeadingRotation(heading).transpose() * best_m.segment<3>(3 * k);
    }
  }
  if (!(std::sqrt(cost / signal) <= io.max_dipole_misfit)) return {};
  if ((a - b).norm() < min_separation_m) return {};
  // Each dipole strong on its own somewhere (not a small correction).
  for (int k = 0; k < 2; ++k) {
    if (!(max_snr[k] >= io.min_tensor_snr)) return {};
  }
  std::vector<InitialTrack> out(2);
  for (int k = 0; k < 2; ++k) {
    InitialTrack& init = out[k];
    const auto q = best_x.segment<5>(5 * k);
    init.t_ref_s = t_ref;
    init.t_first_s = t_min;
    init.t_last_s = t_max;
    const double heading = std::atan2(q(4), q(3));
    init.state = CtState<double>{q(0), q(1), q(2), std::hypot(q(3), q(4)), heading, 0.0};
    init.m_B_Am2 = HeadingRotation(heading).transpose() * best_m.segment<3>(3 * k);
  }
  if (!PairCovariances(samples, best_x, best_m, &out)) {
    for (InitialTrack& init : out) init.has_pair_covariance = false;
  }
  return out;
}

}  // namespace

std::vector<InitialTrack> InitializePair(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                         const TrackerOptions& options, double min_separation_m) {
  const InitOptions& io = options.init;
  if (!(io.max_dipole_misfit > 0.0)) return {};
  // The strong samples one dipole does not explain, with their (ghost) fixes.
  struct Mixed {
    double t_s;
    double snr;
    DipoleFix fix;
    Eigen::Vector3d p_S;  // the sensor's position (world NED, m)
  };
  std::vector<Mixed> mixed;
  for (const Epoch& e : epochs) {
    for (const GradiometerSample& s : e.samples) {
      const double snr = Snr(s, options);
      if (!(snr >= io.min_tensor_snr)) continue;
      const auto r = SingleSampleOffset(s.B - B0_W, s.T);
      if (!r || !NotOneDipole(s, s.B - B0_W, *r, options)) continue;
      mixed.push_back({e.t_s, snr, MakeFix(e.t_s, s.sensor_id, s.p_SinW - *r), s.p_SinW});
    }
  }
  if (static_cast<int>(mixed.size()) < io.min_fixes) return {};
  const auto peak = std::max_element(mixed.begin(), mixed.end(), [](const Mixed& a, const Mixed& b) { return a.snr < b.snr; });
  const double t_peak = peak->t_s;
  // Several pairs in the field at once: with cluster_gate_m on, only the
  // fixes from sensors within kPairReachGates cluster gates (horizontally)
  // of the peak's sensor, and below only the samples of sensors that near the
  // ghost line (the pair's vessels are within a few metres of it, a sensor
  // that sees either strongly within ~20 m of them), so that another pair
  // elsewhere in the field does not enter the fit.
  const double reach_m = kPairReachGates * io.cluster_gate_m;
  std::vector<DipoleFix> ghost_fixes;
  for (const Mixed& x : mixed) {
    if (std::abs(x.t_s - t_peak) > 0.5 * io.span_s) continue;
    if (io.cluster_gate_m > 0.0 && (x.p_S - peak->p_S).head<2>().norm() > reach_m) continue;
    ghost_fixes.push_back(x.fix);
  }
  if (static_cast<int>(ghost_fixes.size()) < io.min_fixes) return {};
  std::vector<bool> use(ghost_fixes.size(), true);
  if (!RobustLine(ghost_fixes, io, &use)) return {};
  const LineFit ghost = FitLine(ghost_fixes, use);
  // The samples: every strong one within the span (and the reach above).
  std::vector<PairSample> samples;
  double t_min = 1e300, t_max = -1e300;
  for (const Epoch& e : epochs) {
    if (std::abs(e.t_s - t_peak) > 0.5 * io.span_s) continue;
    const Eigen::Vector3d on_ghost = ghost.At(e.t_s);
    for (const GradiometerSample& s : e.samples) {
      if (!(Snr(s, options) >= io.min_tensor_snr)) continue;
      if (io.cluster_gate_m > 0.0 &&
          (s.p_SinW - on_ghost).head<2>().norm() > reach_m) {
        continue;
      }
      samples.push_back({e.t_s - ghost.t_ref, s.p_SinW, s.B - B0_W, s.T, FixSigmaB(s, options), SigmaT(s, options)});
      t_min = std::min(t_min, e.t_s);
      t_max = std::max(t_max, e.t_s);
    }
  }
  if (static_cast<int>(samples.size()) < io.min_fixes || t_max - t_min < io.min_span_s) return {};
  const double signal = PairSignal(samples);
  // Starts: the ghost line split sideways by 4, 8, 12 and 16 m. On the
  // approach, where essentially one sensor sees the pair, the ghost line's
  // velocity and depth are themselves wrong (on held-out abreast it ran
  // backwards at up to 2 m/s, at or below the sensor plane) and no split of
  // it converges (the fit runs off); so also from that line with its
  // velocity reversed, and at rest, flown kPairStartHeightM or more above
  // the peak sensor, split by 8, 16 and 24 m.
  const Eigen::Vector2d v = ghost.v;
  const double speed = v.norm();
  const Eigen::Vector2d side = speed > 1e-6 ? Eigen::Vector2d(-v.y(), v.x()) / speed : Eigen::Vector2d(0.0, 1.0);
  struct Start {
    double split_m;
    Eigen::Vector2d v;
    double z;
  };
  constexpr double kPairStartHeightM = 3.0;
  const double z_sensor = peak->p_S.z();
  const double z_above = z_sensor - std::max(std::abs(ghost.p_ref.z() - z_sensor), kPairStartHeightM);
  std::vector<Start> starts;
  for (double d : {4.0, 8.0, 12.0, 16.0}) starts.push_back({d, v, ghost.p_ref.z()});
  for (const Eigen::Vector2d& w : {Eigen::Vector2d(-v), Eigen::Vector2d(Eigen::Vector2d::Zero())}) {
    for (double d : {8.0, 16.0, 24.0}) starts.push_back({d, w, z_above});
  }
  double best = std::numeric_limits<double>::infinity();
  PairParams best_x = PairParams::Zero();
  Eigen::Matrix<double, 6, 1> best_m = Eigen::Matrix<double, 6, 1>::Zero();
  for (const Start& st : starts) {
    PairParams x;
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector2d p = ghost.p_ref.head<2>() + (k == 0 ? -0.5 : 0.5) * st.split_m * side;
      x.segment<5>(5 * k) << p.x(), p.y(), st.z, st.v.x(), st.v.y();
    }
    Eigen::Matrix<double, 6, 1> m;
    const double cost = FitPair(samples, &x, &m);
    if (cost < best) {
      best = cost;
      best_x = x;
      best_m = m;
    }
  }
  std::vector<InitialTrack> out = PairTracks(samples, signal, best, best_x, best_m, ghost.t_ref, t_min, t_max,
                                             options, min_separation_m);
  if (out.size() == 2 && out[1].state.y < out[0].state.y) std::swap(out[0], out[1]);
  return out;
}

std::vector<InitialTrack> RefitPair(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                    const TrackerOptions& options, const InitialTrack& a, const InitialTrack& b,
                                    double min_separation_m, PairFitReport* report) {
  if (report != nullptr) *report = PairFitReport{};
  const InitOptions& io = options.init;
  if (!(io.max_dipole_misfit > 0.0) || epochs.empty()) return {};
  const double t_ref = 0.5 * (epochs.front().t_s + epochs.back().t_s);
  const CtState<double> sa = PropagateCoordinatedTurn(a.state, t_ref - a.t_ref_s);
  const CtState<double> sb = PropagateCoordinatedTurn(b.state, t_ref - b.t_ref_s);
  PairParams x;
  int k = 0;
  for (const CtState<double>& q : {sa, sb}) {
    x.segment<5>(5 * k++) << q.x, q.y, q.z, q.v * std::cos(q.heading), q.v * std::sin(q.heading);
  }
  // The strong samples within the pair's reach (as InitializePair's, from
  // the two lines instead of the ghost line).
  const double reach_m = kPairReachGates * io.cluster_gate_m;
  std::vector<PairSample> samples;
  double t_min = 1e300, t_max = -1e300;
  for (const Epoch& e : epochs) {
    const double dt = e.t_s - t_ref;
    for (const GradiometerSample& s : e.samples) {
      if (!(Snr(s, options) >= io.min_tensor_snr)) continue;
      if (io.cluster_gate_m > 0.0 && (s.p_SinW - PairPosition(x, 0, dt)).head<2>().norm() > reach_m &&
          (s.p_SinW - PairPosition(x, 1, dt)).head<2>().norm() > reach_m) {
        continue;
      }
      samples.push_back({dt, s.p_SinW, s.B - B0_W, s.T, FixSigmaB(s, options), SigmaT(s, options)});
      t_min = std::min(t_min, e.t_s);
      t_max = std::max(t_max, e.t_s);
    }
  }
  if (static_cast<int>(samples.size()) < io.min_fixes || t_max - t_min < io.min_span_s) return {};
  const double signal = PairSignal(samples);
  Eigen::Matrix<double, 6, 1> m;
  const double cost = FitPair(samples, &x, &m);
  return PairTracks(samples, signal, cost, x, m, t_ref, t_min, t_max, options, min_separation_m, report);
}
}  // namespace magnav::tracker
