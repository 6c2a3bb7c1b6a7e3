#include "localizer_node.h"

#include <chrono>

#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include "magnav/core/error.h"
#include "magnav/core/units.h"
#include "magnav/localizer/checkpoint.h"

namespace magnav::localizer {

bool LocalizerNodeOptions::IsValid(std::string* error) const {
  if (!vessel.m_B_Am2.allFinite() || vessel.m_B_Am2.norm() == 0.0 || !std::isfinite(vessel.z_m)) {
    if (error) *error = "the vessel moment must be finite and non-zero, its depth finite";
    return false;
  }
  if (sensors.empty()) {
    if (error) *error = "no sensor";
    return false;
  }
  return localizer.IsValid(error) && stream.IsValid(error);
}

namespace {
const LocalizerNodeOptions& Checked(const LocalizerNodeOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("localizer options: " + err);
  return o;
}
}  // namespace

LocalizerNode::LocalizerNode(dds::Node& node, const LocalizerNodeOptions& options)
    : localizer_(Checked(options).vessel, options.sensors, options.localizer, options.stream),
      vessel_id_(options.vessel_id),
      bounded_(options.stream.bounded) {
  repeats_.SetLogName("magnav-localizer: magnav/magnetometer sensor");
  if (!options.state_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options.state_dir, ec);
    if (ec) throw InputError("--state-dir " + options.state_dir + ": " + ec.message());
    state_path_ = (std::filesystem::path(options.state_dir) / "magnav-localizer.state").string();
    Resume();
  }
  writer_ = node.CreateWriter<dds::msg::SensorPositionEstimate>();
  nav_reader_ =
      node.CreateReader<dds::msg::VesselNav>([this](const dds::msg::VesselNav& m, const auto& info) { OnNav(m, info); });
  mag_reader_ = node.CreateReader<dds::msg::MagnetometerSample>(
      [this](const dds::msg::MagnetometerSample& m, const auto& info) { OnSample(m, info); });
}

void LocalizerNode::Resume() {
  std::string bytes;
  try {
    if (!ReadWholeFile(state_path_, &bytes)) {
      spdlog::info("magnav-localizer: no checkpoint {} yet: starting fresh", state_path_);
      return;
    }
    localizer_.RestoreState(DecodeCheckpoint(bytes));
  } catch (const CheckpointError& e) {
    const std::string aside = state_path_ + ".refused";
    const bool kept = std::rename(state_path_.c_str(), aside.c_str()) == 0;
    spdlog::error("magnav-localizer: checkpoint {} refused ({}): starting fresh, not from it{}", state_path_, e.what(),
                  kept ? "; the file is kept as " + aside : "");
    return;
  } catch (const std::exception& e) {
    spdlog::error("magnav-localizer: checkpoint {} not read ({}): starting fresh", state_path_, e.what());
    return;
  }
  resumed_ = true;
  resumed_until_s_ = localizer_.consumed_until();
  spdlog::info("magnav-localizer: resumed from checkpoint {}: {} items consumed up to t = {:.3f} s; what the "
               "writers' history sends again of those is dropped as already in the checkpoint",
               state_path_, localizer_.consumed(), localizer_.consumed_until());
}

bool LocalizerNode::Checkpoint() {
  if (state_path_.empty()) return false;
  std::string payload;
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (!localizer_.initialized()) return false;
    payload = localizer_.SaveState();
  }
  try {
    WriteFileAtomically(state_path_, EncodeCheckpoint(payload));
  } catch (const std::exception& e) {
    if (!std::exchange(checkpoint_failing_, true)) {
      spdlog::error("magnav-localizer: checkpoint not written ({}); the previous one stays (further failures are "
                    "not logged until one succeeds)", e.what());
    }
    return false;
  }
  if (std::exchange(checkpoint_failing_, false)) spdlog::info("magnav-localizer: checkpoint written again");
  return true;
}

std::uint64_t LocalizerNode::already_consumed() const {
  std::lock_guard<std::mutex> lk(mu_);
  return localizer_.already_consumed();
}

bool LocalizerNode::AlreadyConsumed(SampleCheck c) {
  if (c != SampleCheck::kAlreadyConsumed) return false;
  if (!std::exchange(logged_already_, true)) {
    spdlog::info("magnav-localizer: the writers' history up to t = {:.3f} s is in the checkpoint already: dropped "
                 "and counted as 'already in the checkpoint'", resumed_until_s_);
  }
  return true;
}

std::uint64_t LocalizerNode::outliers() const {
  std::lock_guard<std::mutex> lk(mu_);
  return localizer_.rejected();
}

std::uint64_t LocalizerNode::consumed() const {
  std::lock_guard<std::mutex> lk(mu_);
  return localizer_.consumed();
}

void LocalizerNode::Skip(SampleCheck why, const std::string& stream, std::uint32_t key, double t_s) {
  ++skipped_;
  const bool first = stream == "gnss" ? !std::exchange(warned_gnss_, true) : warned_sensors_.insert(key).second;
  if (first) {
    spdlog::warn("magnav-localizer: {} sample at t = {} s skipped: {} (further skips of this {} are only counted)",
                 stream == "gnss" ? std::string("vessel_nav") : "magnetometer " + std::to_string(key), t_s,
                 SampleCheckName(why), stream == "gnss" ? "stream" : "sensor");
  }
}

namespace {
double WallClock_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

void LocalizerNode::Tick() {
  std::lock_guard<std::mutex> lk(mu_);
  localizer_.Tick(WallClock_s());
}

void LocalizerNode::OnSample(const dds::msg::MagnetometerSample& m, const dds::fdds::SampleInfo& info) {
  if (!repeats_.First(m, info)) return;
  for (const auto& admitted : guard_.Admit(m)) TakeSample(admitted);
}

// A message the time rule admitted (dds/stamp_guard.h).
void LocalizerNode::TakeSample(const dds::msg::MagnetometerSample& m) {
  const MagSample s = FromMsg(m);
  std::lock_guard<std::mutex> lk(mu_);
  localizer_.Tick(WallClock_s());
  const SampleCheck c = localizer_.Add(s);
  if (c != SampleCheck::kOk && !AlreadyConsumed(c)) {
    repeats_.Forget(m);
    Skip(c, "magnetometer", s.sensor_id, s.t_s);
  }
}

void LocalizerNode::OnNav(const dds::msg::VesselNav& m, const dds::fdds::SampleInfo& info) {
  if (m.vessel_id() != vessel_id_ || m.source() != dds::msg::NAV_GNSS) {
    // Another vessel's navigation, or an INS / other source: not the
    // friendly vessel's GNSS (fusing it would pull the vessel state).
    ++ignored_;
    std::lock_guard<std::mutex> lk(mu_);
    if (!std::exchange(warned_ignored_, true)) {
      spdlog::warn("magnav-localizer: vessel_nav of vessel {} source {} ignored: only vessel {}'s GNSS fixes are "
                   "used (--vessel-id; further ones are only counted)",
                   m.vessel_id(), static_cast<int>(m.source()), vessel_id_);
    }
    return;
  }
  if (!nav_repeats_.First(m, info)) return;
  for (const auto& admitted : nav_guard_.Admit(m)) TakeNav(admitted);
}

// A message the time rule admitted (dds/stamp_guard.h).
void LocalizerNode::TakeNav(const dds::msg::VesselNav& m) {
  const GnssFix f = FromMsg(m);
  std::lock_guard<std::mutex> lk(mu_);
  localizer_.Tick(WallClock_s());
  const SampleCheck c = localizer_.Add(f);
  if (c != SampleCheck::kOk && !AlreadyConsumed(c)) {
    nav_repeats_.Forget(m);
    Skip(c, "gnss", 0, f.t_s);
  }
}

void LocalizerNode::Publish() {
  std::vector<SensorEstimate> est;
  std::optional<StreamingLocalizer::Snapshot> snapshot;
  double t = 0.0;
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (!localizer_.initialized()) return;
    if (bounded_) {
      snapshot = localizer_.TakeSnapshot();  // O(window): bounded
    } else {
      est = localizer_.Estimates(/*bounds=*/true);  // over the whole pass (--method ekf)
    }
    t = localizer_.time();
  }
  if (snapshot) est = snapshot->WithBounds();
  for (const auto& e : est) writer_->Write(ToMsg(e, t));
}

void LocalizerNode::Flush() {
  {
    std::lock_guard<std::mutex> lk(mu_);
    localizer_.Flush();
  }
  Publish();
}

}  // namespace magnav::localizer
