#include "tracker_node.h"

#include <algorithm>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <utility>

#include <spdlog/spdlog.h>

#include "magnav/core/error.h"
#include "magnav/core/units.h"
#include "magnav/dds/convert_tracker.h"
#include "magnav/tracker/checkpoint.h"
#include "magnav/tracker/initialize.h"

namespace magnav::tracker {

bool TrackerNodeOptions::IsValid(std::string* error) const {
  if (!merge.IsValid(error)) return false;
  if (!std::isfinite(merge.reorder_delay_s)) {
    if (error) *error = "reorder_delay_s must be finite";
    return false;
  }
  if (kept_ended_tracks < 0 || kept_ended_tracks > kMaxKeptEndedTracks) {
    if (error) *error = "kept_ended_tracks must be in [0, " + std::to_string(kMaxKeptEndedTracks) + "]";
    return false;
  }
  return tracker.IsValid(error);
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

// The node publishes each track's estimates in time order and the wire's
// TrackState has no value for a back-filled start row
// (TrackManagementOptions::backfill_start): off here, offline only.
MultiTrackerOptions LiveOptions(MultiTrackerOptions o) {
  o.management.backfill_start = false;
  return o;
}
}  // namespace

TrackerNode::TrackerNode(dds::Node& node, const TrackerNodeOptions& options,
                         std::unique_ptr<dds::RegionalFieldSource> b0)
    : options_(Checked(options)),
      b0_(std::move(b0)),
      tracker_(Eigen::Vector3d::Zero(), LiveOptions(options.tracker)),
      merge_(options.merge) {
  repeats_.SetLogName("magnav-tracker: magnav/gradiometer sensor");
  if (!options_.state_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options_.state_dir, ec);
    if (ec) throw InputError("--state-dir " + options_.state_dir + ": " + ec.message());
    state_path_ = (std::filesystem::path(options_.state_dir) / "magnav-tracker.state").string();
    Resume();
  }
  // Acknowledgments after every half history (per track: 1000 in the
  // built-in profile, 10 in the durable one), so no estimate a reader has not
  // acknowledged is overwritten, waiting at most 2 s for a reader (a dead one
  // is forgotten after the 3 s lease). Every 5 estimates, as before, capped an
  // unpaced replay with a recorder at ~280 estimates/s and made the stop
  // overrun its bound with hundreds still queued.
  auto track_writer = node.CreateWriter<dds::msg::TrackEstimate>();
  const int window = std::max(1, track_writer->qos().history().depth / 2);
  writer_ = std::make_unique<dds::QueuedWriter<dds::msg::TrackEstimate>>(std::move(track_writer), window,
                                                                        std::chrono::seconds(2));
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
  if (resumed_) {
    // The inverter's history after our restart: fixes the checkpoint took already.
    const auto it = restored_fix_until_.find(f.sensor_id);
    if (it != restored_fix_until_.end() && f.t_s <= it->second) {
      ++already_consumed_;
      return;
    }
  }
  double& until = fix_until_.try_emplace(f.sensor_id, f.t_s).first->second;
  until = std::max(until, f.t_s);
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
  if (resumed_ && (s.t_s < restored_until_s_ ||
                   (s.t_s == restored_until_s_ && restored_at_until_.erase(s.sensor_id) > 0))) {
    // The writers' history after a restart: in the checkpoint already. It
    // still tells the merge that its sensor is alive and where it is.
    ++already_consumed_;
    merge_.Note(s.sensor_id, s.t_s);
    return;
  }
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
  if (s.t_s != fed_until_s_) fed_at_until_.clear();
  fed_at_until_.insert(s.sensor_id);
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

namespace {
constexpr std::uint32_t kNodeTag = 0x45444f4e;  // "NODE"
constexpr std::size_t kMaxCount = std::size_t{1} << 24;
}  // namespace

std::string TrackerNode::ConfigBytes() const {
  StateWriter w;
  w.Bytes(b0_->Describe());
  return w.bytes();
}

void TrackerNode::Resume() {
  std::string bytes;
  try {
    if (!ReadWholeFile(state_path_, &bytes)) {
      spdlog::info("magnav-tracker: no checkpoint {} yet: starting fresh", state_path_);
      return;
    }
    const std::string payload = DecodeTrackerCheckpoint(bytes);
    StateReader r(payload);  // a view: the payload must outlive it
    if (r.Bytes(bytes.size()) != ConfigBytes()) throw CheckpointError("made for another B0 (--b0)");
    if (r.U32() != kNodeTag) throw CheckpointError("corrupt: no node section");
    const double until = r.F64();
    std::set<std::uint32_t> at_until;
    for (std::size_t n = r.Count(kMaxCount); n > 0; --n) at_until.insert(r.U32());
    std::map<std::uint32_t, double> fix_until;
    for (std::size_t n = r.Count(kMaxCount); n > 0; --n) {
      const std::uint32_t id = r.U32();
      fix_until[id] = r.F64();
    }
    std::deque<std::uint32_t> ended;
    for (std::size_t n = r.Count(kMaxCount); n > 0; --n) ended.push_back(r.U32());
    std::uint64_t counters[4];
    for (auto& c : counters) c = r.U64();
    const std::string tracker_state = r.Bytes(bytes.size());
    if (!r.at_end()) throw CheckpointError("corrupt: bytes after the node state");
    tracker_.RestoreState(tracker_state);  // last: throws before anything changed, or takes it all
    fed_until_s_ = restored_until_s_ = until;
    fed_at_until_ = restored_at_until_ = std::move(at_until);
    fix_until_ = restored_fix_until_ = std::move(fix_until);
    ended_ = std::move(ended);
    dropped_late_ = counters[0];
    rejected_ = counters[1];
    fixes_rejected_ = counters[2];
    already_consumed_ = counters[3];
  } catch (const CheckpointError& e) {
    const std::string aside = state_path_ + ".refused";
    const bool kept = std::rename(state_path_.c_str(), aside.c_str()) == 0;
    spdlog::error("magnav-tracker: checkpoint {} refused ({}): starting fresh, not from it{}", state_path_, e.what(),
                  kept ? "; the file is kept as " + aside : "");
    return;
  } catch (const std::exception& e) {
    spdlog::error("magnav-tracker: checkpoint {} not read ({}): starting fresh", state_path_, e.what());
    return;
  }
  resumed_ = true;
  spdlog::info("magnav-tracker: resumed from checkpoint {}: samples consumed up to t = {:.3f} s, {} live tracks, "
               "{} confirmed so far; what the writers' history sends again of those is dropped as already in the "
               "checkpoint",
               state_path_, fed_until_s_, tracker_.num_live_tracks(), tracker_.summary().num_confirmed);
}

bool TrackerNode::Checkpoint() {
  if (state_path_.empty()) return false;
  std::string payload;
  std::uint64_t made = 0;  // estimates (and unregistrations) queued by the snapshot
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (fed_until_s_ == -1e300) return false;  // nothing consumed yet
    made = writer_->pushed();
    StateWriter w;
    w.Bytes(ConfigBytes());
    w.U32(kNodeTag);
    w.F64(fed_until_s_);
    w.U64(fed_at_until_.size());
    for (const std::uint32_t id : fed_at_until_) w.U32(id);
    w.U64(fix_until_.size());
    for (const auto& [id, t] : fix_until_) {
      w.U32(id);
      w.F64(t);
    }
    w.U64(ended_.size());
    for (const std::uint32_t id : ended_) w.U32(id);
    for (std::uint64_t c : {dropped_late_.load(), rejected_.load(), fixes_rejected_.load(), already_consumed_.load()}) {
      w.U64(c);
    }
    w.Bytes(tracker_.SaveState());
    payload = w.bytes();
  }
  // Every estimate made before the snapshot must have reached the readers
  // before the checkpoint replaces the old one: a restart from it does not
  // make them again (a crash after it would lose them). Not delivered within
  // 1 s (a reader slow or gone): this checkpoint is skipped, the old one stays.
  if (!writer_->WaitForDelivered(made, std::chrono::milliseconds(1000))) return false;
  try {
    WriteFileAtomically(state_path_, EncodeTrackerCheckpoint(payload));
  } catch (const std::exception& e) {
    if (!std::exchange(checkpoint_failing_, true)) {
      spdlog::error("magnav-tracker: checkpoint not written ({}); the previous one stays (further failures are "
                    "not logged until one succeeds)", e.what());
    }
    return false;
  }
  if (std::exchange(checkpoint_failing_, false)) spdlog::info("magnav-tracker: checkpoint written again");
  return true;
}

int TrackerNode::num_tracks() const {
  std::lock_guard<std::mutex> lk(mu_);
  return tracker_.summary().num_confirmed;
}

int TrackerNode::num_live_tracks() const {
  std::lock_guard<std::mutex> lk(mu_);
  return tracker_.num_live_tracks();
}

std::string TrackerNode::far_source_report() const {
  std::lock_guard<std::mutex> lk(mu_);
  const MultiSummary& sm = tracker_.summary();
  return sm.far_source_enabled ? sm.far_source.BriefReport() : std::string();
}

void TrackerNode::Publish(const std::vector<TrackOutput>& estimates, bool unregister_ended) {
  // A track's start is logged before its first estimate goes out. Ended
  // tracks stay registered (late consumers, and the durable profile's store,
  // keep their last estimates) until kept_ended_tracks newer ones ended; then
  // the oldest is unregistered: track ids are never reused, and the writer
  // must not keep every track it ever had (track_stream: 100 keys).
  std::vector<std::uint32_t> ended;
  for (const TrackEvent& ev : tracker_.TakeEvents()) {
    if (ev.kind == TrackEvent::Kind::kStarted) {
      spdlog::info("magnav-tracker: track {} started at t = {} s ({})", ev.track_id, ev.t_s, ev.reason);
      // A re-acquired track (reacquire.h) is live again under its id: no
      // longer one of the ended ones to unregister.
      ended_.erase(std::remove(ended_.begin(), ended_.end(), ev.track_id), ended_.end());
    } else {
      spdlog::info("magnav-tracker: track {} ended at t = {} s ({})", ev.track_id, ev.t_s, ev.reason);
      ended_.push_back(ev.track_id);
      while (unregister_ended && ended_.size() > static_cast<std::size_t>(options_.kept_ended_tracks)) {
        ended.push_back(ended_.front());
        ended_.pop_front();
      }
    }
  }
  for (const auto& o : estimates) writer_->Write(ToMsg(o.estimate, o.m_B_Am2, o.cov_m_B, o.track_id, o.state));
  for (const std::uint32_t id : ended) {
    dds::msg::TrackEstimate key;
    key.track_id(id);
    writer_->Unregister(key);
  }
}

}  // namespace magnav::tracker
