#include "magnav/tracker/residual_start.h"

#include <algorithm>
#include <cmath>

#include "magnav/core/option_check.h"

namespace magnav::tracker {

bool ResidualStartOptions::IsValid(std::string* error) const {
  if (!(tensor_snr >= 0.0) || !std::isfinite(tensor_snr)) return Fail(error, "residual_start.tensor_snr must be >= 0");
  if (!(track_share >= 0.0) || !std::isfinite(track_share)) {
    return Fail(error, "residual_start.track_share must be >= 0");
  }
  if (!(max_track_shift_m > 0.0) || !std::isfinite(max_track_shift_m)) {
    return Fail(error, "residual_start.max_track_shift_m must be > 0");
  }
  if (lone_min_fixes < 0) return Fail(error, "residual_start.lone_min_fixes must be >= 0");
  if (!(lone_min_span_s >= 0.0) || !std::isfinite(lone_min_span_s)) {
    return Fail(error, "residual_start.lone_min_span_s must be >= 0");
  }
  return true;
}

TrackerOptions LoneStartTrackerOptions(const TrackerOptions& track, const ResidualStartOptions& o) {
  TrackerOptions lone = ResidualStartTrackerOptions(track, o);
  lone.init.min_fixes = std::max(track.init.min_fixes, o.lone_min_fixes);
  lone.init.min_span_s = std::max(track.init.min_span_s, o.lone_min_span_s);
  // The tracker's own fixes, unless only external fixes may start a track
  // (then StartLone does not run).
  if (lone.init.source != InitSource::kExternal) lone.init.source = InitSource::kSamples;
  return lone;
}

TrackerOptions ResidualStartTrackerOptions(const TrackerOptions& track, const ResidualStartOptions& o) {
  TrackerOptions weak = track;
  if (o.tensor_snr > 0.0) weak.init.min_tensor_snr = std::min(track.init.min_tensor_snr, o.tensor_snr);
  return weak;
}

std::optional<InitialTrack> InitializeInResidual(
    std::vector<Epoch> residual, const Eigen::Vector3d& B0_W, const TrackerOptions& track,
    const ResidualStartOptions& o,
    const std::function<double(double t_s, const GradiometerSample& s)>& tracks_T) {
  if (!(o.tensor_snr > 0.0) || residual.empty()) return std::nullopt;
  const TrackerOptions weak = ResidualStartTrackerOptions(track, o);
  if (tracks_T) {
    for (Epoch& e : residual) {
      for (GradiometerSample& s : e.samples) {
        if (s.T.isZero(0.0)) continue;  // masked already
        const double T = s.T.norm();
        if (T < weak.init.min_tensor_snr * SigmaT(s, weak)) continue;  // no fix from it anyway
        if (T < o.track_share * tracks_T(e.t_s, s)) {
          s.B = B0_W;
          s.T.setZero();
        }
      }
    }
  }
  return InitializeTrack(residual, B0_W, weak);
}

}  // namespace magnav::tracker
