// The sample rule shared by the models of what is slow at a sensor (the
// cluster background's offsets, cluster_background.h; the far source and the
// sensors' drift, far_source.h): a sample enters such a model only where no
// vessel is near. It is "occupied" if the tracks' predicted tensor SNR there
// (‖Σ T̂‖_F / σ_T) is at least occupied_tensor_snr (0: never), "gated" if its
// residual tensor (sample minus the tracks' predicted tensor, whitened with
// σ_T and the tracks' model error, MultiTrackerOptions::kOtherFieldRelativeError
// of its norm over 3 per element; ‖·‖²/9) exceeds tensor_gate (a near source
// no track explains), else "used": its residual B (sample − B0 − the tracks'
// predicted B, world NED, T) with its variance per axis, σ_B² plus
// (field_share · ‖Σ B̂‖)²/3 (T²).
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "magnav/core/gradiometer.h"
#include "magnav/tracker/initialize.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::tracker::internal {

struct QuietRule {
  double occupied_tensor_snr = 3.0;
  double tensor_gate = 4.0;
  double field_share = MultiTrackerOptions::kOtherFieldRelativeError;
};

enum class QuietUse { kUsed, kOccupied, kGated };

// A vessel's predicted field B̂, T̂ at a sample (world NED; T, T/m) with the
// sample's σ_B (T) and σ_T (T/m per element): whether it makes the sample
// "occupied" — its tensor SNR ‖T̂‖_F / σ_T at least tensor_snr (0: never) or
// its B at least kOccupiedBSigmas σ_B. The one rule of the quiet store (the
// live tracks' field, and a confirmed track's approach taken out of it) and
// of the far source's samples from before a track's start.
constexpr double kOccupiedBSigmas = 3.0;
inline bool OccupiedBy(const Eigen::Vector3d& B, const Eigen::Matrix3d& T, double sigma_B, double sigma_T,
                       double tensor_snr) {
  return (tensor_snr > 0.0 && T.norm() >= tensor_snr * sigma_T) || B.norm() >= kOccupiedBSigmas * sigma_B;
}

struct QuietSample {
  QuietUse use = QuietUse::kUsed;
  Eigen::Vector3d r_W = Eigen::Vector3d::Zero();  // set only when used
  double var_T2 = 0.0;                            // set only when used
};

// `B_tracks`, `T_tracks`: the sum of every live track's predicted field at
// the sample (T, T/m).
inline QuietSample QuietResidual(const GradiometerSample& s, const Eigen::Vector3d& B_tracks,
                                 const Eigen::Matrix3d& T_tracks, const Eigen::Vector3d& B0_W,
                                 const TrackerOptions& track_options, const QuietRule& rule) {
  QuietSample q;
  const double rel = MultiTrackerOptions::kOtherFieldRelativeError;
  const double sb = SigmaB(s, track_options), st = SigmaT(s, track_options);
  if (rule.occupied_tensor_snr > 0.0 && T_tracks.norm() >= rule.occupied_tensor_snr * st) {
    q.use = QuietUse::kOccupied;
    return q;
  }
  const double st2 = st * st + rel * rel * T_tracks.squaredNorm() / 9.0;
  if ((s.T - T_tracks).squaredNorm() / st2 / 9.0 > rule.tensor_gate) {
    q.use = QuietUse::kGated;
    return q;
  }
  q.r_W = s.B - B0_W - B_tracks;
  q.var_T2 = sb * sb + rule.field_share * rule.field_share * B_tracks.squaredNorm() / 3.0;
  return q;
}

}  // namespace magnav::tracker::internal
