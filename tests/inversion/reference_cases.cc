#include "reference_cases.h"

#include <algorithm>
#include <cmath>

#include "magnav/core/csv.h"
#include "test_data.h"

namespace magnav::inversion::testing {

std::vector<DipoleCase> LoadDipoleCases() {
  const std::string path = magnav::testing::ReferencePath("dipole_cases.csv");
  const GradiometerFile clean = ReadGradiometerFile(path);
  const GradiometerFile noisy = ReadGradiometerFile(path, GradiometerColumns{"Bn_", "Tn"});
  const CsvTable t = CsvTable::Read(path);
  std::vector<DipoleCase> out(t.num_rows());
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    DipoleCase& c = out[i];
    c.id = clean.case_ids[i];
    c.kind = static_cast<int>(t.integer(i, t.column("case_kind")));
    c.p_DinW = {t.number(i, t.column("dipole_x")), t.number(i, t.column("dipole_y")),
                t.number(i, t.column("dipole_z"))};
    c.m_W = {t.number(i, t.column("m_x")), t.number(i, t.column("m_y")), t.number(i, t.column("m_z"))};
    c.clean = clean.samples[i];
    c.clean.sigma_B = 0.0;  // noise-free columns
    c.clean.sigma_T = 0.0;
    c.noisy = noisy.samples[i];
    c.noisy.sigma_B = kCaseSigmaB;
    c.noisy.sigma_T = kCaseSigmaT;
  }
  return out;
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

}  // namespace magnav::inversion::testing
