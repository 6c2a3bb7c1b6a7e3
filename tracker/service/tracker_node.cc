#include "tracker_node.h"

#include <chrono>
#include <cmath>

#include <spdlog/spdlog.h>

#include "magnav/core/error.h"
#include "magnav/core/units.h"
#include "magnav/dds/convert.h"
#include "magnav/tracker/initialize.h"

namespace magnav::tracker {

bool TrackerNodeOptions::IsValid(std::string* error) const {
  if (!merge.IsValid(error)) return false;
  if (!std::isfinite(merge.reorder_delay_s)) {
    if (error) *error = "reorder_delay_s must be finite";
    return false;
  }
  return tracker.IsValid(error);
}

dds::msg::TrackEstimate ToMsg(const EpochEstimate& e, const Eigen::Vector3d& m_B, const Eigen::Matrix3d& cov_m_B,
                              std::uint32_t track_id) {
  dds::msg::TrackEstimate m;
  m.track_id(track_id);
  m.stamp_ns(SecondsToNanos(e.t_s));
  m.position({e.p_VinW.x(), e.p_VinW.y(), e.p_VinW.z()});
  const Eigen::Vector3d v = e.v_VinW();
  m.velocity({v.x(), v.y(), v.z()});
  m.heading(e.heading_rad);
  m.turn_rate(e.turn_rate_radps);
  std::array<double, 9> cov{}, cov_m{};
  m.usable(e.usable);
  if (e.usable && e.has_covariance) {
    for (int k = 0; k < 9; ++k) cov[k] = e.cov_state(k / 3, k % 3);
  }
  for (int k = 0; k < 9; ++k) cov_m[k] = cov_m_B(k / 3, k % 3);
  m.covariance(cov);
  m.moment_body({m_B.x(), m_B.y(), m_B.z()});
  m.moment_covariance(cov_m);
  m.num_sensors(static_cast<std::uint32_t>(e.num_samples));
  return m;
}

DipoleFix FromMsg(const dds::msg::DipoleFix& m) {
  return MakeFix(NanosToSeconds(m.stamp_ns()), m.sensor_id(), {m.position()[0], m.position()[1], m.position()[2]},
                 m.valid());
}

namespace {
double WallClock_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

const TrackerNodeOptions& Checked(const TrackerNodeOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("tracker options: " + err);
  return o;
}
}  // namespace

TrackerNode::TrackerNode(dds::Node& node, const TrackerNodeOptions& options,
                         std::unique_ptr<dds::RegionalFieldSource> b0)
    : options_(Checked(options)),
      b0_(std::move(b0)),
      tracker_(Eigen::Vector3d::Zero(), options.tracker),
      merge_(options.merge) {
  repeats_.SetLogName("magnav-tracker: magnav/gradiometer sensor");
  // Acknowledgments after every 5 estimates (below the history depth of 10
  // per track), waiting at most 2 s for a reader (a dead one is forgotten
  // after the 3 s lease).
  writer_ = std::make_unique<dds::QueuedWriter<dds::msg::TrackEstimate>>(node.CreateWriter<dds::msg::TrackEstimate>(),
                                                                        5, std::chrono::seconds(2));
  if (options_.tracker.track.init.source != InitSource::kSamples) {
    fix_reader_ =
        node.CreateReader<dds::msg::DipoleFix>([this](const dds::msg::DipoleFix& m, const auto& info) { OnFix(m, info); });
  }
  reader_ = node.CreateReader<dds::msg::GradiometerSample>(
      [this](const dds::msg::GradiometerSample& m, const auto& info) { OnSample(m, info); });
}

void TrackerNode::OnFix(const dds::msg::DipoleFix& m, const dds::fdds::SampleInfo& info) {
  if (!fix_repeats_.First(m, info)) return;  // a restarted inverter's fix of a sample already answered
  const DipoleFix f = FromMsg(m);
  std::lock_guard<std::mutex> lk(mu_);
  try {
    tracker_.AddFix(f);
  } catch (const InputError& e) {
    ++fixes_rejected_;
    spdlog::warn("magnav-tracker: dipole_fix skipped: {}", e.what());
  }
}

void TrackerNode::OnSample(const dds::msg::GradiometerSample& m, const dds::fdds::SampleInfo& info) {
  if (!repeats_.First(m, info)) return;
  for (const auto& admitted : guard_.Admit(m)) TakeSample(admitted);
}

// A message the time rule admitted (dds/stamp_guard.h).
void TrackerNode::TakeSample(const dds::msg::GradiometerSample& m) {
  GradiometerSample s = dds::FromMsg(m);
  if (door_.Check(s) != SampleDefect::kNone) {
    repeats_.Forget(m);  // a refused sample must not make a later good one look like a repeat
    return;
  }
  const auto B0 = b0_->For(s);
  if (!B0) return;  // counted by the source (waiting)
  s.B -= *B0;
  std::lock_guard<std::mutex> lk(mu_);
  if ((s.sigma_B == 0.0 || s.sigma_T == 0.0) && no_sigma_logged_.insert(s.sensor_id).second) {
    spdlog::warn("magnav-tracker: sensor {} sends no sigma_B/sigma_T: assuming sigma_B = {} T, sigma_T = {} T/m "
                 "(--sigma-b, --sigma-t); its covariances are only as right as that",
                 s.sensor_id, options_.tracker.track.default_sigma_B_T, options_.tracker.track.default_sigma_T_Tpm);
  }
  merge_.Tick(WallClock_s());
  if (s.t_s < fed_until_s_) {
    ++dropped_late_;
    return;
  }
  merge_.Push(s.t_s, s.sensor_id, s.sensor_id, s);
  merge_.Release([this](const GradiometerSample& x) { Feed(x); });
}

void TrackerNode::Tick() {
  std::lock_guard<std::mutex> lk(mu_);
  merge_.Tick(WallClock_s());
  if (!merge_.empty()) merge_.Release([this](const GradiometerSample& x) { Feed(x); });
}

void TrackerNode::Feed(const GradiometerSample& s) {
  fed_until_s_ = s.t_s;
  try {
    Publish(tracker_.AddSample(s));
  } catch (const InputError& e) {
    ++rejected_;
    spdlog::warn("magnav-tracker: sample of sensor {} at t = {} s rejected: {}", s.sensor_id, s.t_s, e.what());
  }
}

void TrackerNode::Flush() {
  std::lock_guard<std::mutex> lk(mu_);
  merge_.Release([this](const GradiometerSample& x) { Feed(x); }, /*all=*/true);
  // Tracks ended by the end of the data are not unregistered: their last
  // estimates stay in the writer's history (and, with the durable profile,
  // in its store) for consumers that come later.
  Publish(tracker_.Flush(), /*unregister_ended=*/false);
}

int TrackerNode::num_tracks() const {
  std::lock_guard<std::mutex> lk(mu_);
  return tracker_.summary().num_confirmed;
}

int TrackerNode::num_live_tracks() const {
  std::lock_guard<std::mutex> lk(mu_);
  return tracker_.num_live_tracks();
}

void TrackerNode::Publish(const std::vector<TrackOutput>& estimates, bool unregister_ended) {
  // A track's start is logged before its first estimate goes out. Ended
  // tracks stay registered (late consumers, and the durable profile's store,
  // keep their last estimates) until kKeptEndedTracks newer ones ended; then
  // the oldest is unregistered: track ids are never reused, and the writer
  // must not keep every track it ever had (track_stream: 100 keys).
  std::vector<std::uint32_t> ended;
  for (const TrackEvent& ev : tracker_.TakeEvents()) {
    if (ev.kind == TrackEvent::Kind::kStarted) {
      spdlog::info("magnav-tracker: track {} started at t = {} s ({})", ev.track_id, ev.t_s, ev.reason);
    } else {
      spdlog::info("magnav-tracker: track {} ended at t = {} s ({})", ev.track_id, ev.t_s, ev.reason);
      ended_.push_back(ev.track_id);
      while (unregister_ended && ended_.size() > kKeptEndedTracks) {
        ended.push_back(ended_.front());
        ended_.pop_front();
      }
    }
  }
  for (const auto& o : estimates) writer_->Write(ToMsg(o.estimate, o.m_B_Am2, o.cov_m_B, o.track_id));
  for (const std::uint32_t id : ended) {
    dds::msg::TrackEstimate key;
    key.track_id(id);
    writer_->Unregister(key);
  }
}

}  // namespace magnav::tracker
