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
  // Lost, off the map, partly observable (the matcher's review of the map, its covariance floored), then the
  // filter's converging (particle_filter.h StatusOf), else ok: CONVERGING (appended, issue 25) takes only
  // what was OK before, so the earlier values keep their meaning.
  const mapmatch::StepStatus s = mapmatch::StatusOf(d);
  r.status = s == mapmatch::StepStatus::kLost     ? MapFixStatus::kLost
             : s == mapmatch::StepStatus::kOffMap ? MapFixStatus::kOffMap
             : d.partly_observable                ? MapFixStatus::kPartlyObservable
             : s == mapmatch::StepStatus::kConverging ? MapFixStatus::kConverging
                                                      : MapFixStatus::kOk;
  return r;
}

msg::MapFix ToMsg(const mapmatch::StepDiagnostics& d, mapmatch::ParticleFilterKind kind, std::uint32_t vehicle_id,
                  std::uint64_t stamp_ns) {
  return ToMsg(ToRecord(d, kind, vehicle_id, stamp_ns));
}

}  // namespace magnav::dds
