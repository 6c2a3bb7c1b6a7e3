#include "magnav/tracker/pair_beside.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "magnav/core/dipole.h"
#include "magnav/core/frames.h"
#include "magnav/core/motion.h"

namespace magnav::tracker {

namespace {

// How far behind (or ahead) along the tracked line start 2 puts the newcomer (m).
constexpr double kBesideAlongM = 10.0;
// The init SNR of the beside fit (pair_beside.h).
constexpr double kBesideMinTensorSnr = 10.0;

InitialTrack Shifted(const InitialTrack& a, double along_m, double side_m, double speed_factor) {
  InitialTrack b = a;
  const double c = std::cos(a.state.heading), s = std::sin(a.state.heading);
  b.state.x += along_m * c - side_m * s;
  b.state.y += along_m * s + side_m * c;
  b.state.v *= speed_factor;
  b.state.turn_rate = 0.0;
  return b;
}

// The newcomer's tensor evidence (pair_beside.h): the largest predicted
// tensor SNR ‖T̂‖_F/σ_T of the fit's newcomer line `b` at a sample of
// `epochs` where it reduces the tensor χ² of what the fit's tracked line
// `a` leaves there (‖T − T̂_a‖² − ‖T − T̂_a − T̂‖² > 0, whitened), as a
// tentative track's tensor evidence for confirmation.
double TensorEvidence(const std::vector<Epoch>& epochs, const InitialTrack& a, const InitialTrack& b,
                      const TrackerOptions& options) {
  double best = 0.0;
  for (const Epoch& e : epochs) {
    const CtState<double> qa = PropagateCoordinatedTurn(a.state, e.t_s - a.t_ref_s);
    const CtState<double> qb = PropagateCoordinatedTurn(b.state, e.t_s - b.t_ref_s);
    const Eigen::Vector3d ma = HeadingRotation(qa.heading) * a.m_B_Am2, mb = HeadingRotation(qb.heading) * b.m_B_Am2;
    for (const GradiometerSample& s : e.samples) {
      Eigen::Vector3d B;
      Eigen::Matrix3d Ta, Tb;
      DipoleBT(s.p_SinW - Eigen::Vector3d(qb.x, qb.y, qb.z), mb, &B, &Tb);
      const double snr = Tb.norm() / SigmaT(s, options);
      if (!(snr > best)) continue;
      DipoleBT(s.p_SinW - Eigen::Vector3d(qa.x, qa.y, qa.z), ma, &B, &Ta);
      const Eigen::Matrix3d r = s.T - Ta;
      if (r.squaredNorm() - (r - Tb).squaredNorm() > 0.0) best = snr;
    }
  }
  return std::isfinite(best) ? best : 0.0;
}

}  // namespace

TrackerOptions BesideFitOptions(const TrackerOptions& options) {
  TrackerOptions weak = options;
  weak.init.min_tensor_snr = std::min(options.init.min_tensor_snr, kBesideMinTensorSnr);
  return weak;
}

std::vector<InitialTrack> InitializeBeside(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                           const TrackerOptions& options, const InitialTrack& tracked,
                                           double min_separation_m, double seen_snr, bool* waiting) {
  if (waiting != nullptr) *waiting = false;
  if (epochs.empty() || !(options.init.max_dipole_misfit > 0.0) || !tracked.m_B_Am2.allFinite()) return {};
  std::vector<InitialTrack> starts;
  // 1. The newcomer's own line, once the tracked vessel's field is out.
  std::vector<Epoch> rest = epochs;
  for (Epoch& e : rest) {
    const CtState<double> p = PropagateCoordinatedTurn(tracked.state, e.t_s - tracked.t_ref_s);
    const Eigen::Vector3d m_W = HeadingRotation(p.heading) * tracked.m_B_Am2;
    for (GradiometerSample& s : e.samples) {
      Eigen::Vector3d B;
      Eigen::Matrix3d T;
      DipoleBT(s.p_SinW - Eigen::Vector3d(p.x, p.y, p.z), m_W, &B, &T);
      s.B -= B;
      s.T -= T;
    }
  }
  if (const std::optional<InitialTrack> own = InitializeTrack(rest, B0_W, options)) {
    const CtState<double> at = PropagateCoordinatedTurn(tracked.state, own->t_ref_s - tracked.t_ref_s);
    if (std::hypot(own->state.x - at.x, own->state.y - at.y) >= min_separation_m) starts.push_back(*own);
  }
  // 2. Beside it, behind and faster or ahead and slower.
  for (double side : {-min_separation_m, min_separation_m}) {
    starts.push_back(Shifted(tracked, -kBesideAlongM, side, 2.0));
    starts.push_back(Shifted(tracked, kBesideAlongM, side, 0.5));
  }
  // The fit's samples and the newcomer's strength gate at kBesideMinTensorSnr.
  const TrackerOptions weak = BesideFitOptions(options);
  bool seen = false;
  for (const InitialTrack& b : starts) {
    PairFitReport report;
    std::vector<InitialTrack> pair = RefitPair(epochs, B0_W, weak, tracked, b, min_separation_m, &report);
    if (pair.size() == 2) return pair;
    // Refused only because the newcomer is still weak (pair_beside.h).
    // Its field seen at the fit's samples, and its tensor where it is: a
    // line that only a far dipole's B put there (a far ship, a track's model
    // error) reduces no tensor χ² (pair_beside.h).
    seen = seen || (report.fitted && report.misfit <= weak.init.max_dipole_misfit &&
                    report.separation_m >= min_separation_m &&
                    report.max_tensor_snr[0] >= weak.init.min_tensor_snr && seen_snr > 0.0 &&
                    report.max_signal_snr[1] >= seen_snr &&
                    TensorEvidence(epochs, report.line[0], report.line[1], options) >= seen_snr);
  }
  if (waiting != nullptr) *waiting = seen;
  return {};
}

}  // namespace magnav::tracker
