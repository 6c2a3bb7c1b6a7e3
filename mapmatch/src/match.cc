#include "magnav/mapmatch/match.h"

#include <array>
#include <utility>

namespace magnav::mapmatch {
namespace {

constexpr std::array<std::pair<Method, const char*>, 11> kMethods = {{{Method::kPoint, "point"},
                                                                     {Method::kIcp, "icp"},
                                                                     {Method::kIccp, "iccp"},
                                                                     {Method::kMma, "mma"},
                                                                     {Method::kMad, "mad"},
                                                                     {Method::kMsd, "msd"},
                                                                     {Method::kProd, "prod"},
                                                                     {Method::kNprod, "nprod"},
                                                                     {Method::kFastMsd, "fast-msd"},
                                                                     {Method::kPf, "pf"},
                                                                     {Method::kAfpf, "afpf"}}};

MatchResult Correlate(CorrelationMetric metric, const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                      CorrelationOptions options) {
  options.metric = metric;
  return MatchCorrelation(grid, layer, path, options);
}

}  // namespace

const char* MethodName(Method method) {
  for (const auto& [m, name] : kMethods) {
    if (m == method) return name;
  }
  return "?";
}

std::optional<Method> ParseMethod(std::string_view name) {
  for (const auto& [m, n] : kMethods) {
    if (name == n) return m;
  }
  return std::nullopt;
}

std::string MethodNames() {
  std::string s;
  for (const auto& [m, n] : kMethods) {
    if (!s.empty()) s += '|';
    s += n;
  }
  return s;
}

MatchResult Match(Method method, const GeoGrid& grid, std::size_t layer, const MatchPath& path,
                  const MatchOptions& options) {
  switch (method) {
    case Method::kPoint:
      return MatchPoints(grid, layer, path, options.point);
    case Method::kIcp:
      return MatchIcp(grid, layer, path, options.icp);
    case Method::kIccp:
      return MatchIccp(grid, layer, path, options.iccp);
    case Method::kMma:
      return MatchMma(grid, layer, path, options.mma);
    case Method::kMad:
      return Correlate(CorrelationMetric::kMad, grid, layer, path, options.correlation);
    case Method::kMsd:
      return Correlate(CorrelationMetric::kMsd, grid, layer, path, options.correlation);
    case Method::kProd:
      return Correlate(CorrelationMetric::kProd, grid, layer, path, options.correlation);
    case Method::kNprod:
      return Correlate(CorrelationMetric::kNprod, grid, layer, path, options.correlation);
    case Method::kFastMsd:
      return MatchFastMsd(grid, layer, path, options.fast_msd);
    case Method::kPf:
      return MatchParticleFilter(ParticleFilterKind::kPf, grid, layer, path, options.particle_filter);
    case Method::kAfpf:
      return MatchParticleFilter(ParticleFilterKind::kAfpf, grid, layer, path, options.particle_filter);
  }
  return {};
}

}  // namespace magnav::mapmatch
