// The door check of samples and the running estimate of the regional field B0,
// on the reference passes (independent data) and simulated passes with a
// quiet lead-in.
#include "magnav/core/regional_field.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/simulate.h"
#include "test_data.h"

namespace magnav {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

GradiometerSample GoodSample() {
  GradiometerSample s;
  s.t_s = 1.0;
  s.B = {2e-5, 1e-6, 4.5e-5};
  s.T << 1e-9, 2e-9, 0, 2e-9, -3e-9, 0, 0, 0, 2e-9;
  s.sigma_B = 1e-9;
  s.sigma_T = 1.4e-9;
  return s;
}

TEST(CheckSample, NamesEachDefect) {
  EXPECT_EQ(CheckSample(GoodSample()), SampleDefect::kNone);
  GradiometerSample s = GoodSample();
  s.t_s = kNaN;
  EXPECT_EQ(CheckSample(s), SampleDefect::kNonFiniteTime);
  s = GoodSample();
  s.B.x() = kNaN;
  EXPECT_EQ(CheckSample(s), SampleDefect::kNonFinite);
  s = GoodSample();
  s.T(2, 1) = -kInf;
  EXPECT_EQ(CheckSample(s), SampleDefect::kNonFinite);
  s = GoodSample();
  s.T(0, 0) = 1e200;  // finite, but ‖T‖ overflows
  EXPECT_EQ(CheckSample(s), SampleDefect::kNonFinite);
  s = GoodSample();
  s.p_SinW.z() = kNaN;
  EXPECT_EQ(CheckSample(s), SampleDefect::kNonFinite);
  s = GoodSample();
  s.sigma_T = kInf;
  EXPECT_EQ(CheckSample(s), SampleDefect::kBadSigma);
  s = GoodSample();
  s.sigma_B = -1e-9;
  EXPECT_EQ(CheckSample(s), SampleDefect::kBadSigma);
  s = GoodSample();
  s.sigma_B = s.sigma_T = 0.0;  // unknown is not a defect
  EXPECT_EQ(CheckSample(s), SampleDefect::kNone);
  s = GoodSample();
  s.T.setZero();
  EXPECT_EQ(CheckSample(s), SampleDefect::kZeroTensor);
  // Finite but no reading (the same limits as the file readers).
  s = GoodSample();
  s.p_SinW.y() = 1e308;
  EXPECT_EQ(CheckSample(s), SampleDefect::kOutOfRange);
  s = GoodSample();
  s.B.z() = 45000.0;  // nT as T
  EXPECT_EQ(CheckSample(s), SampleDefect::kOutOfRange);
  s = GoodSample();
  s.T(1, 0) = -11.0;
  EXPECT_EQ(CheckSample(s), SampleDefect::kOutOfRange);
  s = GoodSample();
  s.B.x() = MaxAbs(kLimitB);  // at the limit: kept
  s.p_SinW.x() = MaxAbs(kLimitPosition);
  EXPECT_EQ(CheckSample(s), SampleDefect::kNone);
  EXPECT_STREQ(SampleDefectName(SampleDefect::kOutOfRange), "out_of_range");
  EXPECT_STREQ(SampleDefectName(SampleDefect::kZeroTensor), "zero_tensor");
  EXPECT_STREQ(SampleDefectName(SampleDefect::kNone), "");
}

struct B0Run {
  std::optional<Eigen::Vector3d> B0;
  double ready_at_s = kNaN;
  int n = 0;
};

B0Run Feed(const std::vector<GradiometerSample>& samples, const RegionalFieldOptions& o = {}) {
  RegionalFieldEstimator est(o);
  B0Run run;
  for (const auto& s : samples) {
    if (est.Add(s) == RegionalFieldEstimator::Status::kBecameReady) run.ready_at_s = s.t_s;
  }
  run.B0 = est.B0(samples.front().sensor_id);
  run.n = est.num_samples(samples.front().sensor_id);
  return run;
}

// Largest |B − B0| of a pass: what a B0 error is to be measured against (a
// TED fix errs by ≈ |δB0| / |B − B0| relative).
double PeakAnomaly(const std::vector<GradiometerSample>& samples, const Eigen::Vector3d& B0) {
  double peak = 0.0;
  for (const auto& s : samples) peak = std::max(peak, (s.B - B0).norm());
  return peak;
}

// The AUV fluxgate reference pass starts 111 m from the sensor: its field is
// tensor is at noise level there and B moves by only ≈ 0.04 nT/s, so B0 is
// found with the first full window. The AUV's own field there (0.7–1.8 nT,
// from the noise-free file) is what no quiet test can tell from background:
// the estimate errs by about that, ≈ 0.1 % of the field at closest approach.
TEST(RegionalFieldEstimator, FindsB0OnTheQuietStartOfTheAuvFluxgatePass) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv"));
  const std::vector<GradiometerSample> before_approach(f.samples.begin(), f.samples.begin() + 700);  // t < 70 s
  const B0Run run = Feed(before_approach);
  ASSERT_TRUE(run.B0.has_value());
  EXPECT_LE(run.ready_at_s, 10.0);  // the first full window
  ASSERT_GE(run.n, 50);
  const double err = (*run.B0 - *f.B0).norm();
  const double peak = PeakAnomaly(f.samples, *f.B0);
  std::printf("AUV fluxgate: B0 error %.3g nT, %.3g of the peak anomaly %.4g nT\n", err * 1e9, err / peak,
              peak * 1e9);
  EXPECT_LE(err, 2.0e-9);
  EXPECT_LE(err / peak, 1.8e-3);
}

// The ship's field is never quiet at the sensor during its pass (SQUID noise
// makes even its far tensor strong; with fluxgate noise its far field still
// moves by nT/s): no estimate, rather than a wrong one.
TEST(RegionalFieldEstimator, NoEstimateWhileAShipIsInRange) {
  for (const char* name : {"track_pass_ship_1sensor_squid.csv", "track_pass_ship_1sensor_fluxgate.csv",
                           "track_pass_auv_1sensor_squid.csv"}) {
    const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath(name));
    EXPECT_FALSE(Feed(f.samples).B0.has_value()) << name;
  }
}

// Held out: a simulated ship (another moment, speed, heading and B0) that
// starts 400 m away and passes 10 m from the sensor: B0 is found while it is
// far; at closest approach the estimate in use errs by a tiny fraction of the
// ship's field there.
TEST(RegionalFieldEstimator, SimulatedShipFromFarAway) {
  PassScenario sc;
  sc.moment_body = {3e5, -4e4, 1e5};
  sc.start_position = {-400.0, 10.0, -8.0};
  sc.start_heading_rad = 0.0;
  sc.speed_mps = 2.0;
  sc.segments = {{200.0, 0.0}};  // ends at closest approach
  sc.B0 = {1.8e-5, -2e-6, 4.1e-5};
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 77;
  const SimulatedPass pass = SimulatePass(sc);
  const B0Run run = Feed(pass.samples);
  ASSERT_TRUE(run.B0.has_value());
  EXPECT_LE(run.ready_at_s, 10.0);
  const double err = (*run.B0 - sc.B0).norm();
  const double peak = PeakAnomaly(pass.samples, sc.B0);
  std::printf("simulated ship: B0 error %.3g nT, %.3g of the peak anomaly %.4g nT\n", err * 1e9, err / peak,
              peak * 1e9);
  EXPECT_LE(err / peak, 1.2e-4);
}

TEST(RegionalFieldEstimator, UnknownSigmaAndBadSamplesAreSaidSo) {
  GradiometerSample s = GoodSample();
  s.sigma_B = s.sigma_T = 0.0;
  RegionalFieldEstimator est({});
  EXPECT_EQ(est.Add(s), RegionalFieldEstimator::Status::kUnknownSigma);
  s.B.x() = kNaN;
  EXPECT_EQ(est.Add(s), RegionalFieldEstimator::Status::kBadSample);
  EXPECT_FALSE(est.B0(0).has_value());
  RegionalFieldOptions o;
  o.window_s = -1;
  EXPECT_THROW(RegionalFieldEstimator{o}, InputError);
}

// A bad sample in a quiet stretch is refused and does not move the estimate.
TEST(RegionalFieldEstimator, BadSampleDoesNotPoisonTheEstimate) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv"));
  std::vector<GradiometerSample> samples(f.samples.begin(), f.samples.begin() + 200);
  samples[120].B.y() = kNaN;
  samples[130].T.setZero();
  samples[140].sigma_T = kInf;
  const B0Run run = Feed(samples);
  ASSERT_TRUE(run.B0.has_value());
  EXPECT_TRUE(run.B0->allFinite());
  std::vector<GradiometerSample> clean(f.samples.begin(), f.samples.begin() + 200);
  clean.erase(clean.begin() + 140);  // the same stretch without the bad samples
  clean.erase(clean.begin() + 130);
  clean.erase(clean.begin() + 120);
  const B0Run ref = Feed(clean);
  ASSERT_TRUE(ref.B0.has_value());
  EXPECT_EQ((*run.B0 - *ref.B0).norm(), 0.0);
}

}  // namespace
}  // namespace magnav
