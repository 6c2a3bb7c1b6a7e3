#include <cmath>
#include <string>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

std::vector<Epoch> GroupEpochs(const std::vector<GradiometerSample>& samples, double tolerance_s) {
  std::vector<Epoch> epochs;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const GradiometerSample& s = samples[i];
    if (!std::isfinite(s.t_s)) throw InputError("sample " + std::to_string(i) + ": time is not finite");
    if (!epochs.empty() && std::abs(s.t_s - epochs.back().t_s) <= tolerance_s) {
      epochs.back().samples.push_back(s);
      continue;
    }
    if (!epochs.empty() && s.t_s < epochs.back().t_s) {
      throw InputError("sample " + std::to_string(i) + ": time " + FormatNumber(s.t_s) +
                       " s is earlier than the previous epoch " + FormatNumber(epochs.back().t_s) +
                       " s (samples must be ordered by time)");
    }
    epochs.push_back(Epoch{s.t_s, {s}});
  }
  return epochs;
}

Eigen::Vector3d EpochEstimate::v_VinW() const {
  return {speed_mps * std::cos(heading_rad), speed_mps * std::sin(heading_rad), 0.0};
}

}  // namespace magnav::tracker
