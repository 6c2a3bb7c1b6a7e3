#include "cluster_window.h"

#include <algorithm>
#include <set>

#include "magnav/core/checkpoint.h"
#include "state_io.h"

namespace magnav::tracker::internal {

WindowClusterBackground::WindowClusterBackground(const Eigen::Vector3d& B0_W, const MultiTrackerOptions& options)
    : B0_W_(B0_W), options_(options) {}

void WindowClusterBackground::AddRaw(const Epoch& raw) {
  if (!enabled()) return;
  raw_.push_back(raw);
  const double span = options_.track.window_s + options_.track.epoch_tolerance_s;
  while (raw.t_s - raw_.front().t_s > span) raw_.pop_front();
}

bool WindowClusterBackground::StepIfDue(double t_s, const std::vector<WindowTracker*>& engines) {
  if (!enabled()) return false;
  const TrackerOptions& topt = options_.track;
  if (t_s - last_step_t_ < topt.window_solve_interval_s - topt.epoch_tolerance_s) return false;
  last_step_t_ = t_s;
  std::vector<ClusterTrack> tracks;
  const double tol = topt.epoch_tolerance_s;
  for (WindowTracker* engine : engines) {
    if (!engine->initialized() || !engine->m_B_Am2().allFinite()) continue;
    auto view = std::make_shared<std::vector<WindowTracker::WindowEpochView>>(engine->WindowView());
    if (view->empty()) continue;
    ClusterTrack c;
    c.m_B_Am2 = engine->m_B_Am2();
    std::set<std::uint32_t> s;
    for (const auto& v : *view) s.insert(v.sensor_ids.begin(), v.sensor_ids.end());
    c.sensors.assign(s.begin(), s.end());
    const std::optional<CtState<double>> now = engine->PredictState(t_s);
    const double last = view->back().t_s;
    c.state_at = [view, now, t_s, last, tol](double t) -> std::optional<CtState<double>> {
      if (t > last + tol) {
        if (std::abs(t - t_s) <= tol) return now;
        return std::nullopt;
      }
      const auto it = std::lower_bound(view->begin(), view->end(), t - tol,
                                       [](const WindowTracker::WindowEpochView& v, double x) { return v.t_s < x; });
      if (it == view->end() || std::abs(it->t_s - t) > tol) return std::nullopt;
      return it->state;
    };
    tracks.push_back(std::move(c));
  }
  std::vector<const Epoch*> epochs;
  for (const Epoch& e : raw_) epochs.push_back(&e);
  const SensorOffsets previous = offsets_;
  offsets_.Clear();
  last_step_stats_ =
      EstimateClusterOffsets(epochs, tracks, B0_W_, topt, options_.cluster_background, &previous, &offsets_);
  const WindowTracker::BackgroundOffsetFn fn = Fn();
  for (WindowTracker* engine : engines) engine->SetBackgroundOffsets(fn);
  return true;
}

Epoch WindowClusterBackground::Corrected(const Epoch& raw) const {
  Epoch e = raw;
  if (!enabled()) return e;
  for (GradiometerSample& s : e.samples) s.B -= offsets_.At(s.sensor_id, e.t_s);
  return e;
}

void WindowClusterBackground::PutBack(Epoch* e) const {
  if (!enabled()) return;
  for (GradiometerSample& s : e->samples) s.B += offsets_.At(s.sensor_id, e->t_s);
}

WindowTracker::BackgroundOffsetFn WindowClusterBackground::Fn() const {
  if (!enabled()) return {};
  const SensorOffsets* o = &offsets_;
  return [o](std::uint32_t sensor_id, double t_s) { return o->At(sensor_id, t_s); };
}

void WindowClusterBackground::SaveState(StateWriter& w) const {
  PutDeque(w, raw_);
  offsets_.SaveState(w);
  w.F64(last_step_t_);
}

void WindowClusterBackground::RestoreState(StateReader& r) {
  GetDeque(r, &raw_);
  offsets_.RestoreState(r);
  last_step_t_ = r.F64();
}

}  // namespace magnav::tracker::internal
