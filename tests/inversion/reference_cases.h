// The static single-sample cases of tests/data/reference/dipole_cases.csv,
// with truth, as the inversion tests use them.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "magnav/core/gradiometer.h"

namespace magnav::inversion::testing {

struct DipoleCase {
  long long id = 0;
  int kind = 0;                  // 0 regular, 1 far, 2 near-equatorial, 3 near-axial
  Eigen::Vector3d p_DinW;        // true dipole position, m
  Eigen::Vector3d m_W;           // true moment, A·m²
  GradiometerSample clean;       // noise-free B, T
  GradiometerSample noisy;       // Bn_*, Tn* (fluxgate level) with sigma_B, sigma_T set
  Eigen::Vector3d r_DtoS() const { return clean.p_SinW - p_DinW; }
};

// Noise levels of the noisy columns (reference README: fluxgate level).
inline constexpr double kCaseSigmaB = 1e-9;    // T
inline constexpr double kCaseSigmaT = 1.4e-9;  // T/m

std::vector<DipoleCase> LoadDipoleCases();

// q-quantile (0..1) by linear interpolation of the sorted values.
double Quantile(std::vector<double> values, double q);

}  // namespace magnav::inversion::testing
