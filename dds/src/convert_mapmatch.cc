#include "magnav/dds/convert_mapmatch.h"

#include "magnav/mapmatch/fix_schedule.h"

namespace magnav::dds {

FixMethod FixMethodOf(mapmatch::ParticleFilterKind kind) {
  return kind == mapmatch::ParticleFilterKind::kPf ? FixMethod::kPf : FixMethod::kAfpf;
}

MapFixRecord ToRecord(const mapmatch::StepDiagnostics& d, mapmatch::ParticleFilterKind kind, std::uint32_t vehicle_id,
                      std::uint64_t stamp_ns) {
  MapFixRecord r;
  r.vehicle_id = vehicle_id;
  r.stamp_ns = stamp_ns;
  r.method = FixMethodOf(kind);
  r.method_name = mapmatch::ParticleFilterKindName(kind);
  r.lat_deg = d.lat_deg;
  r.lon_deg = d.lon_deg;
  r.score = d.ess;
  const auto cov = mapmatch::CovarianceNorthEast_m2(d);
  r.cov_ne_m2 << cov[0], cov[1], cov[2], cov[3];
  // The filter's status (particle_filter.h StatusOf: lost, off the map, converging, ok); the matcher's
  // partly observable only where the filter says ok.
  switch (mapmatch::StatusOf(d)) {
    case mapmatch::StepStatus::kLost:
      r.status = MapFixStatus::kLost;
      break;
    case mapmatch::StepStatus::kOffMap:
      r.status = MapFixStatus::kOffMap;
      break;
    case mapmatch::StepStatus::kConverging:
      r.status = MapFixStatus::kConverging;
      break;
    case mapmatch::StepStatus::kOk:
      r.status = d.partly_observable ? MapFixStatus::kPartlyObservable : MapFixStatus::kOk;
      break;
  }
  return r;
}

msg::MapFix ToMsg(const mapmatch::StepDiagnostics& d, mapmatch::ParticleFilterKind kind, std::uint32_t vehicle_id,
                  std::uint64_t stamp_ns) {
  return ToMsg(ToRecord(d, kind, vehicle_id, stamp_ns));
}

}  // namespace magnav::dds
