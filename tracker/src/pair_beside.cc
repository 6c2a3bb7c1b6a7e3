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

}  // namespace

std::vector<InitialTrack> InitializeBeside(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                           const TrackerOptions& options, const InitialTrack& tracked,
                                           double min_separation_m, double seen_tensor_snr, bool* waiting) {
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
  TrackerOptions weak = options;
  weak.init.min_tensor_snr = std::min(options.init.min_tensor_snr, kBesideMinTensorSnr);
  bool seen = false;
  for (const InitialTrack& b : starts) {
    PairFitReport report;
    std::vector<InitialTrack> pair = RefitPair(epochs, B0_W, weak, tracked, b, min_separation_m, &report);
    if (pair.size() == 2) return pair;
    // Refused only because the newcomer is still weak (pair_beside.h).
    seen = seen || (report.fitted && report.misfit <= weak.init.max_dipole_misfit &&
                    report.separation_m >= min_separation_m &&
                    report.max_tensor_snr[0] >= weak.init.min_tensor_snr &&
                    report.max_tensor_snr[1] >= seen_tensor_snr && seen_tensor_snr > 0.0);
  }
  if (waiting != nullptr) *waiting = seen;
  return {};
}

}  // namespace magnav::tracker
