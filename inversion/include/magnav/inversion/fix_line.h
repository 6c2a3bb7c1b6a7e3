// Least-squares constant-velocity line through dipole fixes, the starting
// guess of both trackers (the Monte-Carlo filter's prior, the tracker's
// initial trajectory). World NED, metres, seconds.
#pragma once

#include <vector>

#include "magnav/inversion/inverter.h"

namespace magnav::inversion {

struct FixLine {
  double t_ref_s = 0.0;          // mean time of the fixes used
  Vec3 p_ref = Vec3::Zero();     // mean position, m
  Vec3 v = Vec3::Zero();         // velocity, m/s (0 when the fixes span no time)
  bool has_velocity = false;     // the fixes used span some time
  Vec3 At(double t_s) const { return p_ref + v * (t_s - t_ref_s); }
};

// Fits p(t) = p_ref + v (t − t_ref) by least squares, per axis, to the fixes
// selected by `use` (all when empty). At least one fix must be selected.
FixLine FitFixLine(const std::vector<DipoleFix>& fixes, const std::vector<bool>& use = {});

}  // namespace magnav::inversion
