#include "magnav/localizer/stream.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "magnav/core/error.h"
#include "magnav/localizer/checkpoint.h"
#include "magnav/localizer/crlb.h"

namespace magnav::localizer {

bool StreamOptions::IsValid(std::string* error) const {
  if (!Merge().IsValid(error)) return false;
  if (!(init_window_s > 0.0) || !std::isfinite(init_window_s)) {
    if (error) *error = "init_window_s must be finite and > 0";
    return false;
  }
  return bound.IsValid(error);
}

StreamingLocalizer::StreamingLocalizer(const Vessel& vessel, const std::vector<SensorPrior>& sensors,
                                       const LocalizerOptions& options, const StreamOptions& stream)
    : vessel_(vessel), sensors_(sensors), options_(options), stream_(stream), gate_(sensors), merge_(stream.Merge()) {
  std::string why;
  if (!options.IsValid(&why)) throw InputError("localizer options: " + why);
  if (!stream.IsValid(&why)) throw InputError("stream options: " + why);
  if (sensors.empty()) throw InputError("localizer: no sensor");
  pass_.vessel = vessel;
  pass_.sensors = sensors;
  if (stream.bounded) crlb_.emplace(vessel, sensors, options, stream.bound);
  merge_.Declare(-1);
  for (const auto& p : sensors) merge_.Declare(p.sensor_id);
}

StreamingLocalizer::~StreamingLocalizer() = default;

double StreamingLocalizer::time() const {
  return ekf_ ? ekf_->time() : -std::numeric_limits<double>::infinity();
}

SampleCheck StreamingLocalizer::Add(const MagSample& sample) {
  const SampleCheck c = gate_.Check(sample);
  if (c != SampleCheck::kOk) return c;
  return Buffer(sample.t_s, 1, sample.sensor_id, sample);
}

SampleCheck StreamingLocalizer::Add(const GnssFix& fix) {
  const SampleCheck c = gate_.Check(fix);
  if (c != SampleCheck::kOk) return c;
  return Buffer(fix.t_s, 0, -1, fix);
}

SampleCheck StreamingLocalizer::Buffer(double t_s, int kind, std::int64_t stream, Item item) {
  if (restored_ && (t_s < restored_until_ ||
                    (t_s == restored_until_ && restored_at_until_.erase({kind, stream < 0 ? 0 : stream}) > 0))) {
    // The writers' history after a restart: in the checkpoint already. It
    // still tells that its stream is alive and where it is.
    ++already_consumed_;
    merge_.Note(stream, t_s);
    return SampleCheck::kAlreadyConsumed;
  }
  if (t_s < consumed_until_) {
    ++late_;
    return SampleCheck::kTimeBackwards;
  }
  // Rank: fixes (−1) before samples at equal times, then by sensor id.
  merge_.Push(t_s, stream, kind == 0 ? -1 : stream, std::move(item));
  Release(false);
  return SampleCheck::kOk;
}

void StreamingLocalizer::Tick(double now_s) {
  merge_.Tick(now_s);
  if (stream_.merge == StreamMerge::kWatermark && !merge_.empty()) Release(false);
}

bool StreamingLocalizer::TryStart(bool final) {
  if (merge_.empty()) return false;
  const double t0 = merge_.front_time();
  if (!final && merge_.ReleasableUntil() - t0 < stream_.init_window_s && merge_.size() < stream_.max_pending) {
    return false;
  }
  std::vector<GnssFix> fixes;
  for (const auto& [key, item] : merge_.pending()) {
    if (const auto* f = std::get_if<GnssFix>(&item)) fixes.push_back(*f);
  }
  VesselVector x0;
  VesselCovariance P0;
  bool started = InitialVesselFromGnss(fixes, t0, options_, &x0, &P0, stream_.init_window_s);
  if (!started && options_.vessel_start) {
    const InitialVesselSigma& s = options_.initial;
    x0 = *options_.vessel_start;
    P0 = VesselVector(s.position_m * s.position_m, s.position_m * s.position_m, s.speed_mps * s.speed_mps,
                      s.heading_rad * s.heading_rad, s.turn_rate_radps * s.turn_rate_radps)
             .asDiagonal();
    started = true;
  }
  if (started) {
    ekf_ = std::make_unique<LocalizerEkf>(vessel_, sensors_, t0, x0, P0, options_);
    return true;
  }
  // No usable fixes at the start: slide the start forward.
  if (!final) {
    const double until = merge_.ReleasableUntil();
    while (!merge_.empty() &&
           (until - merge_.front_time() >= stream_.init_window_s || merge_.size() > stream_.max_pending)) {
      merge_.PopFront();
      ++dropped_before_start_;
    }
  }
  return false;
}

void StreamingLocalizer::Release(bool all) {
  if (!ekf_ && !TryStart(all)) return;
  merge_.Release([this](const Item& item) { Consume(item); }, all);
}

void StreamingLocalizer::Consume(const Item& item) {
  const double t = std::visit([](const auto& x) { return x.t_s; }, item);
  if (t != consumed_until_) consumed_at_until_.clear();
  const MagSample* sample = std::get_if<MagSample>(&item);
  consumed_at_until_.insert({sample ? 1 : 0, sample ? static_cast<std::int64_t>(sample->sensor_id) : 0});
  consumed_until_ = t;
  const bool ok = std::visit([this](const auto& x) { return ekf_->Update(x); }, item);
  if (!ok) {
    // Neither is in the pass the bounds are computed on, nor in the
    // trajectory (the batch maps a start onto its own epochs by time).
    ++(ekf_->last_outcome() == LocalizerEkf::Outcome::kRejected ? rejected_ : failed_);
    return;
  }
  ++consumed_;
  const MagSample* s = std::get_if<MagSample>(&item);
  ++(s ? magnetometer_used_ : gnss_used_);
  if (crlb_) {
    if (s) {
      crlb_->Add(*s, ekf_->state());
    } else {
      crlb_->Add(std::get<GnssFix>(item), ekf_->state());
    }
    return;
  }
  if (s) {
    pass_.samples.push_back(*s);
  } else {
    pass_.gnss.push_back(std::get<GnssFix>(item));
  }
  // Epochs as EpochTimes groups them: a new one when t is past the
  // current epoch's start by more than the tolerance.
  if (epoch_t_.empty() || t - epoch_t_.back() > options_.epoch_tolerance_s) {
    epoch_t_.push_back(t);
    trajectory_.emplace_back();
  }
  trajectory_.back() = ekf_->vessel_state();
}

void StreamingLocalizer::Flush() { Release(true); }

namespace {
// The bounded bound at the estimates, written into them.
CrlbResult AttachIncremental(const IncrementalCrlb& crlb, std::vector<SensorEstimate>* sensors) {
  std::vector<Eigen::Vector2d> s_xy;
  for (const auto& e : *sensors) s_xy.push_back(e.p_SinW_m.head<2>());
  CrlbResult b = crlb.Bounds(s_xy);
  for (std::size_t j = 0; j < sensors->size() && j < b.joint.size(); ++j) {
    (*sensors)[j].crlb_joint_m2 = b.joint[j];
    (*sensors)[j].crlb_known_trajectory_m2 = b.known_trajectory[j];
  }
  return b;
}
}  // namespace

std::vector<SensorEstimate> StreamingLocalizer::Estimates(bool bounds) const {
  if (!ekf_) return {};
  std::vector<SensorEstimate> out = ekf_->SensorEstimates();
  if (bounds && crlb_) {
    if (crlb_->window_epochs() > 0) AttachIncremental(*crlb_, &out);
  } else if (bounds && !trajectory_.empty()) {
    AttachCrlb(pass_, options_, trajectory_, &out);
  }
  return out;
}

StreamingLocalizer::Snapshot StreamingLocalizer::TakeSnapshot() const {
  if (!crlb_) throw std::logic_error("StreamingLocalizer::TakeSnapshot: only in bounded mode");
  Snapshot s;
  if (!ekf_) return s;
  s.sensors = ekf_->SensorEstimates();
  s.bound = *crlb_;
  return s;
}

std::vector<SensorEstimate> StreamingLocalizer::Snapshot::WithBounds() const {
  std::vector<SensorEstimate> out = sensors;
  if (bound && !out.empty() && bound->window_epochs() > 0) AttachIncremental(*bound, &out);
  return out;
}

std::size_t StreamingLocalizer::retained_items() const {
  return merge_.size() + (crlb_ ? crlb_->window_items() : 0) + pass_.samples.size() + pass_.gnss.size() +
         trajectory_.size() + epoch_t_.size();
}

Localization StreamingLocalizer::Result() const {
  Localization out;
  out.summary.method = crlb_ ? "ekf-bounded" : "ekf";
  if (!ekf_) {
    out.summary.message = "not started: no GNSS fixes at the start";
    return out;
  }
  const auto t0 = std::chrono::steady_clock::now();
  out.sensors = Estimates(false);
  out.cov_sensors_m2 = ekf_->covariance().bottomRightCorner(2 * ekf_->num_sensors(), 2 * ekf_->num_sensors());
  out.trajectory_t_s = crlb_ ? crlb_->WindowTimes() : epoch_t_;
  out.trajectory = crlb_ ? crlb_->WindowTrajectory() : trajectory_;
  out.summary.magnetometer_updates = static_cast<int>(magnetometer_used_);
  out.summary.gnss_updates = static_cast<int>(gnss_used_);
  out.summary.magnetometer_outliers = static_cast<int>(ekf_->rejected_magnetometer());
  out.summary.gnss_outliers = static_cast<int>(ekf_->rejected_gnss());
  out.summary.gate_releases = static_cast<int>(ekf_->gate_releases());
  out.summary.gate_probability = options_.gate_probability;
  out.summary.converged = failed_ == 0 && ekf_->covariance().allFinite() && ekf_->state().allFinite();
  if (failed_ == 0 && rejected_ == 0) {
    out.summary.message = "every sample used";
  } else {
    out.summary.message.clear();
    if (rejected_ > 0) out.summary.message = std::to_string(rejected_) + " updates refused by the NIS gate";
    if (failed_ > 0) {
      if (!out.summary.message.empty()) out.summary.message += ", ";
      out.summary.message += std::to_string(failed_) + " updates failed (not applied)";
    }
  }
  MarkDivergence(&out.summary);
  out.crlb_joint_m2 = crlb_ ? AttachIncremental(*crlb_, &out.sensors).joint_full
                            : AttachCrlb(pass_, options_, trajectory_, &out.sensors).joint_full;
  out.summary.crlb_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

namespace {
void PutSample(StateWriter& w, const MagSample& s) {
  w.F64(s.t_s);
  w.U32(s.sensor_id);
  for (int i = 0; i < 3; ++i) w.F64(s.B_T[i]);
}
MagSample GetSample(StateReader& r) {
  MagSample s;
  s.t_s = r.F64();
  s.sensor_id = r.U32();
  for (int i = 0; i < 3; ++i) s.B_T[i] = r.F64();
  return s;
}
void PutFix(StateWriter& w, const GnssFix& f) {
  w.F64(f.t_s);
  w.F64(f.p_xy_m.x());
  w.F64(f.p_xy_m.y());
  w.F64(f.sigma_m);
}
GnssFix GetFix(StateReader& r) {
  GnssFix f;
  f.t_s = r.F64();
  f.p_xy_m.x() = r.F64();
  f.p_xy_m.y() = r.F64();
  f.sigma_m = r.F64();
  return f;
}
// Payload tag of the stream section (after the configuration).
constexpr std::uint32_t kStreamTag = 0x4d414552;  // "REAM"
constexpr std::size_t kMaxCount = std::size_t{1} << 40;  // a corrupt count: refused before allocating
}  // namespace

std::string StreamingLocalizer::ConfigBytes(int part) const {
  StateWriter w;
  if (part == 0) {
    for (const auto& p : sensors_) {
      w.U32(p.sensor_id);
      for (int i = 0; i < 3; ++i) w.F64(p.p_SinW_m[i]);
      w.F64(p.sigma_xy_m);
    }
  } else if (part == 1) {
    for (int i = 0; i < 3; ++i) w.F64(vessel_.m_B_Am2[i]);
    w.F64(vessel_.z_m);
  } else {
    const LocalizerOptions& o = options_;
    for (double v : {o.process.position_m_per_sqrt_s, o.process.speed_mps_per_sqrt_s, o.process.heading_rad_per_sqrt_s,
                     o.process.turn_rate_radps_per_sqrt_s, o.initial.position_m, o.initial.speed_mps,
                     o.initial.heading_rad, o.initial.turn_rate_radps, o.sigma_B_T, o.gnss_sigma_m,
                     o.gate_probability, o.epoch_tolerance_s, stream_.bound.lag_s}) {
      w.F64(v);
    }
    w.I64(o.gate_release_after);
    w.U8(stream_.bounded ? 1 : 0);
    w.U64(stream_.bound.max_window_items);
  }
  return w.bytes();
}

std::string StreamingLocalizer::SaveState() const {
  StateWriter w;
  for (int part = 0; part < 3; ++part) w.Bytes(ConfigBytes(part));
  w.U32(kStreamTag);
  w.F64(consumed_until_);
  w.U64(consumed_at_until_.size());
  for (const auto& [kind, id] : consumed_at_until_) {
    w.U8(static_cast<std::uint8_t>(kind));
    w.I64(id);
  }
  for (std::uint64_t c : {consumed_, late_, failed_, rejected_, dropped_before_start_, magnetometer_used_, gnss_used_,
                          already_consumed_}) {
    w.U64(c);
  }
  w.U8(ekf_ ? 1 : 0);
  if (ekf_) ekf_->SaveState(w);
  w.U8(crlb_ ? 1 : 0);
  if (crlb_) {
    crlb_->SaveState(w);
  } else {
    w.U64(pass_.samples.size());
    for (const auto& s : pass_.samples) PutSample(w, s);
    w.U64(pass_.gnss.size());
    for (const auto& f : pass_.gnss) PutFix(w, f);
    w.U64(epoch_t_.size());
    for (std::size_t i = 0; i < epoch_t_.size(); ++i) {
      w.F64(epoch_t_[i]);
      w.Matrix(trajectory_[i]);
    }
  }
  return w.bytes();
}

void StreamingLocalizer::RestoreState(const std::string& payload) {
  if (merge_.pushed() > 0 || ekf_ || restored_) {
    throw std::logic_error("StreamingLocalizer::RestoreState: only into a new localizer");
  }
  StateReader r(payload);
  static const char* const kParts[3] = {
      "another deployment (sensor ids, positions or sigmas differ)", "another vessel (moment or depth differ)",
      "other estimator options (noise, gate, method or bound differ)"};
  for (int part = 0; part < 3; ++part) {
    if (r.Bytes(payload.size()) != ConfigBytes(part)) {
      throw CheckpointError(std::string("made for ") + kParts[part]);
    }
  }
  if (r.U32() != kStreamTag) throw CheckpointError("corrupt: no stream section");
  const double until = r.F64();
  std::set<std::pair<int, std::int64_t>> at_until;
  for (std::size_t i = r.Count(sensors_.size() + 1); i > 0; --i) {
    const int kind = r.U8();
    at_until.insert({kind, r.I64()});
  }
  std::uint64_t counters[8];
  for (auto& c : counters) c = r.U64();
  std::unique_ptr<LocalizerEkf> ekf;
  if (r.U8() != 0) {
    ekf = std::make_unique<LocalizerEkf>(vessel_, sensors_, 0.0, VesselVector::Zero(), VesselCovariance::Identity(),
                                         options_);
    ekf->RestoreState(r);
  }
  const bool bounded = r.U8() != 0;
  if (bounded != stream_.bounded) throw CheckpointError("made for " + std::string(kParts[2]));
  std::optional<IncrementalCrlb> crlb;
  Pass pass = pass_;
  std::vector<double> epoch_t;
  std::vector<VesselVector> trajectory;
  if (bounded) {
    crlb.emplace(vessel_, sensors_, options_, stream_.bound);
    crlb->RestoreState(r);
  } else {
    pass.samples.resize(r.Count(kMaxCount / 48));
    for (auto& s : pass.samples) s = GetSample(r);
    pass.gnss.resize(r.Count(kMaxCount / 32));
    for (auto& f : pass.gnss) f = GetFix(r);
    const std::size_t epochs = r.Count(kMaxCount / 64);
    for (std::size_t i = 0; i < epochs; ++i) {
      epoch_t.push_back(r.F64());
      const Eigen::MatrixXd x = r.Matrix(5, 1);
      if (x.rows() != 5 || x.cols() != 1) throw CheckpointError("corrupt: trajectory state of another size");
      trajectory.push_back(x);
    }
  }
  if (!r.at_end()) throw CheckpointError("corrupt: bytes after the state");
  if (!ekf && std::isfinite(until)) throw CheckpointError("corrupt: consumed items but no EKF");
  consumed_until_ = until;
  consumed_at_until_ = at_until;
  restored_ = true;
  restored_until_ = until;
  restored_at_until_ = std::move(at_until);
  consumed_ = counters[0];
  late_ = counters[1];
  failed_ = counters[2];
  rejected_ = counters[3];
  dropped_before_start_ = counters[4];
  magnetometer_used_ = counters[5];
  gnss_used_ = counters[6];
  already_consumed_ = counters[7];
  ekf_ = std::move(ekf);
  crlb_ = std::move(crlb);
  pass_ = std::move(pass);
  epoch_t_ = std::move(epoch_t);
  trajectory_ = std::move(trajectory);
}

}  // namespace magnav::localizer
