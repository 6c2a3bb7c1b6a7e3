#include "magnav/tracker/reacquire.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

#include "magnav/core/motion.h"
#include "magnav/core/units.h"
#include "magnav/tracker/association.h"

namespace magnav::tracker {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

bool ReacquirableEnd(const std::string& reason) { return reason != "duplicate" && reason != "end of data"; }

double ContinuationChi2(const EpochEstimate& a, const EpochEstimate& b, double t_s, const MultiTrackerOptions& options) {
  CtState<double> sa, sb;
  StateCovariance Pa, Pb;
  if (!PropagateEstimate(a, t_s, options, &sa, &Pa) || !PropagateEstimate(b, t_s, options, &sb, &Pb)) return kInf;
  // [x y speed heading] of the state order [x y z v h ω].
  const int idx[4] = {0, 1, 3, 4};
  Eigen::Matrix4d S;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) S(r, c) = Pa(idx[r], idx[c]) + Pb(idx[r], idx[c]);
  }
  S = 0.5 * (S + S.transpose());
  const Eigen::Vector4d d(sb.x - sa.x, sb.y - sa.y, sb.v - sa.v, WrapAngle(sb.heading - sa.heading));
  const Eigen::LLT<Eigen::Matrix4d> llt(S);
  if (llt.info() != Eigen::Success) return kInf;
  const double chi2 = d.dot(llt.solve(d));
  return std::isfinite(chi2) && chi2 >= 0.0 ? chi2 : kInf;
}

std::optional<std::size_t> ChooseContinuation(const std::vector<EndedTrack>& ended, const EpochEstimate& newcomer,
                                              double t_first_row_s, const std::vector<EpochEstimate>& live,
                                              double t_s, const MultiTrackerOptions& options, double* chi2) {
  const TrackManagementOptions& mg = options.management;
  const double tol = options.track.epoch_tolerance_s;
  std::optional<std::size_t> best;
  double best_chi2 = kInf;
  for (std::size_t i = 0; i < ended.size(); ++i) {
    const EndedTrack& e = ended[i];
    if (!ReacquirableEnd(e.reason) || t_s - e.t_end_s > mg.reacquire_s + tol) continue;
    if (!(t_first_row_s > e.t_last_row_s + tol)) continue;
    const double c = ContinuationChi2(e.newest, newcomer, t_s, options);
    if (!(c <= mg.reacquire_gate_chi2) || !(c < best_chi2)) continue;
    bool other_closer = false;
    for (const EpochEstimate& l : live) {
      other_closer = other_closer || ContinuationChi2(e.newest, l, t_s, options) < c ||
                     ContinuationChi2(newcomer, l, t_s, options) < c;
    }
    if (other_closer) continue;
    best = i;
    best_chi2 = c;
  }
  if (chi2 != nullptr) *chi2 = best_chi2;
  return best;
}

}  // namespace magnav::tracker
