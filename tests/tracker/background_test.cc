// The per-sensor background filter alone (tracker/background.h), at its
// defaults: it follows a drift and a slow far source, down-weights a near
// vessel's fast field and holds while a residual tensor shows one, keeps
// sensors apart, and survives a checkpoint bit for bit. Figures measured
// 2026-11-26 (the filter is deterministic: noise-free inputs).
#include "magnav/tracker/background.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "magnav/core/checkpoint.h"

namespace magnav::tracker {
namespace {

const Eigen::Vector3d kB0(2.0e-5, 1.0e-6, 4.5e-5);
constexpr double kSigma = 1e-9;  // fluxgate σ_B per axis
constexpr double kDt = 0.1;      // 10 Hz

TEST(SensorBackground, FollowsADriftOfAFewNanoteslaPerMinute) {
  SensorBackgrounds bg(kB0, BackgroundOptions{});
  const Eigen::Vector3d rate(4e-9 / 60.0, -2e-9 / 60.0, 1e-9 / 60.0);  // ~4.6 nT/min
  double worst = 0.0;
  for (int k = 0; k <= 3000; ++k) {  // 300 s, noise-free
    const double t = k * kDt;
    const Eigen::Vector3d truth = kB0 + rate * t;
    if (t > 30.0) worst = std::max(worst, (bg.Predict(7, t).B_W - truth).norm());
    bg.Update(7, t, truth, kSigma * kSigma, 1.0);
  }
  // Measured 0.02 nT after the first 30 s (an integrated random walk has no
  // lag on a ramp once it has its rate); 0.1 nT is 1/10 of σ_B.
  std::printf("drift: largest error after 30 s %.4f nT\n", worst * 1e9);
  EXPECT_LT(worst, 0.035e-9);
}

TEST(SensorBackground, FollowsAFarSourceOfTensOfNanoteslaPerMinute) {
  // 20 nT/min, then a 30 nT bell 150 s wide (a far ship passing slowly).
  SensorBackgrounds ramp(kB0, BackgroundOptions{});
  SensorBackgrounds bell(kB0, BackgroundOptions{});
  const Eigen::Vector3d dir = Eigen::Vector3d(1, 2, -2).normalized();
  double worst_ramp = 0.0, worst_bell = 0.0;
  for (int k = 0; k <= 6000; ++k) {
    const double t = k * kDt;
    const Eigen::Vector3d r = kB0 + 20e-9 / 60.0 * t * dir;
    const double u = (t - 300.0) / 150.0;
    const Eigen::Vector3d b = kB0 + 30e-9 * dir / std::pow(1.0 + u * u, 1.5);
    if (t > 30.0) worst_ramp = std::max(worst_ramp, (ramp.Predict(1, t).B_W - r).norm());
    worst_bell = std::max(worst_bell, (bell.Predict(1, t).B_W - b).norm());
    ramp.Update(1, t, r, kSigma * kSigma, 1.0);
    bell.Update(1, t, b, kSigma * kSigma, 1.0);
  }
  std::printf("ramp: %.4f nT after 30 s; bell: %.3f nT\n", worst_ramp * 1e9, worst_bell * 1e9);
  EXPECT_LT(worst_ramp, 0.15e-9);  // measured 0.086 nT after the first 30 s
  EXPECT_LT(worst_bell, 4.0e-9);  // measured 2.7 nT of 30 nT
  // Not followed at these defaults: a 30 nT bell only ~50 s wide (a ship at
  // 3 m/s ~110 m off) lags by about its whole height (docs/ACCURACY.md).
}

TEST(SensorBackground, BarelyMovesForANearVessel) {
  // A near, untracked vessel: 300 nT rising and falling within ~10 s.
  SensorBackgrounds bg(kB0, BackgroundOptions{});
  const Eigen::Vector3d dir = Eigen::Vector3d(0, 1, 1).normalized();
  for (int k = 0; k <= 600; ++k) bg.Update(2, k * kDt, kB0, kSigma * kSigma, 1.0);
  double worst = 0.0;
  for (int k = 601; k <= 1800; ++k) {
    const double t = k * kDt;
    const double u = (t - 120.0) / 4.0;
    bg.Update(2, t, kB0 + 300e-9 * dir / std::pow(1.0 + u * u, 1.5), kSigma * kSigma, 1.0);
    worst = std::max(worst, (bg.Predict(2, t).B_W - kB0).norm());
  }
  std::printf("near vessel: %.2f nT taken\n", worst * 1e9);
  EXPECT_GT(bg.num_gated(), 0);
  EXPECT_LT(worst, 13e-9);  // measured 6.6 nT of the vessel's 300 nT
}

TEST(SensorBackground, HeldWhileATensorSaysANearSourceIsThere) {
  // The same vessel, its residual tensor seen (χ² per element ≫ 1): the
  // level is held and its σ grows.
  SensorBackgrounds bg(kB0, BackgroundOptions{});
  for (int k = 0; k <= 600; ++k) bg.Update(2, k * kDt, kB0, kSigma * kSigma, 1.0);
  const double sigma_before = bg.Predict(2, 60.0).sigma_T;
  const Eigen::Vector3d dir = Eigen::Vector3d(0, 1, 1).normalized();
  double worst = 0.0;
  for (int k = 601; k <= 1800; ++k) {
    const double t = k * kDt;
    const double u = (t - 120.0) / 4.0;
    const double f = 1.0 / std::pow(1.0 + u * u, 1.5);
    bg.Update(2, t, kB0 + 300e-9 * dir * f, kSigma * kSigma, 1.0 + 400.0 * f);
    worst = std::max(worst, (bg.Predict(2, t).B_W - kB0).norm());
  }
  std::printf("near vessel, tensor seen: %.3f nT taken\n", worst * 1e9);
  EXPECT_GT(bg.num_occupied(), 0);
  EXPECT_LT(worst, 0.13e-9);  // measured 0.068 nT
  EXPECT_GT(bg.Predict(2, 120.0).sigma_T, sigma_before);
}

TEST(SensorBackground, SensorsAreApartAndUnseenOnesAreB0) {
  SensorBackgrounds bg(kB0, BackgroundOptions{});
  const Eigen::Vector3d off(5e-9, 0, 0);
  for (int k = 0; k <= 200; ++k) bg.Update(3, k * kDt, kB0 + off, kSigma * kSigma, 1.0);
  EXPECT_LT((bg.Predict(3, 20.0).B_W - kB0 - off).norm(), 0.5e-9);
  EXPECT_EQ(bg.Predict(4, 20.0).B_W, kB0);
  EXPECT_EQ(bg.Predict(4, 20.0).sigma_T, BackgroundOptions{}.initial_sigma_T);
  EXPECT_EQ(bg.num_sensors(), 1);
}

TEST(SensorBackground, CheckpointGoesOnBitForBit) {
  SensorBackgrounds a(kB0, BackgroundOptions{});
  for (int k = 0; k < 100; ++k) a.Update(k % 3, k * kDt, kB0 + Eigen::Vector3d(k * 1e-10, 0, 0), kSigma * kSigma, 1.0);
  StateWriter w;
  a.SaveState(w);
  SensorBackgrounds b(kB0, BackgroundOptions{});
  StateReader r(w.bytes());
  b.RestoreState(r);
  EXPECT_TRUE(r.at_end());
  for (int k = 100; k < 150; ++k) {
    const Eigen::Vector3d z = kB0 + Eigen::Vector3d(0, k * 1e-10, 0);
    a.Update(k % 3, k * kDt, z, kSigma * kSigma, 1.0);
    b.Update(k % 3, k * kDt, z, kSigma * kSigma, 1.0);
  }
  for (std::uint32_t id = 0; id < 3; ++id) {
    EXPECT_EQ(a.Predict(id, 20.0).B_W, b.Predict(id, 20.0).B_W);
    EXPECT_EQ(a.Predict(id, 20.0).sigma_T, b.Predict(id, 20.0).sigma_T);
  }
}

TEST(SensorBackground, OptionsAreChecked) {
  BackgroundOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why));
  o.rate_walk_T_per_s_per_sqrt_s = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  o = BackgroundOptions{};
  o.gate_chi2 = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
}

}  // namespace
}  // namespace magnav::tracker
