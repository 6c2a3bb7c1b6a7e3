#include "timeline.h"

namespace magnav::localizer::internal {

Timeline BuildTimeline(const Pass& pass, double tolerance_s) {
  Timeline tl;
  std::size_t i = 0, g = 0;
  const std::size_t ns = pass.samples.size(), ng = pass.gnss.size();
  while (i < ns || g < ng) {
    const double t = (g >= ng || (i < ns && pass.samples[i].t_s < pass.gnss[g].t_s)) ? pass.samples[i].t_s
                                                                                      : pass.gnss[g].t_s;
    tl.t.push_back(t);
    tl.samples_at.emplace_back();
    tl.gnss_at.emplace_back();
    while (g < ng && pass.gnss[g].t_s - t <= tolerance_s) tl.gnss_at.back().push_back(static_cast<int>(g++));
    while (i < ns && pass.samples[i].t_s - t <= tolerance_s) tl.samples_at.back().push_back(static_cast<int>(i++));
  }
  return tl;
}

}  // namespace magnav::localizer::internal
