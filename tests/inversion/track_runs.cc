#include "track_runs.h"

#include <cmath>

#include "magnav/inversion/particle_filter.h"

namespace magnav::inversion::testing {

magnav::testing::ErrorStats RunInverter(const std::vector<GradiometerSample>& samples,
                                        const magnav::testing::TruthTrack& truth, const Eigen::Vector3d& B0,
                                        Method method) {
  InverterOptions o;
  o.method = method;
  o.B0_W = B0;
  return RunInverter(samples, truth, o);
}

magnav::testing::ErrorStats RunInverter(const std::vector<GradiometerSample>& samples,
                                        const magnav::testing::TruthTrack& truth, const InverterOptions& options) {
  Inverter inv(options);
  magnav::testing::ErrorStats st;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const DipoleFix f = inv.Process(samples[i]);
    if (f.valid) st.Add((f.p_DinW - truth.p[i]).norm());
  }
  return st;
}

McRun RunMonteCarlo(const std::vector<GradiometerSample>& samples, const magnav::testing::TruthTrack& truth,
                    const Eigen::Vector3d& B0, const Eigen::Vector3d& moment_body, std::uint64_t seed) {
  MonteCarloTrackerOptions mc;
  mc.filter.moment_body_Am2 = moment_body;
  mc.filter.seed = seed;
  mc.init_inverter.B0_W = B0;
  MonteCarloTracker tracker(mc);
  McRun r;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const DipoleFix f = tracker.Process(samples[i]);
    const Eigen::Vector3d d = truth.p[i] - samples[i].p_SinW;
    if (std::hypot(d.x(), d.y()) > kMcHorizontalRange) continue;
    ++r.epochs;
    if (f.valid) r.err.Add((f.p_DinW - truth.p[i]).norm());
  }
  return r;
}

}  // namespace magnav::inversion::testing
