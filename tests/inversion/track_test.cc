// Track passes of the reference data: accuracy of TED, TED+EGT, EGT (fixes
// passing the default gates; the uncertainty gate relative to range) and of
// the Monte-Carlo tracker, against the
// truth tracks. Prints the tables of docs/ACCURACY.md ("Inverter") and
// asserts every figure there: an error may grow by at most kFigureMargin
// (1.5×), a count or coverage may shrink by at most that factor (MC coverage:
// 10 %), so a 2× regression of any figure fails. The paper's targets are
// asserted as well.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/frames.h"
#include "magnav/core/gradiometer.h"
#include "magnav/inversion/crlb.h"
#include "magnav/inversion/inverter.h"
#include "magnav/inversion/particle_filter.h"
#include "reference_truth.h"
#include "test_data.h"
#include "track_runs.h"

namespace magnav::inversion {
namespace {

using magnav::testing::ErrorStats;
using magnav::testing::ExpectCountFigure;
using magnav::testing::ExpectErrorFigure;
using magnav::testing::TruthTrack;

using testing::kMcHorizontalRange;
using testing::McRun;

// MC coverage (epochs with an estimate / epochs in the window) is set by when
// the first gated fixes arrive, not by the random draws: 10 % margin.
constexpr double kCoverageMargin = 1.1;

// One documented row of the track-pass table: accepted fixes, RMS, max.
struct MethodFigure {
  int count;
  double rms, max;
};

void ExpectMethodFigure(const ErrorStats& st, const MethodFigure& doc, const std::string& what) {
  ExpectCountFigure(st.count, doc.count, what + " accepted");
  if (doc.count == 0) return;
  ExpectErrorFigure(st.rms(), doc.rms, what + " RMS");
  ExpectErrorFigure(st.max, doc.max, what + " max");
}

McRun RunMc(const GradiometerFile& file, const TruthTrack& truth, std::uint64_t seed) {
  return testing::RunMonteCarlo(file.samples, truth, *file.B0, *file.moment_body, seed);
}

ErrorStats RunInverter(const GradiometerFile& file, const TruthTrack& truth, Method method) {
  return testing::RunInverter(file.samples, truth, *file.B0, method);
}

// TED+EGT with the uncertainty gates set: relative to range (`relative`) and
// absolute (`absolute`, m); 0 = off.
ErrorStats RunSigmaGates(const GradiometerFile& file, const TruthTrack& truth, double relative, double absolute) {
  return testing::RunInverter(file.samples, truth, testing::SigmaGateOptions(*file.B0, relative, absolute));
}

// The documented figures of one 1-sensor pass (docs/ACCURACY.md, "Track passes").
struct PassFigures {
  const char* vessel;
  const char* sensor;
  MethodFigure ted, ted_egt, egt;
  int mc_count, mc_epochs;
  double mc_rms, mc_max;
  double mc_worst_seed_rms;  // seeds 1-5
  double crlb;               // m, at the closest approach
  double paper_ted_egt_max, paper_mc_rms;
};

void RunPass(const PassFigures& doc) {
  const std::string vessel = doc.vessel, sensor = doc.sensor, what = vessel + " " + sensor;
  const GradiometerFile file =
      ReadGradiometerFile(magnav::testing::ReferencePath("track_pass_" + vessel + "_1sensor_" + sensor + ".csv"));
  const TruthTrack truth = magnav::testing::LoadTruthTrack(vessel);
  ASSERT_EQ(file.samples.size(), truth.t.size());
  const ErrorStats ted = RunInverter(file, truth, Method::kTed);
  const ErrorStats ted_egt = RunInverter(file, truth, Method::kTedEgt);
  const ErrorStats egt = RunInverter(file, truth, Method::kEgt);
  const McRun mc = RunMc(file, truth, ParticleFilterOptions{}.seed);
  // The filter is random: also run seeds 1..5 and keep the worst RMS.
  std::vector<double> seed_rms;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) seed_rms.push_back(RunMc(file, truth, seed).err.rms());
  const double worst_seed_rms = *std::max_element(seed_rms.begin(), seed_rms.end());

  // CRLB at the closest approach (unknown moment, one sample).
  std::size_t closest = 0;
  for (std::size_t i = 0; i < truth.p.size(); ++i) {
    if ((truth.p[i] - file.samples[i].p_SinW).norm() < (truth.p[closest] - file.samples[closest].p_SinW).norm()) {
      closest = i;
    }
  }
  const Vec3 m_W = WorldMoment(*file.moment_body, truth.heading[closest]);
  const double crlb =
      PositionCrlb(file.samples[closest].p_SinW - truth.p[closest], m_W, *file.sigma_B, *file.sigma_T);

  const char* v = doc.vessel;
  const char* s = doc.sensor;
  std::printf("| %s %s | TED | %d | %.4f | %.4f |\n", v, s, ted.count, ted.rms(), ted.max);
  std::printf("| %s %s | TED+EGT | %d | %.4f | %.4f |\n", v, s, ted_egt.count, ted_egt.rms(), ted_egt.max);
  std::printf("| %s %s | EGT | %d | %.4f | %.4f |\n", v, s, egt.count, egt.rms(), egt.max);
  std::printf("| %s %s | MC | %d of %d | %.4f | %.4f |\n", v, s, mc.err.count, mc.epochs, mc.err.rms(), mc.err.max);
  std::printf("| %s %s | MC RMS, seeds 1–5 | | %.3f %.3f %.3f %.3f %.3f | |\n", v, s, seed_rms[0], seed_rms[1],
              seed_rms[2], seed_rms[3], seed_rms[4]);
  std::printf("| %s %s | CRLB at closest approach (t = %.1f s, %.2f m) | | %.3g | |\n", v, s, truth.t[closest],
              (truth.p[closest] - file.samples[closest].p_SinW).norm(), crlb);

  ExpectMethodFigure(ted, doc.ted, what + " TED");
  ExpectMethodFigure(ted_egt, doc.ted_egt, what + " TED+EGT");
  ExpectMethodFigure(egt, doc.egt, what + " EGT");
  EXPECT_EQ(mc.epochs, doc.mc_epochs) << what;
  ExpectCountFigure(mc.err.count, doc.mc_count, what + " MC epochs with an estimate", kCoverageMargin);
  ExpectErrorFigure(mc.err.rms(), doc.mc_rms, what + " MC RMS");
  ExpectErrorFigure(mc.err.max, doc.mc_max, what + " MC max");
  ExpectErrorFigure(worst_seed_rms, doc.mc_worst_seed_rms, what + " MC worst RMS of seeds 1-5");
  // A closed form: to its printed precision.
  EXPECT_NEAR(crlb, doc.crlb, 0.05 * doc.crlb) << what;
  // The paper's targets (Table 2). TED+EGT max: fluxgate with the default
  // gates (the AUV's ≥ 20 fixes: heldout_test); SQUID with the absolute 5 cm gate,
  // the paper's per-fix accuracy: the default 0.4 m σ gate also accepts far
  // SQUID fixes, up to 0.75 m off (docs/ACCURACY.md, "Default gates off the
  // tuning set").
  if (sensor == "fluxgate") {
    EXPECT_LE(ted_egt.max, doc.paper_ted_egt_max) << what;
  } else {
    EXPECT_LE(RunSigmaGates(file, truth, 0.0, 0.05).max, doc.paper_ted_egt_max) << what << ", 5 cm gate";
  }
  EXPECT_LE(mc.err.rms(), doc.paper_mc_rms) << what;
  EXPECT_LE(worst_seed_rms, doc.paper_mc_rms) << what;
}

// Paper (Table 2): TED+EGT max 0.13 m SQUID / 1.7 m fluxgate; MC RMS 0.4 / 0.7 m.
constexpr PassFigures kAuvSquid{"auv", "squid", {1441, 0.1280, 0.8103}, {1425, 0.1179, 0.7506}, {1372, 0.1593, 1.3102},
                                608, 608, 0.0408, 0.0948, 0.033, 2.6e-6, 0.13, 0.4};
constexpr PassFigures kShipSquid{"ship", "squid", {1997, 0.0038, 0.0276}, {2001, 0.0043, 0.0345},
                                 {2001, 0.0075, 0.0537}, 514, 514, 0.0724, 0.1733, 0.092, 2.5e-7, 0.13, 0.4};
constexpr PassFigures kAuvFluxgate{"auv", "fluxgate", {130, 0.1965, 0.6101}, {156, 0.1722, 0.7289}, {147, 0.2425, 1.7057},
                                   385, 608, 0.3559, 1.1229, 0.407, 0.035, 1.7, 0.7};
constexpr PassFigures kShipFluxgate{"ship", "fluxgate", {522, 0.1296, 0.6431}, {512, 0.1329, 0.8105},
                                    {488, 0.1883, 1.1364}, 514, 514, 0.0672, 0.2030, 0.170, 0.0034, 1.7, 0.7};

TEST(TrackPass, AuvSquid) { RunPass(kAuvSquid); }
TEST(TrackPass, ShipSquid) { RunPass(kShipSquid); }
TEST(TrackPass, AuvFluxgate) { RunPass(kAuvFluxgate); }
TEST(TrackPass, ShipFluxgate) { RunPass(kShipFluxgate); }

// The documented figures of one sensor of a 4-sensor pass.
struct SensorFigures {
  MethodFigure ted_egt;
  int mc_count, mc_epochs;
  double mc_rms, mc_max;
};

// Four gradiometers on a 40 m square (fluxgate): per sensor, TED+EGT fixes
// passing the default gates and one MC filter per sensor (epochs within 30 m
// horizontally of that sensor). Every sensor is checked against its own row:
// a sensor that loses its fixes fails (it is not scored as "max error 0").
void RunFourSensors(const std::string& vessel, const SensorFigures (&doc)[4]) {
  const GradiometerFile file =
      ReadGradiometerFile(magnav::testing::ReferencePath("track_pass_" + vessel + "_4sensor_fluxgate.csv"));
  const TruthTrack truth = magnav::testing::LoadTruthTrack(vessel);
  ASSERT_EQ(file.samples.size(), 4 * truth.t.size());
  InverterOptions o;
  o.B0_W = *file.B0;
  Inverter inv(o);
  MonteCarloTrackerOptions mc;
  mc.filter.moment_body_Am2 = *file.moment_body;
  mc.init_inverter.B0_W = *file.B0;
  MonteCarloTracker tracker(mc);  // rows are in time order, one filter per sensor_id
  ErrorStats ted_egt[4], mc_stats[4];
  int epochs[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < file.samples.size(); ++i) {
    const GradiometerSample& s = file.samples[i];
    const std::size_t k = i / 4;  // rows ordered by t, then sensor_id
    ASSERT_EQ(s.t_s, truth.t[k]);
    const DipoleFix a = inv.Process(s);
    if (a.valid) ted_egt[s.sensor_id].Add((a.p_DinW - truth.p[k]).norm());
    const DipoleFix f = tracker.Process(s);
    const Vec3 d = truth.p[k] - s.p_SinW;
    if (std::hypot(d.x(), d.y()) > kMcHorizontalRange) continue;
    ++epochs[s.sensor_id];
    if (f.valid) mc_stats[s.sensor_id].Add((f.p_DinW - truth.p[k]).norm());
  }
  for (int j = 0; j < 4; ++j) {
    const std::string what = vessel + " 4-sensor, sensor " + std::to_string(j);
    std::printf("| %s, %d | %d | %.3f | %.3f | %d of %d | %.3f | %.3f |\n", vessel.c_str(), j, ted_egt[j].count,
                ted_egt[j].rms(), ted_egt[j].max, mc_stats[j].count, epochs[j], mc_stats[j].rms(), mc_stats[j].max);
    ExpectMethodFigure(ted_egt[j], doc[j].ted_egt, what + " TED+EGT");
    if (doc[j].ted_egt.count > 0) {
      EXPECT_LE(ted_egt[j].max, 1.7) << what;  // paper, fluxgate
    }
    EXPECT_EQ(epochs[j], doc[j].mc_epochs) << what;
    ExpectCountFigure(mc_stats[j].count, doc[j].mc_count, what + " MC epochs with an estimate", kCoverageMargin);
    if (doc[j].mc_count > 0) {
      ExpectErrorFigure(mc_stats[j].rms(), doc[j].mc_rms, what + " MC RMS");
      ExpectErrorFigure(mc_stats[j].max, doc[j].mc_max, what + " MC max");
    }
  }
}

TEST(TrackPass, FourSensorsFluxgate) {
  // Sensors without a row figure (0 fixes) are the documented gaps.
  const SensorFigures auv[4] = {{{185, 0.172, 0.728}, 393, 613, 0.514, 1.789},
                                {{0, 0, 0}, 0, 0, 0, 0},
                                {{181, 0.166, 0.672}, 383, 599, 0.581, 1.363},
                                {{0, 0, 0}, 0, 332, 0, 0}};
  const SensorFigures ship[4] = {{{633, 0.127, 0.673}, 633, 633, 0.160, 0.676},
                                 {{578, 0.145, 1.061}, 605, 605, 0.039, 0.113},
                                 {{0, 0, 0}, 0, 0, 0, 0},
                                 {{0, 0, 0}, 0, 0, 0, 0}};
  RunFourSensors("auv", auv);
  RunFourSensors("ship", ship);
}

// The 20-seed spread of docs/ACCURACY.md (~4 s): the MC targets must hold
// for every seed, not just the default one, and the spread's figures are
// asserted (mean, median, 90th percentile, worst; coverage per seed).
TEST(TrackPass, McTwentySeeds) {
  struct SpreadFigures {
    const char* vessel;
    const char* sensor;
    double mean, median, p90, max;
    int mc_count;
    double paper_mc_rms;
  };
  const SpreadFigures docs[] = {{"auv", "squid", 0.039, 0.040, 0.048, 0.049, 608, 0.4},
                                {"auv", "fluxgate", 0.310, 0.303, 0.390, 0.411, 385, 0.7},
                                {"ship", "squid", 0.064, 0.061, 0.075, 0.092, 514, 0.4},
                                {"ship", "fluxgate", 0.090, 0.076, 0.141, 0.175, 514, 0.7}};
  for (const SpreadFigures& doc : docs) {
    const std::string vessel = doc.vessel, sensor = doc.sensor, what = vessel + " " + sensor;
    const GradiometerFile file = ReadGradiometerFile(
        magnav::testing::ReferencePath("track_pass_" + vessel + "_1sensor_" + sensor + ".csv"));
    const TruthTrack truth = magnav::testing::LoadTruthTrack(vessel);
    std::vector<double> rms;
    int min_count = 1 << 30;
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
      const McRun r = RunMc(file, truth, seed);
      rms.push_back(r.err.rms());
      min_count = std::min(min_count, r.err.count);
    }
    std::sort(rms.begin(), rms.end());
    double mean = 0.0;
    for (double r : rms) mean += r / 20.0;
    const double median = 0.5 * (rms[9] + rms[10]);
    std::printf("| %s %s | MC RMS over seeds 1-20: mean %.3f median %.3f p90 %.3f max %.3f | fewest estimates %d |\n",
                doc.vessel, doc.sensor, mean, median, rms[17], rms[19], min_count);
    ExpectErrorFigure(mean, doc.mean, what + " 20-seed mean RMS");
    ExpectErrorFigure(median, doc.median, what + " 20-seed median RMS");
    ExpectErrorFigure(rms[17], doc.p90, what + " 20-seed p90 RMS");
    ExpectErrorFigure(rms[19], doc.max, what + " 20-seed worst RMS");
    ExpectCountFigure(min_count, doc.mc_count, what + " fewest epochs with an estimate", kCoverageMargin);
    EXPECT_LE(rms[19], doc.paper_mc_rms) << what;
  }
}

// The absolute predicted-σ gate sweep of docs/ACCURACY.md (TED+EGT, relative
// gate off, other gates at default): accepted / RMS / max per gate and pass;
// ∞ = gate off. 0.05 was the default before the relative gate.
TEST(TrackPass, PredictedSigmaGateSweep) {
  struct Row {
    double max_sigma;
    MethodFigure auv_squid, ship_squid, auv_fluxgate, ship_fluxgate;
  };
  const double inf = std::numeric_limits<double>::infinity();
  const Row rows[] = {
      {inf, {1741, 0.418, 3.935}, {2001, 0.0043, 0.035}, {148, 0.157, 0.635}, {648, 0.324, 1.452}},
      {0.5, {1492, 0.146, 1.097}, {2001, 0.0043, 0.035}, {146, 0.155, 0.635}, {540, 0.164, 1.002}},
      {0.2, {1222, 0.062, 0.519}, {2001, 0.0043, 0.035}, {122, 0.098, 0.343}, {427, 0.063, 0.263}},
      {0.1, {1048, 0.029, 0.178}, {2001, 0.0043, 0.035}, {85, 0.057, 0.140}, {358, 0.034, 0.149}},
      {0.05, {897, 0.015, 0.089}, {2001, 0.0043, 0.035}, {39, 0.046, 0.077}, {294, 0.020, 0.085}},
      {0.03, {798, 0.009, 0.054}, {2001, 0.0043, 0.035}, {0, 0, 0}, {252, 0.012, 0.043}},
  };
  const char* passes[4][2] = {{"auv", "squid"}, {"ship", "squid"}, {"auv", "fluxgate"}, {"ship", "fluxgate"}};
  for (int k = 0; k < 4; ++k) {
    const std::string vessel = passes[k][0], sensor = passes[k][1];
    const GradiometerFile file = ReadGradiometerFile(
        magnav::testing::ReferencePath("track_pass_" + vessel + "_1sensor_" + sensor + ".csv"));
    const TruthTrack truth = magnav::testing::LoadTruthTrack(vessel);
    for (const Row& row : rows) {
      const ErrorStats st = RunSigmaGates(file, truth, 0.0, row.max_sigma);
      const MethodFigure& doc = k == 0 ? row.auv_squid : k == 1 ? row.ship_squid : k == 2 ? row.auv_fluxgate
                                                                                          : row.ship_fluxgate;
      std::printf("| %g | %s %s | %d / %.4f / %.3f |\n", row.max_sigma, passes[k][0], passes[k][1], st.count,
                  st.rms(), st.max);
      ExpectMethodFigure(st, doc, vessel + " " + sensor + ", sigma gate " + std::to_string(row.max_sigma));
    }
  }
}

// The relative σ gate sweep of docs/ACCURACY.md ("Uncertainty gate"; TED+EGT,
// absolute gate off, SNR ≥ 100, other gates at default) on the data the former default was
// chosen on: accepted / RMS / max / max of |error| / range per ρ and pass;
// the 4-sensor passes pooled over their sensors. 0.015 is the largest ρ of
// the grid at which every fluxgate pass and sensor keeps the paper's 1.7 m
// (at 0.02 a ship 4-sensor fix is 1.9 m off); every cell is asserted.
TEST(TrackPass, RelativeSigmaGateSweep) {
  struct Cell {
    int count;
    double rms, max, max_rel;
  };
  struct Row {
    double rho;
    Cell cells[6];
  };
  const Row rows[] = {
      {0.0, {{1741, 0.418, 3.935, 0.039}, {2001, 0.0043, 0.034, 0.0003}, {148, 0.157, 0.635, 0.065},
             {648, 0.324, 1.452, 0.038}, {342, 0.137, 0.566, 0.058}, {1871, 0.423, 3.160, 0.078}}},
      {0.03, {{1738, 0.400, 3.935, 0.039}, {2001, 0.0043, 0.034, 0.0003}, {136, 0.126, 0.635, 0.065},
              {624, 0.284, 1.380, 0.038}, {332, 0.131, 0.566, 0.058}, {1822, 0.414, 2.975, 0.074}}},
      {0.02, {{1707, 0.296, 2.011, 0.023}, {2001, 0.0043, 0.034, 0.0003}, {113, 0.086, 0.343, 0.038},
              {577, 0.219, 1.500, 0.044}, {268, 0.067, 0.265, 0.032}, {1469, 0.264, 1.899, 0.055}}},
      {0.015, {{1681, 0.252, 2.011, 0.023}, {2001, 0.0043, 0.034, 0.0003}, {93, 0.060, 0.140, 0.019},
               {535, 0.157, 0.810, 0.028}, {236, 0.048, 0.194, 0.023}, {1252, 0.160, 1.303, 0.040}}},
      {0.01, {{1609, 0.204, 1.149, 0.016}, {2001, 0.0043, 0.034, 0.0003}, {65, 0.049, 0.080, 0.012},
              {466, 0.091, 0.482, 0.017}, {198, 0.031, 0.095, 0.013}, {1117, 0.099, 1.061, 0.040}}},
      {0.005, {{1361, 0.095, 0.560, 0.010}, {2001, 0.0043, 0.034, 0.0003}, {0, 0, 0, 0},
               {377, 0.040, 0.149, 0.007}, {125, 0.019, 0.042, 0.007}, {915, 0.037, 0.244, 0.013}}},
  };
  const char* passes[6][2] = {{"auv", "1sensor_squid"},    {"ship", "1sensor_squid"},
                              {"auv", "1sensor_fluxgate"}, {"ship", "1sensor_fluxgate"},
                              {"auv", "4sensor_fluxgate"}, {"ship", "4sensor_fluxgate"}};
  for (int k = 0; k < 6; ++k) {
    const std::string vessel = passes[k][0], kind = passes[k][1];
    const GradiometerFile file =
        ReadGradiometerFile(magnav::testing::ReferencePath("track_pass_" + vessel + "_" + kind + ".csv"));
    const TruthTrack truth = magnav::testing::LoadTruthTrack(vessel);
    const std::size_t per = file.samples.size() / truth.p.size();  // rows per instant (sensors)
    for (const Row& row : rows) {
      const testing::RangeErrors r = testing::RunInverterWithRange(
          file.samples, truth, testing::SigmaGateOptions(*file.B0, row.rho, 0.0), per);
      const ErrorStats& st = r.err;
      const double max_rel = r.max_relative;
      const Cell& doc = row.cells[k];
      const std::string what = vessel + " " + kind + ", relative gate " + std::to_string(row.rho);
      std::printf("| %g | %s %s | %d / %.4f / %.3f / %.4f |\n", row.rho, vessel.c_str(), kind.c_str(), st.count,
                  st.rms(), st.max, max_rel);
      ExpectMethodFigure(st, {doc.count, doc.rms, doc.max}, what);
      if (doc.count > 0) ExpectErrorFigure(max_rel, doc.max_rel, what + " max |error| / range");
      if (row.rho == 0.015 && kind.find("fluxgate") != std::string::npos) {  // the default 2026-11-25
        EXPECT_LE(st.max, 1.7) << what << ": the rule the default was chosen by";
      }
    }
  }
}

}  // namespace
}  // namespace magnav::inversion
