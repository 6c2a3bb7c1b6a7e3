#include "magnav/inversion/fix_line.h"

namespace magnav::inversion {

FixLine FitFixLine(const std::vector<DipoleFix>& fixes, const std::vector<bool>& use) {
  const auto used = [&](std::size_t i) { return use.empty() || use[i]; };
  FixLine f;
  double n = 0.0;
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    if (!used(i)) continue;
    f.t_ref_s += fixes[i].t_s;
    f.p_ref += fixes[i].p_DinW;
    n += 1.0;
  }
  if (!(n > 0.0)) return f;
  f.t_ref_s /= n;
  f.p_ref /= n;
  double stt = 0.0;
  Vec3 stp = Vec3::Zero();
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    if (!used(i)) continue;
    const double dt = fixes[i].t_s - f.t_ref_s;
    stt += dt * dt;
    stp += dt * (fixes[i].p_DinW - f.p_ref);
  }
  f.has_velocity = stt > 0.0;
  if (f.has_velocity) f.v = stp / stt;
  return f;
}

}  // namespace magnav::inversion
