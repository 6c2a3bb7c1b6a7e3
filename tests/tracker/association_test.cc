// The multi-tracker's associator alone (association.h) on hand-made
// predictions: the SNR gate, the joint model (the other tracks' fields
// removed from a shared sample, their model error added to its σ), and the
// detected / missed / poor-fit / unobserved verdicts; and the evidence
// assignment (AssignEvidence: which single-sample fix belongs to which track,
// on cases where the former rule — a fix within min_separation_m, 8 m, of
// any track is "that track's" — or a nearest-fix choice goes wrong).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

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

// fresh_abreast2/abreast_40 at 54 s: a track 11.7 m from sensor 0 (tensor
// SNR ≈ 50), whose gate also takes sensor 1 by its B alone (≈ 10 nT,
// tensor SNR ≈ 1), where an untracked vessel 16 m away (too weak to start)
// adds ≈ 70 nT and its tensor. By default that sample makes the track's fit
// poor (a miss); with poor_fit_tensor_snr it is left out of the test, and
// the track is detected. A B offset there without a tensor (a far source)
// still makes the fit poor.
TEST(Association, AnUntrackedVesselsSampleIsNotThisTracksPoorFit) {
  Epoch e{1.0, {Sensor(0, {-36, -36, 0}), Sensor(1, {0, -36, 0})}};
  MultiTrackerOptions opt;
  const auto x = At(-26.5, -40.6, -5), other = At(13, -43.6, -6);
  const TrackPrediction p = Predict(x, e, opt);
  ASSERT_GE(p.at[1].snr, opt.management.gate_snr);
  ASSERT_LT(p.at[1].T.norm() / 1.4e-9, 2.0);
  Epoch far = e;
  for (std::size_t j = 0; j < e.samples.size(); ++j) {
    const FieldPrediction o = PredictAtSample(other, Eigen::Vector3d(2200, -250, 750), e.samples[j], opt.track);
    for (Epoch* k : {&e, &far}) {
      k->samples[j].B += p.at[j].B;
      k->samples[j].T += p.at[j].T;
    }
    e.samples[j].B += o.B;
    e.samples[j].T += o.T;
  }
  ASSERT_GT(PredictAtSample(other, Eigen::Vector3d(2200, -250, 750), e.samples[1], opt.track).T.norm() / 1.4e-9, 6.0);
  far.samples[1].B += Eigen::Vector3d(50e-9, 0, 0);
  const auto by_default = AssociateEpoch(e, {p}, kB0, opt);
  ASSERT_EQ(by_default[0].mine.samples.size(), 2u);
  EXPECT_TRUE(by_default[0].poor_fit);
  EXPECT_TRUE(by_default[0].missed);
  opt.management.poor_fit_tensor_snr = 6.0;
  const auto with_rule = AssociateEpoch(e, {p}, kB0, opt);
  EXPECT_FALSE(with_rule[0].poor_fit);
  EXPECT_TRUE(with_rule[0].detected);
  EXPECT_EQ(with_rule[0].num_fit_samples, 1);
  const auto far_source = AssociateEpoch(far, {p}, kB0, opt);
  EXPECT_TRUE(far_source[0].poor_fit);
  EXPECT_EQ(far_source[0].num_fit_samples, 2);
  opt.management.poor_fit_tensor_snr = -1.0;
  EXPECT_FALSE(opt.management.IsValid(nullptr));
}

// fresh_overtaking3/overtaking_s13 at 48 s: the slow vessel's track 10.6 m
// from sensor (36, 36) (tensor SNR ≈ 30) also gates sensor (36, 0) by its B
// alone (≈ 10 σ_B, tensor ≈ 1 σ_T), where the untracked overtaker, 23 m from
// it, adds ≈ 30 σ_B of B: by default that sample makes the track's fit poor
// (a miss; 2 s of them ended the track "missed" and the vessel got 2 ids).
// With foreign_b_ratio 1 the sample is another source's (more than the
// track's whole B unexplained where its tensor is not seen) and not the
// track's: detected. A track off its vessel is still a poor fit (its strong
// sensor shows it), and a sample its own B explains stays its.
TEST(Association, AnOvertakersBWhereTheTrackIsSeenByItsBAloneIsNotItsSample) {
  Epoch e{1.0, {Sensor(0, {36, 36, 0}), Sensor(1, {36, 0, 0})}};
  MultiTrackerOptions opt;
  const auto x = At(30.8, 26, -5), other = At(54, 12.5, -5);
  const Eigen::Vector3d m_other(1800, 300, 950);
  const TrackPrediction p = Predict(x, e, opt);
  ASSERT_GT(p.at[0].T.norm() / 1.4e-9, 20.0);
  ASSERT_GE(p.at[1].snr, opt.management.gate_snr);
  ASSERT_LT(p.at[1].T.norm() / 1.4e-9, opt.management.reach_tensor_snr);
  Epoch alone = e;
  for (std::size_t j = 0; j < e.samples.size(); ++j) {
    for (Epoch* k : {&e, &alone}) {
      k->samples[j].B += p.at[j].B;
      k->samples[j].T += p.at[j].T;
    }
    const FieldPrediction o = PredictAtSample(other, m_other, e.samples[j], opt.track);
    e.samples[j].B += o.B;
    e.samples[j].T += o.T;
  }
  const FieldPrediction o1 = PredictAtSample(other, m_other, e.samples[1], opt.track);
  ASSERT_GT(o1.B.norm(), 2.0 * p.at[1].B.norm());
  opt.management.foreign_b_ratio = 0.0;
  const auto off = AssociateEpoch(e, {p}, kB0, opt);
  ASSERT_EQ(off[0].mine.samples.size(), 2u);
  EXPECT_TRUE(off[0].poor_fit);
  EXPECT_TRUE(off[0].missed);
  EXPECT_EQ(off[0].num_foreign, 0);
  opt.management.foreign_b_ratio = 1.0;
  const auto on = AssociateEpoch(e, {p}, kB0, opt);
  ASSERT_EQ(on[0].mine.samples.size(), 1u);
  EXPECT_EQ(on[0].mine.samples[0].sensor_id, 0u);
  EXPECT_EQ(on[0].num_foreign, 1);
  EXPECT_FALSE(on[0].poor_fit);
  EXPECT_TRUE(on[0].detected);
  // Without the overtaker both samples are the track's.
  const auto own = AssociateEpoch(alone, {p}, kB0, opt);
  EXPECT_EQ(own[0].mine.samples.size(), 2u);
  EXPECT_EQ(own[0].num_foreign, 0);
  EXPECT_TRUE(own[0].detected);
  // A track 4 m off its vessel: still a poor fit with the rule.
  const TrackPrediction off_vessel = Predict(At(30.8, 22, -5), e, opt);
  const auto lost = AssociateEpoch(e, {off_vessel}, kB0, opt);
  EXPECT_TRUE(lost[0].poor_fit);
  EXPECT_TRUE(lost[0].missed);
  opt.management.foreign_b_ratio = -1.0;
  EXPECT_FALSE(opt.management.IsValid(nullptr));
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

// The departing track's B where another track is (TrackManagementOptions::reach_shared_b_snr):
// its largest predicted B SNR at a sensor the other track gates, and 0 where no other track gates.
TEST(Association, SharedBSnrIsADepartingTracksBAtTheSensorsAnotherTrackGates) {
  MultiTrackerOptions opt;
  opt.management.reach_shared_b_snr = 3.0;  // computed only for the rule that uses it
  // Sensor 0 under track 1 (5 m above it); the departing track 2 is 40 m away from
  // sensor 0 (its B there well above σ_B, its tensor below the reach) and 400 m from sensor 1.
  Epoch e{1.0, {Sensor(0, {0, 0, 0}), Sensor(1, {400, 0, 0})}};
  const auto x1 = At(1, 0, -5), x2 = At(-40, 0, -5);
  const TrackPrediction p1 = Predict(x1, e, opt), p2 = Predict(x2, e, opt);
  ASSERT_GE(p1.at[0].snr, opt.management.gate_snr);
  const double b_snr = p2.at[0].B.norm() / 1e-9;
  ASSERT_GT(b_snr, 3.0);
  ASSERT_LT(p2.at[0].T.norm() / 1.4e-9, opt.management.reach_tensor_snr);
  const auto both = AssociateEpoch(e, {p1, p2}, kB0, opt);
  EXPECT_NEAR(both[1].max_shared_b_snr, b_snr, 1e-9 * b_snr);
  // Track 1's: its B SNR at sensor 0 if track 2 gates sensor 0, else 0 (sensor 1 is nobody's).
  const double want1 = p2.at[0].snr >= opt.management.gate_snr ? p1.at[0].B.norm() / 1e-9 : 0.0;
  EXPECT_NEAR(both[0].max_shared_b_snr, want1, 1e-9 * want1);
  // Alone, track 2 shares no sensor with anyone.
  const auto alone = AssociateEpoch(e, {p2}, kB0, opt);
  EXPECT_EQ(alone[0].max_shared_b_snr, 0.0);
  // With the rule off (the default) it is not computed.
  const MultiTrackerOptions off;
  EXPECT_EQ(AssociateEpoch(e, {p1, p2}, kB0, off)[1].max_shared_b_snr, 0.0);
  // The option: off by default, checked by IsValid.
  EXPECT_EQ(off.management.reach_shared_b_snr, 0.0);
  MultiTrackerOptions bad = opt;
  bad.management.reach_shared_b_snr = -1.0;
  EXPECT_FALSE(bad.management.IsValid(nullptr));
  bad.management.reach_shared_b_snr = 3.0;
  EXPECT_TRUE(bad.management.IsValid(nullptr));
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

TrackGate Gate(const Eigen::Vector3d& p, const Eigen::Vector3d& sigma) {
  TrackGate g;
  g.valid = true;
  g.p_W = p;
  g.cov_p_W = sigma.array().square().matrix().asDiagonal();
  return g;
}

Evidence Fix(std::uint32_t sensor, const Eigen::Vector3d& p, double sigma) {
  return {sensor, p, sigma * sigma * Eigen::Matrix3d::Identity()};
}

// Two tracks 2 m apart, crossing evidence: A's covariance is long along x
// (1.5 m), B's tight (0.1 m). Fix 0 is nearer B (2.62 m against 2.77 m) but
// lies along A's long axis (χ² 6.9 for A, 69 for B); fix 1 is B's (χ² 0.03;
// 12.4 for A, inside A's gate too). A nearest-fix choice, track by track,
// gives A fix 1 and B fix 0 (outside B's gate); the assignment gives each
// its own.
TEST(Evidence, ChiSquareNotDistanceDecidesWhoseFixItIs) {
  const MultiTrackerOptions opt;
  const std::vector<TrackGate> gates = {Gate({0, 0, -5}, {1.5, 0.5, 0.3}), Gate({0, 2, -5}, {0.1, 0.1, 0.1})};
  const std::vector<Evidence> ev = {Fix(0, {2.5, 1.2, -5}, 0.3), Fix(1, {0, 2.05, -5}, 0.3)};
  EXPECT_LT((ev[0].p_W - gates[1].p_W).norm(), (ev[0].p_W - gates[0].p_W).norm());
  EXPECT_NEAR(InnovationChi2(ev[0], gates[0]), 6.906, 1e-3);
  EXPECT_GT(InnovationChi2(ev[0], gates[1]), opt.management.evidence_gate_chi2);
  EXPECT_NEAR(InnovationChi2(ev[1], gates[0]), 12.36, 1e-2);
  EXPECT_LT(InnovationChi2(ev[1], gates[0]), opt.management.evidence_gate_chi2);
  const auto a = AssignEvidence(ev, gates, Eigen::MatrixXd::Constant(2, 2, 100.0), opt.management);
  EXPECT_EQ(a.track_of_evidence, (std::vector<int>{0, 1}));
  EXPECT_EQ(a.num_taken, (std::vector<int>{1, 1}));
  EXPECT_EQ(a.num_clusters, 1);
  EXPECT_FALSE(a.outbid[0] || a.outbid[1]);
}

// A duplicate (two tracks 0.3 m apart on one vessel) and one fix of it in
// both gates: the former rule made it both tracks' (each could count it
// toward its confirmation); it goes to the likelier one, the other is
// outbid (not detected while tentative). Two fixes of one sensor and epoch
// (the inverter's and the tracker's own of one sample): one track takes one.
TEST(Evidence, OneFixNeverGoesToTwoTracksNorTwoFixesOfOneSensorToOneTrack) {
  const MultiTrackerOptions opt;
  const std::vector<TrackGate> dup = {Gate({0, 0, -5}, {0.2, 0.2, 0.2}), Gate({0.3, 0, -5}, {0.2, 0.2, 0.2})};
  const std::vector<Evidence> one = {Fix(0, {0.05, 0, -5}, 0.1)};
  EXPECT_LT(InnovationChi2(one[0], dup[1]), opt.management.evidence_gate_chi2);
  const auto a = AssignEvidence(one, dup, Eigen::MatrixXd::Constant(2, 1, 100.0), opt.management);
  EXPECT_EQ(a.track_of_evidence, (std::vector<int>{0}));
  EXPECT_EQ(a.num_taken, (std::vector<int>{1, 0}));
  EXPECT_FALSE(a.outbid[0]);
  EXPECT_TRUE(a.outbid[1]);

  const std::vector<Evidence> same_sample = {Fix(0, {0.05, 0, -5}, 0.1), Fix(0, {-0.02, 0.03, -5}, 0.1)};
  const auto b = AssignEvidence(same_sample, {dup[0]}, Eigen::MatrixXd::Constant(1, 2, 100.0), opt.management);
  EXPECT_EQ(b.num_taken, (std::vector<int>{1}));
  EXPECT_EQ((b.track_of_evidence[0] == 0) + (b.track_of_evidence[1] == 0), 1);
  // A third fix, of another sensor: the track takes it too (one per sensor).
  std::vector<Evidence> two_sensors = same_sample;
  two_sensors.push_back(Fix(1, {0.02, -0.01, -5}, 0.1));
  const auto c = AssignEvidence(two_sensors, {dup[0]}, Eigen::MatrixXd::Constant(1, 3, 100.0), opt.management);
  EXPECT_EQ(c.num_taken, (std::vector<int>{2}));
  EXPECT_EQ(c.track_of_evidence[2], 0);
}

// A fix 5 m from a precise track (σ 5 cm): the former rule (within 8 m of a
// track) dropped it as the track's; its χ² is 270, so it is unexplained —
// the initiator's. A fix in the χ² gate at a sensor where the track's
// predicted tensor SNR is below evidence_min_tensor_snr is not the track's
// either. Independent clusters are solved apart.
TEST(Evidence, WhatNoTrackExplainsGoesToTheInitiator) {
  const MultiTrackerOptions opt;
  const double gate_snr = opt.management.evidence_min_tensor_snr;
  const std::vector<TrackGate> gates = {Gate({0, 0, -5}, {0.05, 0.05, 0.05}), Gate({60, 0, -5}, {0.3, 0.3, 0.3})};
  const std::vector<Evidence> ev = {Fix(0, {5, 0, -5}, 0.3), Fix(1, {0.1, 0, -5}, 0.3), Fix(2, {60.2, 0.1, -5}, 0.3)};
  EXPECT_NEAR(InnovationChi2(ev[0], gates[0]), 25.0 / (0.0025 + 0.09), 1e-6);
  Eigen::MatrixXd snr = Eigen::MatrixXd::Constant(2, 3, 100.0);
  snr(0, 1) = 0.9 * gate_snr;
  const auto a = AssignEvidence(ev, gates, snr, opt.management);
  EXPECT_EQ(a.track_of_evidence, (std::vector<int>{-1, -1, 1}));
  EXPECT_EQ(a.num_clusters, 1);
  snr(0, 1) = 1.1 * gate_snr;
  const auto b = AssignEvidence(ev, gates, snr, opt.management);
  EXPECT_EQ(b.track_of_evidence, (std::vector<int>{-1, 0, 1}));
  EXPECT_EQ(b.num_clusters, 2);
  // A track without a gate takes nothing; sizes are checked.
  TrackGate none = gates[0];
  none.valid = false;
  EXPECT_EQ(AssignEvidence(ev, {none, gates[1]}, snr, opt.management).track_of_evidence,
            (std::vector<int>{-1, -1, 1}));
  EXPECT_THROW(AssignEvidence(ev, gates, Eigen::MatrixXd::Zero(2, 2), opt.management), std::invalid_argument);
}

// The gate's covariance: the newest estimate's, grown by the motion model
// and the window's process noise with time; without a usable estimate, as
// wide as a live track may be (max_sigma_horizontal_m).
TEST(Evidence, GateGrowsWithTimeAndIsWideWithoutAnEstimate) {
  const MultiTrackerOptions opt;
  EpochEstimate e;
  e.t_s = 10.0;
  e.p_VinW = {1, 2, -5};
  e.speed_mps = 1.5;
  e.heading_rad = 0.3;
  e.usable = true;
  e.has_covariance = true;
  e.cov_state = (Eigen::Matrix<double, 6, 1>() << 0.01, 0.01, 0.01, 1e-4, 1e-4, 1e-6).finished().asDiagonal();
  const CtState<double> x{1, 2, -5, 1.5, 0.3, 0.0};
  const TrackGate now = PredictGate(x, 10.0, &e, opt);
  EXPECT_TRUE(now.valid);
  EXPECT_LT((now.cov_p_W - 0.01 * Eigen::Matrix3d::Identity()).norm(), 1e-15);
  const TrackGate later = PredictGate(PropagateCoordinatedTurn(x, 5.0), 15.0, &e, opt);
  // Speed and heading uncertainty: along-track 5 s · 0.01 m/s, across 5 s · 1.5 m/s · 0.01 rad.
  EXPECT_GT(later.cov_p_W.trace(), now.cov_p_W.trace() + 2.0 * 0.0025);
  EXPECT_NEAR(later.p_W.x(), 1 + 5 * 1.5 * std::cos(0.3), 1e-9);
  const TrackGate wide = PredictGate(x, 10.0, nullptr, opt);
  const double s = opt.management.max_sigma_horizontal_m;
  EXPECT_LT((wide.cov_p_W - s * s * Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

// The epoch's own evidence: a strong sample under a vessel gives one fix,
// which goes to the track predicted there, not to a track 60 m off; a weak
// sample gives none.
TEST(Evidence, AnEpochsStrongSampleGivesTheTrackThereItsFix) {
  const MultiTrackerOptions opt;
  Epoch e{1.0, {Sensor(0, {0, 0, 0}), Sensor(1, {400, 0, 0})}};
  const auto x = At(1, 0, -5), far = At(61, 0, -5);
  const TrackPrediction p = Predict(x, e, opt), q = Predict(far, e, opt);
  for (auto& s : e.samples) {
    s.B += PredictAtSample(x, kMoment, s, opt.track).B;
    s.T += PredictAtSample(x, kMoment, s, opt.track).T;
  }
  const std::vector<TrackGate> gates = {Gate({61, 0, -5}, {0.3, 0.3, 0.3}), Gate({1.2, 0.1, -5}, {0.3, 0.3, 0.3})};
  std::vector<std::size_t> sample_of;
  const auto a = AssignEpochFixes(e, {q, p}, gates, kB0, opt, &sample_of);
  EXPECT_EQ(sample_of, (std::vector<std::size_t>{0}));
  EXPECT_EQ(a.track_of_evidence, (std::vector<int>{1}));
  EXPECT_EQ(a.num_taken, (std::vector<int>{0, 1}));
  EXPECT_FALSE(a.outbid[0]);
}

}  // namespace
}  // namespace magnav::tracker
