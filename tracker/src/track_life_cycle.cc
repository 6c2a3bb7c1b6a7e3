#include "magnav/tracker/track_life_cycle.h"

#include <cmath>
#include <limits>

#include "magnav/core/checkpoint.h"

namespace magnav::tracker {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

TrackLifeCycle::TrackLifeCycle(double t_created_s, const TrackManagementOptions& options)
    : options_(options),
      t_created_(t_created_s),
      t_last_detection_(t_created_s),
      miss_since_(kNaN),
      unusable_since_(kNaN),
      duplicate_since_(kNaN),
      out_of_reach_since_(kNaN) {}

void TrackLifeCycle::OnAssociation(double t_s, bool detected, bool missed, bool had_samples, bool tensor_evidence) {
  if (detected) t_last_detection_ = t_s;
  if (missed) {
    if (std::isnan(miss_since_)) miss_since_ = t_s;
  } else {
    miss_since_ = kNaN;
  }
  if (!confirmed_ && had_samples) {
    ++seen_;
    detections_ += detected && tensor_evidence ? 1 : 0;
  }
}

void TrackLifeCycle::ExcuseMisses() { miss_since_ = kNaN; }

void TrackLifeCycle::OnReach(double t_s, bool in_reach) {
  if (in_reach) {
    out_of_reach_since_ = kNaN;
  } else if (std::isnan(out_of_reach_since_)) {
    out_of_reach_since_ = t_s;
  }
}

void TrackLifeCycle::OnEstimate(double t_s, bool usable, double sigma_horizontal_m) {
  sigma_h_ = sigma_horizontal_m;
  if (!usable) {
    if (std::isnan(unusable_since_)) unusable_since_ = t_s;
  } else {
    unusable_since_ = kNaN;
  }
}

TrackLifeCycle::Decision TrackLifeCycle::Decide(double t, std::string* reason) const {
  const auto end = [&](const char* why) {
    if (reason) *reason = why;
    return Decision::kEnd;
  };
  if (!confirmed_) {
    if (detections_ >= options_.confirm_m) return Decision::kConfirm;
    if (seen_ - detections_ > options_.confirm_n - options_.confirm_m || t - t_created_ > options_.max_coast_s) {
      return end("not confirmed");
    }
    return Decision::kKeep;
  }
  if (!std::isnan(miss_since_) && t - miss_since_ >= options_.max_miss_s) return end("missed");
  if (options_.out_of_reach_s > 0.0 && !std::isnan(out_of_reach_since_) &&
      t - out_of_reach_since_ >= options_.out_of_reach_s) {
    return end("out_of_reach");
  }
  if (t - t_last_detection_ >= options_.max_coast_s) return end("lost");
  if (sigma_h_ > options_.max_sigma_horizontal_m) return end("uncertain");
  if (!std::isnan(unusable_since_) && t - unusable_since_ >= options_.max_miss_s) return end("unusable");
  return Decision::kKeep;
}

bool TrackLifeCycle::OnDuplicateCheck(double t_s, bool close_to_older) {
  if (!close_to_older) {
    duplicate_since_ = kNaN;
    return false;
  }
  if (!confirmed_) return true;
  if (std::isnan(duplicate_since_)) duplicate_since_ = t_s;
  return t_s - duplicate_since_ >= options_.max_miss_s;
}

void TrackLifeCycle::SaveState(StateWriter& w) const {
  w.U8(confirmed_ ? 1 : 0);
  w.F64(t_created_);
  w.I64(seen_);
  w.I64(detections_);
  for (double v : {t_last_detection_, miss_since_, unusable_since_, duplicate_since_, out_of_reach_since_, sigma_h_}) {
    w.F64(v);
  }
}

void TrackLifeCycle::RestoreState(StateReader& r) {
  confirmed_ = r.U8() != 0;
  t_created_ = r.F64();
  seen_ = static_cast<int>(r.I64());
  detections_ = static_cast<int>(r.I64());
  for (double* v : {&t_last_detection_, &miss_since_, &unusable_since_, &duplicate_since_, &out_of_reach_since_,
                    &sigma_h_}) {
    *v = r.F64();
  }
}

}  // namespace magnav::tracker
