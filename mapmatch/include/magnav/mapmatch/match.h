// One entry point over every matcher (what `magnav match` and the accuracy
// tests run): a method name and every method's options.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

#include "magnav/mapmatch/correlation.h"
#include "magnav/mapmatch/fast_msd.h"
#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/icp.h"
#include "magnav/mapmatch/particle_filter.h"
#include "magnav/mapmatch/path.h"
#include "magnav/mapmatch/point_match.h"

namespace magnav::mapmatch {

enum class Method { kPoint, kIcp, kIccp, kMma, kMad, kMsd, kProd, kNprod, kFastMsd, kPf, kAfpf };

// "point", "icp", "iccp", "mma", "mad", "msd", "prod", "nprod", "fast-msd",
// "pf", "afpf" (the sequential filters of particle_filter.h, run over the path).
const char* MethodName(Method method);
std::optional<Method> ParseMethod(std::string_view name);
// Every method name, separated by '|' (for help texts and errors).
std::string MethodNames();

struct MatchOptions {
  PointMatchOptions point;
  IcpOptions icp;
  IccpOptions iccp;
  MmaOptions mma;
  // metric is set from the method; search_window_deg has no default.
  CorrelationOptions correlation;
  FastMsdOptions fast_msd;
  ParticleFilterOptions particle_filter;  // pf and afpf
};

MatchResult Match(Method method, const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                  const MatchOptions& options);

}  // namespace magnav::mapmatch
