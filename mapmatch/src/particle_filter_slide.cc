// The offset-slide test (ParticleFilterOptions::offset_slide_*; particle_filter_slide.h).
#include "particle_filter_slide.h"

#include <cmath>

#include "magnav/mapmatch/fix_schedule.h"

namespace magnav::mapmatch::internal {

void OffsetSlideTest::Add(double ins_lat, double ins_lon, const StepDiagnostics& d, int reinitialisations) {
  if (window_ == 0) return;
  // An INS jump (not applied: the offset changes by it) or a re-spread cloud restarts the window.
  if (d.ins_jump || !std::isfinite(ins_lat) || !std::isfinite(ins_lon) || reinitialisations != reinitialisations_) {
    reinitialisations_ = reinitialisations;
    updates_.clear();
    have_last_ = false;
    q_ = 0.0;
    return;
  }
  q_ += d.drift_sigma_deg * d.drift_sigma_deg;
  last_ = {d.lat_deg - ins_lat, d.lon_deg - ins_lon, d.cloud_cov_lat_lat, d.cloud_cov_lat_lon, d.cloud_cov_lon_lon, q_,
           d.lat_deg};
  have_last_ = true;
  if (d.update == StepUpdate::kUpdated) {
    updates_.push_back(last_);
    if (updates_.size() > window_) updates_.pop_front();
  }
}

double OffsetSlideTest::Chi2() const {
  if (window_ == 0 || !have_last_ || updates_.size() < window_) return 0.0;
  const Mark& s = updates_.front();
  const double dl = last_.off_lat - s.off_lat, dn = last_.off_lon - s.off_lon, q = last_.q - s.q;
  const double a = s.cll + last_.cll + q, b = s.cln + last_.cln, c = s.cnn + last_.cnn + q;
  const double det = a * c - b * b;
  if (!(det > 0.0)) return 0.0;
  return (c * dl * dl - 2.0 * b * dl * dn + a * dn * dn) / det;
}

double OffsetSlideTest::SlideMetres() const {
  if (!have_last_ || updates_.empty()) return 0.0;
  const Mark& s = updates_.front();
  return std::hypot((last_.off_lat - s.off_lat) * MetresPerDegreeLat(last_.lat),
                    (last_.off_lon - s.off_lon) * MetresPerDegreeLon(last_.lat));
}

}  // namespace magnav::mapmatch::internal
