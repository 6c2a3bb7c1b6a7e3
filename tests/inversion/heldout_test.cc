// Held-out checks of the inverter's tuned defaults (docs/ACCURACY.md,
// "Tuned and held-out figures"): the TED+EGT eigenvector-row weight was chosen
// on the 233 strong noisy reference cases and the MC noise settings on the
// four reference passes. Here both meet their targets on data they were not
// tuned on: fresh random static cases and simulated passes with other
// moments, headings, closest approaches, turn direction and noise seeds.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/gradiometer.h"
#include "magnav/core/simulate.h"
#include "magnav/inversion/analytic.h"
#include "magnav/inversion/inverter.h"
#include "magnav/inversion/particle_filter.h"
#include "reference_cases.h"
#include "reference_truth.h"
#include "test_data.h"
#include "track_runs.h"

namespace magnav::inversion {
namespace {

using magnav::testing::ErrorStats;
using magnav::testing::ExpectCountFigure;
using magnav::testing::ExpectErrorFigure;
using magnav::testing::TruthTrack;

struct StaticCase {
  Vec3 r_DtoS;
  GradiometerSample noisy;
};

// `n` cases drawn like the reference's regular kind (moment log-uniform in
// [10, 1e6] A·m², direction uniform; range log-uniform in [2, 60] m), with
// the simulator's reference noise model (fluxgate level), own seed.
std::vector<StaticCase> FreshCases(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  std::uniform_real_distribution<double> u01;
  auto direction = [&] {
    Vec3 d(n01(rng), n01(rng), n01(rng));
    return Vec3(d / d.norm());
  };
  std::vector<StaticCase> out;
  for (int i = 0; i < n; ++i) {
    PassScenario sc;  // one instant of a vessel at rest at the origin, heading 0
    sc.moment_body = std::pow(10.0, 1.0 + 5.0 * u01(rng)) * direction();
    sc.start_position = Vec3::Zero();
    sc.start_heading_rad = 0.0;
    sc.speed_mps = 0.0;
    sc.segments = {{0.05, 0.0}};
    const double range = 2.0 * std::pow(30.0, u01(rng));
    sc.sensors = {range * direction()};
    sc.B0 = Vec3::Zero();
    sc.sigma_B = testing::kCaseSigmaB;
    sc.sigma_T = testing::kCaseSigmaT;
    sc.seed = seed * 100000 + static_cast<std::uint64_t>(i);
    const SimulatedPass pass = SimulatePass(sc);
    out.push_back({sc.sensors[0], pass.samples.at(0)});
  }
  return out;
}

// The fresh cases of both static tests (seed 77), drawn once.
const std::vector<StaticCase>& Fresh() {
  static const std::vector<StaticCase> cases = FreshCases(2000, 77);
  return cases;
}

// Median and 90th percentile of the TED+EGT relative error for weight w over
// the cases with ‖T‖_F > 100 σ_T (as in the reference comparison).
std::pair<double, double> RelativeErrors(const std::vector<StaticCase>& cases, double w, int* used) {
  std::vector<double> e;
  for (const StaticCase& c : cases) {
    if (c.noisy.T.norm() <= 100.0 * testing::kCaseSigmaT) continue;
    AnalyticSolution s;
    e.push_back(SolveTedEgt(c.noisy.T, c.noisy.B, w, {}, &s) ? (s.r_DtoS - c.r_DtoS).norm() / c.r_DtoS.norm()
                                                            : 1e9);
  }
  *used = static_cast<int>(e.size());
  return {testing::Quantile(e, 0.5), testing::Quantile(e, 0.9)};
}

// The weight 0.5 was picked on 233 reference cases, where 0.3–1 were within
// the sampling noise. On 2000 fresh draws it must still be within that band:
// 90th percentile within 5 % of the best weight's, median within 5 %.
TEST(HeldOut, EigenvectorRowWeightOnFreshCases) {
  const std::vector<StaticCase>& cases = Fresh();
  const double w0 = InverterOptions{}.egt_row_weight;
  double best_median = 1e9, best_p90 = 1e9;
  int used = 0;
  std::printf("| w | median | p90 |\n");
  for (const double w : {0.0, 0.1, 0.3, 0.5, 1.0, 2.0, 10.0}) {
    const auto [median, p90] = RelativeErrors(cases, w, &used);
    std::printf("| %g | %.5f | %.5f |\n", w, median, p90);
    best_median = std::min(best_median, median);
    best_p90 = std::min(best_p90, p90);
  }
  const auto [median, p90] = RelativeErrors(cases, w0, &used);
  std::printf("%d of 2000 fresh cases with |T| > 100 sigma_T\n", used);
  EXPECT_GT(used, 600);
  EXPECT_LE(p90, 1.05 * best_p90);
  EXPECT_LE(median, 1.05 * best_median);
  // The targets of the reference comparison (median ≤ 0.01, p90 ≤ 0.05).
  EXPECT_LE(median, 0.01);
  EXPECT_LE(p90, 0.05);
}

// The predicted 1-σ position error was checked on the 233 reference cases
// (RMS of |e|/σ 1.00); on the 986 strong fresh cases the RMS of |e|/σ has a
// standard error of ~0.013 (|e|²/σ² ~ χ²(3)/3): within ±0.05 is ~4 of them.
TEST(HeldOut, PredictedSigmaCalibratedOnFreshCases) {
  const std::vector<StaticCase>& cases = Fresh();
  double sum = 0.0;
  int n = 0;
  for (const StaticCase& c : cases) {
    if (c.noisy.T.norm() <= 100.0 * testing::kCaseSigmaT) continue;
    AnalyticSolution s;
    ASSERT_TRUE(SolveTedEgt(c.noisy.T, c.noisy.B, InverterOptions{}.egt_row_weight,
                            {testing::kCaseSigmaB, testing::kCaseSigmaT}, &s));
    const double z = (s.r_DtoS - c.r_DtoS).norm() / s.position_sigma_3d_m;
    sum += z * z;
    ++n;
  }
  const double rms = std::sqrt(sum / n);
  std::printf("fresh cases: RMS(error / predicted sigma) = %.3f over %d cases\n", rms, n);
  EXPECT_GT(rms, 0.95);
  EXPECT_LT(rms, 1.05);
}

// Documented figures of one held-out pass (docs/ACCURACY.md).
struct HeldOutFigures {
  int ted_egt_count;  // default gates
  double ted_egt_max;
  int abs_count;      // the former absolute 5 cm σ gate instead
  double abs_max;
  double mc_worst_rms;  // worst of seeds 1-5
  int mc_fewest;        // fewest epochs with an MC estimate over the seeds
  bool mc_meets_paper;  // MC RMS within the paper's target for every seed
};

// TED+EGT (default gates, and the absolute 5 cm gate) and MC (default
// options, seeds 1-5) on one simulated pass; MC window 30 m horizontal as on
// the reference passes.
void RunHeldOutPass(const PassScenario& sc, bool fluxgate, const HeldOutFigures& doc, const std::string& what) {
  const SimulatedPass pass = SimulatePass(sc);
  const TruthTrack truth = magnav::testing::TruthOf(pass);
  const ErrorStats ted_egt = testing::RunInverter(pass.samples, truth, sc.B0, Method::kTedEgt);
  const ErrorStats abs = testing::RunInverter(pass.samples, truth, testing::SigmaGateOptions(sc.B0, 0.0, 0.05));
  double mc_worst_rms = 0.0;
  int min_count = 1 << 30, epochs = 0;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const testing::McRun mc = testing::RunMonteCarlo(pass.samples, truth, sc.B0, sc.moment_body, seed);
    mc_worst_rms = std::max(mc_worst_rms, mc.err.rms());
    min_count = std::min(min_count, mc.err.count);
    epochs = mc.epochs;
  }
  std::printf("| %s | TED+EGT %d fixes, RMS %.4f, max %.4f (5 cm gate: %d, %.4f) | MC worst RMS of seeds 1-5 %.3f, "
              "fewest %d of %d |\n",
              what.c_str(), ted_egt.count, ted_egt.rms(), ted_egt.max, abs.count, abs.max, mc_worst_rms, min_count,
              epochs);
  // Targets (paper Table 2): TED+EGT max 0.13 m SQUID / 1.7 m fluxgate, MC
  // RMS 0.4 / 0.7 m. TED+EGT: fluxgate with the default gates, SQUID with the
  // 5 cm gate (the default 0.4 m σ gate accepts far SQUID fixes up to ~0.9 m
  // off). The MC target is missed on the held-out AUV
  // fluxgate passes (documented): there only the measured figure is held.
  EXPECT_LE(fluxgate ? ted_egt.max : abs.max, fluxgate ? 1.7 : 0.13) << what;
  if (doc.mc_meets_paper) {
    EXPECT_LE(mc_worst_rms, fluxgate ? 0.7 : 0.4) << what;
  }
  ExpectCountFigure(ted_egt.count, doc.ted_egt_count, what + " TED+EGT fixes");
  if (doc.ted_egt_count > 0) ExpectErrorFigure(ted_egt.max, doc.ted_egt_max, what + " TED+EGT max");
  ExpectCountFigure(abs.count, doc.abs_count, what + " TED+EGT fixes, 5 cm gate");
  if (doc.abs_count > 0) ExpectErrorFigure(abs.max, doc.abs_max, what + " TED+EGT max, 5 cm gate");
  ExpectErrorFigure(mc_worst_rms, doc.mc_worst_rms, what + " MC worst RMS of seeds 1-5");
  ExpectCountFigure(min_count, doc.mc_fewest, what + " MC epochs with an estimate", 1.1);
}

TEST(HeldOut, InverterAndMonteCarloOnSimulatedPasses) {
  const auto passes = magnav::testing::HeldOutPasses();
  // Measured, per pass: SQUID, fluxgate.
  const HeldOutFigures doc[3][2] = {
      {{1351, 0.5795, 865, 0.0981, 0.035, 585, true}, {139, 0.6751, 0, 0.0, 1.023, 347, false}},
      {{1395, 0.9007, 895, 0.0842, 0.056, 591, true}, {161, 0.8067, 40, 0.1219, 0.794, 370, false}},
      {{2001, 0.0947, 2001, 0.0947, 0.061, 567, true}, {499, 0.7399, 300, 0.0975, 0.089, 567, true}},
  };
  ASSERT_EQ(passes.size(), 3u);
  for (std::size_t k = 0; k < passes.size(); ++k) {
    for (const bool fluxgate : {false, true}) {
      const std::string what = passes[k].name + (fluxgate ? ", fluxgate" : ", SQUID");
      const PassScenario sc = fluxgate ? magnav::testing::HeldOutScenario(passes[k], magnav::testing::kFluxgateSigmaB,
                                                                           magnav::testing::kFluxgateSigmaT)
                                       : magnav::testing::HeldOutScenario(passes[k], magnav::testing::kSquidSigmaB,
                                                                           magnav::testing::kSquidSigmaT);
      RunHeldOutPass(sc, fluxgate, doc[k][fluxgate], what);
    }
  }
}

// Fluxgate passes built with the simulator at closest approaches a few
// metres beyond the reference ones (AUV 6.4 m, ship 12.1 m), other moments,
// headings, speeds, turns and seeds (written for the former relative 1.5 %
// gate, kept for the 0.4 m σ gate that replaced it). The 5 cm gate accepts no
// fix on any of them; the default accepts fixes whose errors stay within
// 4 × 0.4 m (errors are ≤ ~4 σ) and within the paper's fluxgate 1.7 m. The
// far ship pass (30 m, 3 m/s) keeps 2 fixes (46 with the former relative
// gate, whose σ limit there was 0.45 m): the price of the absolute gate.
TEST(HeldOut, DefaultGatesOnFartherFluxgatePasses) {
  struct Farther {
    magnav::testing::HeldOutPass pass;
    double closest_3d_m;
    double speed_mps;
    int count;  // measured with the default gates
    double max, max_rel;
  };
  const Farther farther[] = {
      {{"auv-like, 7.5 m", {1500.0, -400.0, 1000.0}, -2.0, 0.0, -0.02, 101}, 7.5, 1.0, 128, 0.487, 0.052},
      {{"auv-like, 8 m, 2 m/s", {2500.0, 500.0, -600.0}, 1.0, 0.0, 0.03, 301}, 8.0, 2.0, 71, 0.511, 0.049},
      {{"ship-like, 25 m", {300000.0, -80000.0, 150000.0}, 2.5, 0.0, 0.02, 201}, 25.0, 1.0, 267, 0.746, 0.027},
      {{"ship-like, 30 m, 3 m/s", {400000.0, 100000.0, -250000.0}, -1.0, 0.0, -0.01, 401}, 30.0, 3.0, 2, 0.431,
       0.014},
  };
  const double sigma_limit = GateOptions{}.max_position_sigma_3d_m;
  for (const Farther& f : farther) {
    magnav::testing::HeldOutPass hp = f.pass;
    hp.closest_m = std::sqrt(f.closest_3d_m * f.closest_3d_m - 25.0);  // 5 m above the sensor plane
    PassScenario sc =
        magnav::testing::HeldOutScenario(hp, magnav::testing::kFluxgateSigmaB, magnav::testing::kFluxgateSigmaT);
    // The same closest approach at t = 75 s, at this speed.
    const Vec3 v(std::cos(hp.heading_rad), std::sin(hp.heading_rad), 0.0);
    sc.start_position += 75.0 * (sc.speed_mps - f.speed_mps) * v;
    sc.speed_mps = f.speed_mps;
    const SimulatedPass pass = SimulatePass(sc);
    const TruthTrack truth = magnav::testing::TruthOf(pass);
    double closest = 1e9;
    for (std::size_t i = 0; i < pass.samples.size(); ++i) {
      closest = std::min(closest, (truth.p[i] - pass.samples[i].p_SinW).norm());
    }
    InverterOptions defaults;
    defaults.B0_W = sc.B0;
    const testing::RangeErrors r = testing::RunInverterWithRange(pass.samples, truth, defaults);
    const ErrorStats& st = r.err;
    const double max_rel = r.max_relative;
    const ErrorStats former = testing::RunInverter(pass.samples, truth, testing::SigmaGateOptions(sc.B0, 0.0, 0.05));
    std::printf("| %s (closest %.2f m) | 5 cm gate: %d fixes | default: %d fixes, RMS %.4f, max %.4f, max |e|/range "
                "%.4f |\n",
                f.pass.name.c_str(), closest, former.count, st.count, st.rms(), st.max, max_rel);
    EXPECT_NEAR(closest, f.closest_3d_m, 0.05) << f.pass.name;
    EXPECT_EQ(former.count, 0) << f.pass.name;  // the failure of the former default
    ExpectCountFigure(st.count, f.count, f.pass.name + " fixes, default gates");
    ExpectErrorFigure(st.max, f.max, f.pass.name + " max error, default gates");
    ExpectErrorFigure(max_rel, f.max_rel, f.pass.name + " max |error| / range, default gates");
    EXPECT_LE(st.max, 4.0 * sigma_limit) << f.pass.name;
    EXPECT_LE(st.max, 1.7) << f.pass.name;
  }
}

// The paper's fluxgate figure on the reference AUV pass: at least 20
// accepted fixes, max error ≤ 1.7 m (the 5 cm gate, for comparison, kept 39;
// the relative 1.5 % gate 93, max 0.14 m; docs/ACCURACY.md).
TEST(HeldOut, ReferenceAuvFluxgateKeepsThePaperFigure) {
  const GradiometerFile file =
      ReadGradiometerFile(magnav::testing::ReferencePath("track_pass_auv_1sensor_fluxgate.csv"));
  const TruthTrack truth = magnav::testing::LoadTruthTrack("auv");
  const ErrorStats st = testing::RunInverter(file.samples, truth, *file.B0, Method::kTedEgt);
  std::printf("reference auv fluxgate, default gates: %d fixes, RMS %.4f, max %.4f\n", st.count, st.rms(), st.max);
  EXPECT_GE(st.count, 20);
  EXPECT_LE(st.max, 1.7);
  ExpectCountFigure(st.count, 156, "reference auv fluxgate fixes");
  ExpectErrorFigure(st.max, 0.7289, "reference auv fluxgate max");
}

}  // namespace
}  // namespace magnav::inversion
