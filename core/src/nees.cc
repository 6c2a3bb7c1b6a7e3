#include "magnav/core/nees.h"

#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>

#include <boost/math/distributions/chi_squared.hpp>

namespace magnav {

double ChiSquareQuantile(double probability, double dof) {
  if (probability >= 1.0) return std::numeric_limits<double>::infinity();
  if (!(probability > 0.0) || !(dof > 0.0) || !std::isfinite(dof)) return 0.0;
  return boost::math::quantile(boost::math::chi_squared(dof), probability);
}

NeesInterval RunAveragedNeesInterval(int runs, int dof, double confidence) {
  if (runs < 1 || dof < 1 || !(confidence > 0.0 && confidence < 1.0)) {
    throw std::invalid_argument("RunAveragedNeesInterval: runs >= 1, dof >= 1 and confidence in (0, 1)");
  }
  const boost::math::chi_squared chi2(static_cast<double>(runs) * dof);
  const double a = 0.5 * (1.0 - confidence);
  return {boost::math::quantile(chi2, a) / runs, boost::math::quantile(chi2, 1.0 - a) / runs};
}

std::map<std::string, NeesRegimeStats> ComputeNeesStats(const std::vector<NeesSample>& samples, int dof,
                                                        int min_runs_per_epoch) {
  if (dof < 1) throw std::invalid_argument("ComputeNeesStats: dof >= 1");
  struct Acc {
    double sum_nees = 0.0, sum_e2 = 0.0;
    std::size_t n = 0;
    std::set<long long> runs;
    std::map<long long, std::pair<double, int>> per_epoch;  // epoch -> (sum NEES, runs)
  };
  std::map<std::string, Acc> acc;
  for (const NeesSample& s : samples) {
    for (const std::string& key : {s.regime, std::string("all")}) {
      Acc& a = acc[key];
      a.sum_nees += s.nees;
      a.sum_e2 += s.error_sq;
      ++a.n;
      a.runs.insert(s.run);
      auto& e = a.per_epoch[s.epoch];
      e.first += s.nees;
      ++e.second;
    }
  }
  std::map<std::string, NeesRegimeStats> out;
  const double d = dof;
  for (const auto& [key, a] : acc) {
    NeesRegimeStats r;
    r.samples = a.n;
    r.runs = a.runs.size();
    r.epochs = a.per_epoch.size();
    r.anees = a.sum_nees / static_cast<double>(a.n);
    r.rms = std::sqrt(a.sum_e2 / static_cast<double>(a.n));
    r.anees_accepted = std::isfinite(r.anees) && r.anees >= 0.5 * d && r.anees <= 2.0 * d;
    for (const auto& [epoch, e] : a.per_epoch) {
      if (e.second < min_runs_per_epoch) continue;
      ++r.epochs_tested;
      const NeesInterval in = RunAveragedNeesInterval(e.second, dof);
      const double mean = e.first / e.second;
      if (mean >= in.lo && mean <= in.hi) ++r.epochs_inside;
    }
    out.emplace(key, r);
  }
  return out;
}

}  // namespace magnav
