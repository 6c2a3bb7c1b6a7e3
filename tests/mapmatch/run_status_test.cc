// RunStatus (run_status.h): an implausible or a non-finite estimate spoils a finished run for ever
// (kWholeRun, `magnav match`), and a live matcher's status only for the steps of its window
// (kRecent, magnav-matcher): the live status recovers once the estimates are sane again.
#include "magnav/mapmatch/run_status.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace magnav::mapmatch {
namespace {

// A settled, on-track step: the estimate `off_deg` north of the INS position.
StepDiagnostics Step(double ins_lat, double ins_lon, double off_deg) {
  StepDiagnostics d;
  d.lat_deg = ins_lat + off_deg;
  d.lon_deg = ins_lon;
  d.cloud_cov_lat_lat = d.cloud_cov_lon_lon = 1e-8;
  d.update = StepUpdate::kUpdated;
  return d;
}

struct TwoStatuses {
  ParticleFilterOptions o;
  RunStatus whole{ParticleFilterKind::kPf, o, 0.0, RunStatusMemory::kWholeRun};
  RunStatus recent{ParticleFilterKind::kPf, o, 0.0, RunStatusMemory::kRecent};
  FilterCounters c;
  long long k = 0;
  void Add(double off_deg) {
    const double lat = 50.0 + 1e-4 * k, lon = 7.0;
    const StepDiagnostics d = Step(lat, lon, off_deg);
    whole.Add(lat, lon, d, c, k);
    recent.Add(lat, lon, d, c, k);
    ++k;
  }
};

TEST(RunStatus, AnImplausibleEstimateSpoilsTheRunButNotTheLiveStatusForEver) {
  TwoStatuses r;
  const std::size_t window = 2 * static_cast<std::size_t>(r.o.divergence_window);
  const double plausible = 2.0 * r.o.prior_half_width_deg;
  for (int i = 0; i < 30; ++i) r.Add(1e-4);
  ASSERT_EQ(r.whole.verdict(), RunVerdict::kConverged);
  ASSERT_EQ(r.recent.verdict(), RunVerdict::kConverged);
  r.Add(3.0 * plausible);  // one estimate far beyond the plausible correction
  EXPECT_EQ(r.whole.verdict(), RunVerdict::kImplausible);
  EXPECT_EQ(r.recent.verdict(), RunVerdict::kImplausible);
  EXPECT_NE(r.recent.reason().find("within the last"), std::string::npos) << r.recent.reason();
  // Still implausible over the window after it...
  for (std::size_t i = 0; i + 1 < window; ++i) {
    r.Add(1e-4);
    ASSERT_EQ(r.recent.verdict(), RunVerdict::kImplausible) << "step " << i << " after the bad one";
  }
  // ...and then the live status recovers, while the finished run keeps the verdict.
  r.Add(1e-4);
  EXPECT_EQ(r.recent.verdict(), RunVerdict::kConverged) << r.recent.reason();
  for (int i = 0; i < 500; ++i) r.Add(1e-4);
  EXPECT_EQ(r.recent.verdict(), RunVerdict::kConverged);
  EXPECT_EQ(r.whole.verdict(), RunVerdict::kImplausible) << r.whole.reason();
  EXPECT_EQ(r.whole.reason().find("within the last"), std::string::npos) << r.whole.reason();
  // A second episode is judged afresh.
  r.Add(-3.0 * plausible);
  EXPECT_EQ(r.recent.verdict(), RunVerdict::kImplausible);
}

TEST(RunStatus, ANonFiniteEstimateIsForgottenByTheLiveStatusAfterItsWindow) {
  TwoStatuses r;
  const std::size_t window = 2 * static_cast<std::size_t>(r.o.divergence_window);
  for (int i = 0; i < 30; ++i) r.Add(1e-4);
  r.Add(std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(r.whole.verdict(), RunVerdict::kNonFinite);
  EXPECT_EQ(r.recent.verdict(), RunVerdict::kNonFinite);
  for (std::size_t i = 0; i + 1 < window; ++i) r.Add(1e-4);
  EXPECT_EQ(r.recent.verdict(), RunVerdict::kNonFinite);
  r.Add(1e-4);
  EXPECT_EQ(r.recent.verdict(), RunVerdict::kConverged) << r.recent.reason();
  EXPECT_EQ(r.whole.verdict(), RunVerdict::kNonFinite);
  // Every later non-finite estimate holds the live status for a window of its own.
  r.Add(std::numeric_limits<double>::quiet_NaN());
  r.Add(1e-4);
  EXPECT_EQ(r.recent.verdict(), RunVerdict::kNonFinite);
}

}  // namespace
}  // namespace magnav::mapmatch
