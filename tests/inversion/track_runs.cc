#include "track_runs.h"

#include <algorithm>
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
  return RunInverterWithRange(samples, truth, options).err;
}

InverterOptions SigmaGateOptions(const Eigen::Vector3d& B0, double relative, double absolute) {
  InverterOptions o;
  o.B0_W = B0;
  o.gates.min_snr = 100.0;  // the weak-signal floor these sweeps were measured with (the default until 2026-11-25)
  o.gates.max_relative_sigma = relative;
  o.gates.max_position_sigma_3d_m = absolute;
  return o;
}

RangeErrors RunInverterWithRange(const std::vector<GradiometerSample>& samples,
                                 const magnav::testing::TruthTrack& truth, const InverterOptions& options,
                                 std::size_t samples_per_instant) {
  Inverter inv(options);  // one speed-gate reference per sensor
  RangeErrors r;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const DipoleFix f = inv.Process(samples[i]);
    if (!f.valid) continue;
    const Eigen::Vector3d& p = truth.p[i / samples_per_instant];
    const double e = (f.p_DinW - p).norm();
    r.err.Add(e);
    r.max_relative = std::max(r.max_relative, e / (p - samples[i].p_SinW).norm());
  }
  return r;
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
