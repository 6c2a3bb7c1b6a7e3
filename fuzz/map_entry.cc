// FuzzMap: the map readers of mapmatch (entries.h).
#include <cmath>
#include <cstdlib>
#include <string>

#include "entries.h"
#include "magnav/core/error.h"
#include "magnav/mapmatch/geo_grid.h"
#include "mem_file.h"

namespace magnav::fuzz {
namespace {

// A map that was read answers queries: at nodes, cell centres, just outside
// and at NaN, with finite values inside and nothing outside.
void Probe(const mapmatch::GeoGrid& g) {
  const auto& lat = g.lat();
  const auto& lon = g.lon();
  if (lat.count < 2 || lon.count < 2 || !(lat.step_deg > 0) || !(lon.step_deg > 0)) std::abort();
  for (std::size_t l = 0; l < g.layer_names().size(); ++l) {
    if (g.values(l).size() != g.num_nodes()) std::abort();
    (void)g.rms_gradient_nT_per_deg(l);
    const int is[] = {0, lat.count / 2, lat.count - 1};
    const int js[] = {0, lon.count / 2, lon.count - 1};
    for (int i : is) {
      for (int j : js) {
        (void)g.node(l, i, j);
        const auto s = g.Sample(l, lat.at(i), lon.at(j));
        if (s && !std::isfinite(s->value_nT) && std::isfinite(lat.step_deg) && std::isfinite(lon.step_deg) &&
            std::isfinite(g.max_value(l) - g.min_value(l))) {
          std::abort();
        }
        (void)g.Sample(l, lat.at(i) + 0.5 * lat.step_deg, lon.at(j) + 0.5 * lon.step_deg);
      }
    }
    if (g.Sample(l, lat.first_deg - lat.step_deg, lon.first_deg)) std::abort();
    if (g.Sample(l, std::nan(""), lon.first_deg)) std::abort();
  }
}

template <class F>
void Refused(F&& f) {
  try {
    f();
  } catch (const InputError&) {
  }
}

}  // namespace

void FuzzMap(const std::uint8_t* data, std::size_t size) {
  static MemFile input;
  const std::string& path = input.Write(AsText(data, size));
  Refused([&] { Probe(mapmatch::ReadGeoGridCsv(path, {"F_nT"})); });
  Refused([&] { Probe(mapmatch::ReadGeoGridCsv(path, {"F_nT", "X_north_nT"})); });
  Refused([&] { Probe(mapmatch::ReadGeoGridXyz(path, "F_nT")); });
}

}  // namespace magnav::fuzz
