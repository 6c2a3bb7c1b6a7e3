// Track passes of the reference data: accuracy of TED, TED+EGT, EGT (fixes
// passing the default gates) and of the Monte-Carlo tracker, against the
// truth tracks. Prints the tables of docs/ACCURACY.md ("Inverter").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/csv.h"
#include "magnav/core/frames.h"
#include "magnav/core/gradiometer.h"
#include "magnav/inversion/crlb.h"
#include "magnav/inversion/inverter.h"
#include "magnav/inversion/particle_filter.h"
#include "test_data.h"

namespace magnav::inversion {
namespace {

struct Truth {
  std::vector<double> t;
  std::vector<Vec3> p;  // vessel = dipole position, m
  std::vector<double> heading;
};

Truth LoadTruth(const std::string& vessel) {
  const CsvTable t = CsvTable::Read(magnav::testing::ReferencePath("track_truth_" + vessel + ".csv"));
  Truth out;
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    out.t.push_back(t.number(i, t.column("t")));
    out.p.emplace_back(t.number(i, t.column("x")), t.number(i, t.column("y")), t.number(i, t.column("z")));
    out.heading.push_back(t.number(i, t.column("heading")));
  }
  return out;
}

struct Stats {
  int count = 0;
  double sum_sq = 0.0, max = 0.0;
  void Add(double e) {
    ++count;
    sum_sq += e * e;
    max = std::max(max, e);
  }
  double rms() const { return count ? std::sqrt(sum_sq / count) : std::nan(""); }
};

struct PassResult {
  Stats ted, ted_egt, egt, mc;
  int mc_epochs = 0;  // epochs within 30 m horizontal range
  std::vector<double> mc_seed_rms;
  double mc_worst_seed_rms = 0.0;
  double crlb = 0.0;
};

constexpr double kMcHorizontalRange = 30.0;  // m, MC evaluation window

PassResult RunPass(const std::string& vessel, const std::string& sensor) {
  const std::string name = "track_pass_" + vessel + "_1sensor_" + sensor + ".csv";
  const GradiometerFile file = ReadGradiometerFile(magnav::testing::ReferencePath(name));
  const Truth truth = LoadTruth(vessel);
  EXPECT_EQ(file.samples.size(), truth.t.size());
  PassResult r;
  auto run = [&](Method method, Stats* st) {
    InverterOptions o;
    o.method = method;
    o.B0_W = *file.B0;
    Inverter inv(o);
    for (std::size_t i = 0; i < file.samples.size(); ++i) {
      const DipoleFix f = inv.Process(file.samples[i]);
      if (f.valid) st->Add((f.p_DinW - truth.p[i]).norm());
    }
  };
  run(Method::kTed, &r.ted);
  run(Method::kTedEgt, &r.ted_egt);
  run(Method::kEgt, &r.egt);

  auto run_mc = [&](std::uint64_t seed, Stats* st, int* epochs) {
    MonteCarloTrackerOptions mc;
    mc.filter.moment_body_Am2 = *file.moment_body;
    mc.filter.seed = seed;
    mc.init_inverter.B0_W = *file.B0;
    MonteCarloTracker tracker(mc);
    for (std::size_t i = 0; i < file.samples.size(); ++i) {
      const DipoleFix f = tracker.Process(file.samples[i]);
      const Vec3 d = truth.p[i] - file.samples[i].p_SinW;
      if (std::hypot(d.x(), d.y()) > kMcHorizontalRange) continue;
      ++*epochs;
      if (f.valid) st->Add((f.p_DinW - truth.p[i]).norm());
    }
  };
  run_mc(ParticleFilterOptions{}.seed, &r.mc, &r.mc_epochs);
  // The filter is random: also run seeds 1..5 and keep the worst RMS.
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    Stats st;
    int epochs = 0;
    run_mc(seed, &st, &epochs);
    r.mc_seed_rms.push_back(st.rms());
    r.mc_worst_seed_rms = std::max(r.mc_worst_seed_rms, st.rms());
  }

  // CRLB at the closest approach (unknown moment, one sample).
  std::size_t closest = 0;
  for (std::size_t i = 0; i < truth.p.size(); ++i) {
    if ((truth.p[i] - file.samples[i].p_SinW).norm() < (truth.p[closest] - file.samples[closest].p_SinW).norm()) {
      closest = i;
    }
  }
  const Vec3 m_W = WorldMoment(*file.moment_body, truth.heading[closest]);
  r.crlb = PositionCrlb(file.samples[closest].p_SinW - truth.p[closest], m_W, *file.sigma_B, *file.sigma_T);

  std::printf("| %s %s | TED | %d | %.4f | %.4f |\n", vessel.c_str(), sensor.c_str(), r.ted.count, r.ted.rms(),
              r.ted.max);
  std::printf("| %s %s | TED+EGT | %d | %.4f | %.4f |\n", vessel.c_str(), sensor.c_str(), r.ted_egt.count,
              r.ted_egt.rms(), r.ted_egt.max);
  std::printf("| %s %s | EGT | %d | %.4f | %.4f |\n", vessel.c_str(), sensor.c_str(), r.egt.count, r.egt.rms(),
              r.egt.max);
  std::printf("| %s %s | MC (≤ 30 m horiz.) | %d of %d | %.4f | %.4f |\n", vessel.c_str(), sensor.c_str(),
              r.mc.count, r.mc_epochs, r.mc.rms(), r.mc.max);
  std::printf("| %s %s | MC RMS, seeds 1-5 | | %.4f %.4f %.4f %.4f %.4f | |\n", vessel.c_str(), sensor.c_str(),
              r.mc_seed_rms[0], r.mc_seed_rms[1], r.mc_seed_rms[2], r.mc_seed_rms[3], r.mc_seed_rms[4]);
  std::printf("| %s %s | CRLB at closest approach (t = %.1f s, %.2f m) | | %.3g | |\n", vessel.c_str(),
              sensor.c_str(), truth.t[closest], (truth.p[closest] - file.samples[closest].p_SinW).norm(), r.crlb);
  return r;
}

// Four gradiometers on a 40 m square (fluxgate): per sensor, TED+EGT fixes
// passing the default gates and one MC filter per sensor (epochs within 30 m
// horizontally of that sensor). Returns the worst TED+EGT max error.
double RunFourSensors(const std::string& vessel) {
  const std::string name = "track_pass_" + vessel + "_4sensor_fluxgate.csv";
  const GradiometerFile file = ReadGradiometerFile(magnav::testing::ReferencePath(name));
  const Truth truth = LoadTruth(vessel);
  EXPECT_EQ(file.samples.size(), 4 * truth.t.size());
  InverterOptions o;
  o.B0_W = *file.B0;
  Inverter inv(o);
  MonteCarloTrackerOptions mc;
  mc.filter.moment_body_Am2 = *file.moment_body;
  mc.init_inverter.B0_W = *file.B0;
  MonteCarloTracker tracker(mc);  // rows are in time order, one filter per sensor_id
  Stats ted_egt[4], mc_stats[4];
  int epochs[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < file.samples.size(); ++i) {
    const GradiometerSample& s = file.samples[i];
    const std::size_t k = i / 4;  // rows ordered by t, then sensor_id
    EXPECT_EQ(s.t_s, truth.t[k]);
    const DipoleFix a = inv.Process(s);
    if (a.valid) ted_egt[s.sensor_id].Add((a.p_DinW - truth.p[k]).norm());
    const DipoleFix f = tracker.Process(s);
    const Vec3 d = truth.p[k] - s.p_SinW;
    if (std::hypot(d.x(), d.y()) > kMcHorizontalRange) continue;
    ++epochs[s.sensor_id];
    if (f.valid) mc_stats[s.sensor_id].Add((f.p_DinW - truth.p[k]).norm());
  }
  double worst = 0.0;
  for (int j = 0; j < 4; ++j) {
    std::printf("| %s 4sensor fluxgate, sensor %d | TED+EGT %d fixes, RMS %.4f, max %.4f | MC %d of %d, RMS %.4f, max %.4f |\n",
                vessel.c_str(), j, ted_egt[j].count, ted_egt[j].rms(), ted_egt[j].max, mc_stats[j].count, epochs[j],
                mc_stats[j].rms(), mc_stats[j].max);
    worst = std::max(worst, ted_egt[j].max);
  }
  return worst;
}

TEST(TrackPass, FourSensorsFluxgate) {
  EXPECT_LE(RunFourSensors("auv"), 1.7);
  EXPECT_LE(RunFourSensors("ship"), 1.7);
}

// The 20-seed spread of docs/ACCURACY.md (~4 s): the MC targets must hold
// for every seed, not just the default one.
TEST(TrackPass, McTwentySeeds) {
  for (const char* vessel : {"auv", "ship"}) {
    for (const char* sensor : {"squid", "fluxgate"}) {
      const std::string name = std::string("track_pass_") + vessel + "_1sensor_" + sensor + ".csv";
      const GradiometerFile file = ReadGradiometerFile(magnav::testing::ReferencePath(name));
      const Truth truth = LoadTruth(vessel);
      std::vector<double> rms;
      for (std::uint64_t seed = 1; seed <= 20; ++seed) {
        MonteCarloTrackerOptions mc;
        mc.filter.moment_body_Am2 = *file.moment_body;
        mc.filter.seed = seed;
        mc.init_inverter.B0_W = *file.B0;
        MonteCarloTracker tracker(mc);
        Stats st;
        for (std::size_t i = 0; i < file.samples.size(); ++i) {
          const DipoleFix f = tracker.Process(file.samples[i]);
          const Vec3 d = truth.p[i] - file.samples[i].p_SinW;
          if (std::hypot(d.x(), d.y()) <= kMcHorizontalRange && f.valid) st.Add((f.p_DinW - truth.p[i]).norm());
        }
        rms.push_back(st.rms());
      }
      std::sort(rms.begin(), rms.end());
      double mean = 0.0;
      for (double r : rms) mean += r / 20.0;
      std::printf("| %s %s | MC RMS over seeds 1-20: mean %.3f median %.3f p90 %.3f max %.3f |\n", vessel, sensor,
                  mean, 0.5 * (rms[9] + rms[10]), rms[17], rms[19]);
      EXPECT_LE(rms[19], std::string(sensor) == "squid" ? 0.4 : 0.7);
    }
  }
}

TEST(TrackPass, AuvSquid) {
  const PassResult r = RunPass("auv", "squid");
  EXPECT_GT(r.ted_egt.count, 100);
  EXPECT_LE(r.ted_egt.max, 0.13);  // paper: TED+EGT max 0.13 m with SQUIDs
  EXPECT_LE(r.mc.rms(), 0.4);      // paper: MC RMS 0.4 m with SQUIDs
  EXPECT_LE(r.mc_worst_seed_rms, 0.4);
}

TEST(TrackPass, ShipSquid) {
  const PassResult r = RunPass("ship", "squid");
  EXPECT_GT(r.ted_egt.count, 100);
  EXPECT_LE(r.ted_egt.max, 0.13);
  EXPECT_LE(r.mc.rms(), 0.4);
  EXPECT_LE(r.mc_worst_seed_rms, 0.4);
}

TEST(TrackPass, AuvFluxgate) {
  const PassResult r = RunPass("auv", "fluxgate");
  EXPECT_GT(r.ted_egt.count, 10);
  EXPECT_LE(r.ted_egt.max, 1.7);  // paper: TED+EGT max 1.7 m with fluxgates
  EXPECT_LE(r.mc.rms(), 0.7);     // paper: MC RMS 0.7 m with fluxgates
  EXPECT_LE(r.mc_worst_seed_rms, 0.7);
}

TEST(TrackPass, ShipFluxgate) {
  const PassResult r = RunPass("ship", "fluxgate");
  EXPECT_GT(r.ted_egt.count, 10);
  EXPECT_LE(r.ted_egt.max, 1.7);
  EXPECT_LE(r.mc.rms(), 0.7);
  EXPECT_LE(r.mc_worst_seed_rms, 0.7);
}

}  // namespace
}  // namespace magnav::inversion
