#include "magnav/dds/sample_door.h"

#include <spdlog/spdlog.h>

namespace magnav::dds {

SampleDefect SampleDoor::Check(const GradiometerSample& sample) {
  const SampleDefect defect = CheckSample(sample);
  if (defect == SampleDefect::kNone) return defect;
  ++rejected_;
  std::lock_guard<std::mutex> lk(mu_);
  if (logged_.emplace(sample.sensor_id, static_cast<int>(defect)).second) {
    spdlog::warn("{}: sample of sensor {} at t = {} s skipped: {} (logged once per sensor and defect; see the "
                 "'bad samples' count)",
                 service_, sample.sensor_id, sample.t_s, SampleDefectName(defect));
  }
  return defect;
}

}  // namespace magnav::dds
