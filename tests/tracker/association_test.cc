// The multi-tracker's associator alone (association.h) on hand-made
// predictions: the SNR gate, the joint model (the other tracks' fields
// removed from a shared sample, their model error added to its σ), and the
// detected / missed / poor-fit / unobserved verdicts.
#include <gtest/gtest.h>

#include <cmath>

#include "magnav/tracker/association.h"

namespace magnav::tracker {
namespace {

const Eigen::Vector3d kB0(2e-5, 1e-6, 4.5e-5);
const Eigen::Vector3d kMoment(2000, 300, 800);

CtState<double> At(double x, double y, double z) { return {x, y, z, 1.0, 0.3, 0.0}; }

GradiometerSample Sensor(std::uint32_t id, const Eigen::Vector3d& p) {
  GradiometerSample s;
  s.sensor_id = id;
  s.t_s = 1.0;
  s.p_SinW = p;
  s.B = kB0;
  s.T.setZero();
  s.sigma_B = 1e-9;
  s.sigma_T = 1.4e-9;
  return s;
}

TrackPrediction Predict(const CtState<double>& x, const Epoch& e, const MultiTrackerOptions& opt) {
  TrackPrediction p;
  p.valid = true;
  for (const auto& s : e.samples) p.at.push_back(PredictAtSample(x, kMoment, s, opt.track));
  return p;
}

TEST(Association, GateGivesATrackOnlyTheSensorsItReaches) {
  const MultiTrackerOptions opt;
  // A vessel 5 m above sensor 0; sensor 1 is 400 m away.
  Epoch e{1.0, {Sensor(0, {0, 0, 0}), Sensor(1, {400, 0, 0})}};
  const auto x = At(1, 0, -5);
  const TrackPrediction p = Predict(x, e, opt);
  EXPECT_GT(p.at[0].snr, 1000.0);
  EXPECT_LT(p.at[1].snr, opt.management.gate_snr);
  for (auto& s : e.samples) {
    s.B += PredictAtSample(x, kMoment, s, opt.track).B;
    s.T += PredictAtSample(x, kMoment, s, opt.track).T;
  }
  const auto a = AssociateEpoch(e, {p}, kB0, opt);
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(a[0].mine.samples.size(), 1u);
  EXPECT_EQ(a[0].mine.samples[0].sensor_id, 0u);
  EXPECT_DOUBLE_EQ(a[0].mine.t_s, 1.0);
  EXPECT_TRUE(a[0].detected);
  EXPECT_FALSE(a[0].missed);
  EXPECT_NEAR(a[0].sum_r2, 0.0, 1e-6);
}

TEST(Association, ASharedSensorIsGivenToEachTrackWithTheOthersFieldRemoved) {
  const MultiTrackerOptions opt;
  Epoch e{1.0, {Sensor(0, {0, 0, 0})}};
  const auto x1 = At(3, 0, -5), x2 = At(-4, 2, -6);
  const TrackPrediction p1 = Predict(x1, e, opt), p2 = Predict(x2, e, opt);
  GradiometerSample& s = e.samples[0];
  s.B += p1.at[0].B + p2.at[0].B;
  s.T += p1.at[0].T + p2.at[0].T;
  const auto a = AssociateEpoch(e, {p1, p2}, kB0, opt);
  ASSERT_EQ(a.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    ASSERT_EQ(a[i].mine.samples.size(), 1u);
    const TrackPrediction& mine = i == 0 ? p1 : p2;
    const TrackPrediction& other = i == 0 ? p2 : p1;
    const GradiometerSample& got = a[i].mine.samples[0];
    EXPECT_LT((got.B - kB0 - mine.at[0].B).norm(), 1e-18) << i;
    EXPECT_LT((got.T - mine.at[0].T).norm(), 1e-20) << i;
    // The other field's model error (5 % of its norm) widens the σ.
    const double rel = MultiTrackerOptions::kOtherFieldRelativeError;
    EXPECT_NEAR(got.sigma_B, std::hypot(1e-9, rel * other.at[0].B.norm() / std::sqrt(3.0)), 1e-24) << i;
    EXPECT_NEAR(got.sigma_T, std::hypot(1.4e-9, rel * other.at[0].T.norm() / 3.0), 1e-24) << i;
    EXPECT_GT(got.sigma_T, 1.4e-9);
    EXPECT_TRUE(a[i].detected) << i;
  }
}

TEST(Association, MissedWhereThePredictedFieldIsAbsentOrExplainsTooLittle) {
  const MultiTrackerOptions opt;
  const auto x = At(1, 0, -5);
  // Nothing there: the LLR is −½‖ẑ‖², a miss.
  Epoch empty{1.0, {Sensor(0, {0, 0, 0})}};
  const TrackPrediction p = Predict(x, empty, opt);
  const auto a = AssociateEpoch(empty, {p}, kB0, opt);
  EXPECT_LT(a[0].llr, -opt.management.detect_llr);
  EXPECT_TRUE(a[0].missed);
  EXPECT_FALSE(a[0].detected);
  // Ten times the predicted field: the LLR is positive but 81 % of the
  // signal energy is left: a poor fit, missed, not detected.
  Epoch strong = empty;
  strong.samples[0].B += 10.0 * p.at[0].B;
  strong.samples[0].T += 10.0 * p.at[0].T;
  const auto b = AssociateEpoch(strong, {p}, kB0, opt);
  EXPECT_GT(b[0].llr, opt.management.detect_llr);
  EXPECT_NEAR(b[0].sum_r2 / b[0].sum_m2, 0.81, 1e-6);
  EXPECT_TRUE(b[0].poor_fit);
  EXPECT_TRUE(b[0].missed);
  EXPECT_FALSE(b[0].detected);
}

TEST(Association, ATrackWithoutPredictionTakesAndRemovesNothing) {
  const MultiTrackerOptions opt;
  Epoch e{1.0, {Sensor(0, {0, 0, 0})}};
  const auto x = At(1, 0, -5);
  const TrackPrediction p = Predict(x, e, opt);
  TrackPrediction none = Predict(At(-2, 1, -5), e, opt);
  none.valid = false;
  e.samples[0].B += p.at[0].B;
  e.samples[0].T += p.at[0].T;
  const auto a = AssociateEpoch(e, {none, p}, kB0, opt);
  EXPECT_TRUE(a[0].mine.samples.empty());
  EXPECT_FALSE(a[0].detected || a[0].missed);  // unobserved
  ASSERT_EQ(a[1].mine.samples.size(), 1u);
  EXPECT_DOUBLE_EQ(a[1].mine.samples[0].sigma_B, 1e-9);  // nothing removed
  EXPECT_TRUE(a[1].detected);
}

}  // namespace
}  // namespace magnav::tracker
