// The held-out two-vessel field the tracker tests share: two AUV-sized
// vessels cross a 3x3 gradiometer grid (40 m spacing) at the same time,
// 50-60 m apart, one northwards and one westwards, fluxgate noise. The
// multi-tracker's management defaults were chosen on the reference field,
// not on this one.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "magnav/core/simulate.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::testing {

inline FieldScenario TwoVesselScenario() {
  FieldScenario sc;
  sc.sensors = SensorGrid(3, 3, 40.0);
  FieldVessel a;
  a.vessel_id = 1;
  a.moment_body = {2500.0, 300.0, 900.0};
  a.start_position = {-100.0, 38.0, -5.0};
  a.start_heading_rad = 0.0;  // north, along x
  a.speed_mps = 1.5;
  a.segments = {{140.0, 0.0}};
  FieldVessel b;
  b.vessel_id = 2;
  b.moment_body = {1800.0, -500.0, 700.0};
  b.start_position = {38.0, 100.0, -6.0};
  b.start_heading_rad = -M_PI / 2;  // west, along -y
  b.speed_mps = 1.2;
  b.segments = {{140.0, 0.0}};
  sc.vessels = {a, b};
  sc.sigma_B = 1e-9;
  sc.sigma_T = 1.4e-9;
  sc.seed = 11;
  return sc;
}

// (track_id, estimate) rows of a run.
using TrackRows = std::vector<std::pair<std::uint32_t, tracker::EpochEstimate>>;

// The usable estimates of a batch solve.
inline TrackRows BatchRows(const std::vector<tracker::MultiTrackEstimate>& tracks) {
  TrackRows rows;
  for (const auto& t : tracks) {
    for (const auto& e : t.track.epochs) {
      if (e.usable) rows.emplace_back(t.track_id, e);
    }
  }
  return rows;
}

// Every estimate of a window tracker fed `samples` (then flushed).
inline TrackRows WindowRows(tracker::MultiTracker* tracker, const std::vector<GradiometerSample>& samples) {
  TrackRows rows;
  const auto take = [&](const std::vector<tracker::TrackOutput>& out) {
    for (const auto& o : out) rows.emplace_back(o.track_id, o.estimate);
  };
  for (const auto& s : samples) take(tracker->AddSample(s));
  take(tracker->Flush());
  return rows;
}

// Scores of a multi-track output against a simulated field's truth (not the
// tracker's helpers): each row goes to the nearest vessel present at its
// instant (3-D) or, farther than 5 m from every one, counts as false;
// coverage is over the instants a vessel is within 15 m horizontally of a
// sensor (the rule), RMS over the rows there.
struct FieldScores {
  std::size_t rows = 0, false_rows = 0;
  std::vector<double> coverage, rms;  // per vessel (scenario order)
  std::vector<std::size_t> ids;       // distinct track ids per vessel
  std::vector<std::map<std::uint32_t, int>> rows_by_id;  // per vessel: rows of each track id
};

inline FieldScores ScoreField(const FieldScenario& sc, const SimulatedField& f,
                              const TrackRows& rows) {
  FieldScores s;
  const std::size_t nv = f.truth.size();
  const auto key = [&](double t) { return static_cast<long long>(std::llround(t * sc.rate_hz)); };
  std::vector<std::map<long long, const VesselTruth*>> at(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    for (const auto& t : f.truth[v]) at[v][key(t.t_s)] = &t;
  }
  const auto in_field = [&](const Eigen::Vector3d& p) {
    for (const auto& q : sc.sensors) {
      if ((p - q).head<2>().norm() <= 15.0) return true;
    }
    return false;
  };
  std::vector<std::map<long long, bool>> covered(nv);
  std::vector<double> sum_sq(nv, 0.0);
  std::vector<std::size_t> n(nv, 0);
  s.rows_by_id.resize(nv);
  for (const auto& [id, e] : rows) {
    ++s.rows;
    const long long k = key(e.t_s);
    std::size_t best_v = nv;
    double best = 5.0;
    for (std::size_t v = 0; v < nv; ++v) {
      const auto it = at[v].find(k);
      if (it == at[v].end()) continue;
      const double d = (e.p_VinW - it->second->p_VinW).norm();
      if (d <= best) {
        best = d;
        best_v = v;
      }
    }
    if (best_v == nv) {
      ++s.false_rows;
      continue;
    }
    ++s.rows_by_id[best_v][id];
    if (!in_field(at[best_v][k]->p_VinW)) continue;
    covered[best_v][k] = true;
    sum_sq[best_v] += best * best;
    ++n[best_v];
  }
  for (std::size_t v = 0; v < nv; ++v) {
    std::size_t instants = 0;
    for (const auto& t : f.truth[v]) instants += in_field(t.p_VinW) ? 1 : 0;
    s.coverage.push_back(instants > 0 ? static_cast<double>(covered[v].size()) / static_cast<double>(instants) : 0.0);
    s.rms.push_back(n[v] > 0 ? std::sqrt(sum_sq[v] / static_cast<double>(n[v])) : 1e300);
    s.ids.push_back(s.rows_by_id[v].size());
  }
  return s;
}

// One line per run: rows, false rows, and per vessel coverage, RMS (m; "-"
// without rows near it) and track ids.
inline void PrintFieldScores(const char* what, const FieldScores& s) {
  std::printf("%s: %zu rows, %zu false;", what, s.rows, s.false_rows);
  for (std::size_t v = 0; v < s.coverage.size(); ++v) {
    if (s.rms[v] < 1e299) {
      std::printf(" vessel %zu coverage %.3f RMS %.4f m ids %zu;", v + 1, s.coverage[v], s.rms[v], s.ids[v]);
    } else {
      std::printf(" vessel %zu coverage %.3f RMS - ids %zu;", v + 1, s.coverage[v], s.ids[v]);
    }
  }
  std::printf("\n");
}

}  // namespace magnav::testing
