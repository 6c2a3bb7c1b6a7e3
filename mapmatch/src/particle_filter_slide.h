// The offset-slide test (ParticleFilterOptions::offset_slide_*, particle_filter.h): a status rule
// of MatchParticleFilter, fed every step of a run. Units as in particle_filter.h (deg, deg²).
#pragma once

#include <cstddef>
#include <deque>

#include "magnav/mapmatch/particle_filter.h"

namespace magnav::mapmatch::internal {

class OffsetSlideTest {
 public:
  explicit OffsetSlideTest(const ParticleFilterOptions& o) : window_(static_cast<std::size_t>(o.offset_slide_updates)) {}
  // One step: the INS position given to the filter, the step's diagnostics, and the filter's
  // re-initialisations so far (a new one restarts the window, as does an INS jump).
  void Add(double ins_lat_deg, double ins_lon_deg, const StepDiagnostics& d, int reinitialisations);
  // χ² of the estimate's offset from the INS over the last offset_slide_updates updates up to the
  // last step added (0 when off or fewer updates since the last restart), and that offset's change (m).
  double Chi2() const;
  double SlideMetres() const;

 private:
  struct Mark {
    double off_lat = 0.0, off_lon = 0.0;           // x̂ − ins (deg)
    double cll = 0.0, cln = 0.0, cnn = 0.0;        // the cloud's covariance (deg²)
    double q = 0.0;                                // Σ drift_sigma_deg² since the restart (deg²)
    double lat = 0.0;                              // the estimate's latitude (deg), for metres
  };
  std::size_t window_;
  std::deque<Mark> updates_;  // the last window_ updates since the restart
  Mark last_;                 // the last step
  bool have_last_ = false;
  double q_ = 0.0;
  int reinitialisations_ = 0;
};

}  // namespace magnav::mapmatch::internal
