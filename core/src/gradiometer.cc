#include "magnav/core/gradiometer.h"

#include <cmath>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"

namespace magnav {

const char* SampleDefectName(SampleDefect defect) {
  switch (defect) {
    case SampleDefect::kNone:
      return "";
    case SampleDefect::kNonFiniteTime:
      return "non_finite_time";
    case SampleDefect::kNonFinite:
      return "non_finite";
    case SampleDefect::kBadSigma:
      return "bad_sigma";
    case SampleDefect::kZeroTensor:
      return "zero_tensor";
    case SampleDefect::kOutOfRange:
      return "out_of_range";
  }
  return "unknown";
}

SampleDefect CheckSample(const GradiometerSample& s) {
  if (!std::isfinite(s.t_s)) return SampleDefect::kNonFiniteTime;
  if (!s.B.allFinite() || !s.T.allFinite() || !s.p_SinW.allFinite()) return SampleDefect::kNonFinite;
  // ‖T‖ can overflow to inf from finite elements (1e200): as bad as a NaN.
  if (!std::isfinite(s.T.norm()) || !std::isfinite(s.B.norm())) return SampleDefect::kNonFinite;
  const auto sigma_ok = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!sigma_ok(s.sigma_B) || !sigma_ok(s.sigma_T)) return SampleDefect::kBadSigma;
  if (s.p_SinW.cwiseAbs().maxCoeff() > MaxAbs(kLimitPosition) || s.B.cwiseAbs().maxCoeff() > MaxAbs(kLimitB) ||
      s.T.cwiseAbs().maxCoeff() > MaxAbs(kLimitT)) {
    return SampleDefect::kOutOfRange;
  }
  if (s.T.isZero(0.0)) return SampleDefect::kZeroTensor;
  return SampleDefect::kNone;
}

std::string TensorColumnName(const std::string& prefix, int i, int j) {
  std::string name = prefix;
  name += static_cast<char>('0' + i);
  name += static_cast<char>('0' + j);
  return name;
}

std::vector<std::string> GradiometerDataColumns() {
  std::vector<std::string> c = {"sensor_x", "sensor_y", "sensor_z", "B_x", "B_y", "B_z"};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) c.push_back(TensorColumnName("T", i, j));
  }
  return c;
}

namespace {

// Refuses a row whose value `values[i]` (from column `cols[i]`) is beyond
// `limit` (|v|): not a reading in the file's units (1e308, or nT given as T),
// named by line and column.
template <std::size_t N>
void CheckRange(const CsvTable& t, std::size_t row, const std::size_t (&cols)[N], const double* values,
                const Limit& limit) {
  for (std::size_t i = 0; i < N; ++i) {
    if (!WithinLimit(limit, values[i])) {
      throw InputError(t.source() + ":" + std::to_string(t.line_of(row)) + ": column '" + t.header()[cols[i]] +
                       "': " + OutOfRange(limit, values[i]));
    }
  }
}

}  // namespace

GradiometerFile ReadGradiometerFile(const std::string& path, const GradiometerColumns& cols) {
  const CsvTable t = CsvTable::Read(path);
  GradiometerFile f;
  f.path = path;
  f.B0 = t.param_vec3("B0_T");
  f.moment_body = t.param_vec3("moment_body_Am2");
  f.sigma_B = t.param_number("sigma_B_T");
  f.sigma_T = t.param_number("sigma_T_Tpm");
  if (f.sigma_B && *f.sigma_B < 0) throw InputError(path + ": parameter 'sigma_B_T' must be >= 0");
  if (f.sigma_T && *f.sigma_T < 0) throw InputError(path + ": parameter 'sigma_T_Tpm' must be >= 0");

  const std::size_t sx = t.column("sensor_x"), sy = t.column("sensor_y"), sz = t.column("sensor_z");
  const std::size_t s_cols[3] = {sx, sy, sz};
  std::size_t b[3], tt[9];
  const char* axes = "xyz";
  for (int i = 0; i < 3; ++i) b[i] = t.column(cols.B + axes[i]);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) tt[3 * i + j] = t.column(TensorColumnName(cols.T, i, j));
  }
  const auto c_t = t.find_column("t");
  const auto c_id = t.find_column("sensor_id");
  const auto c_case = t.find_column("case_id");
  // Per-row noise (magnav record writes it): overrides the file parameters.
  const auto c_sigma_B = t.find_column("sigma_B"), c_sigma_T = t.find_column("sigma_T");
  if (!c_t && !c_case) {
    try {
      t.column("t");
    } catch (const InputError& e) {
      throw InputError(std::string(e.what()) + "; a pass needs its time column 't' (s), a file of independent cases "
                                               "its 'case_id'");
    }
  }
  f.has_time = c_t.has_value();
  f.has_sensor_id = c_id.has_value();

  f.samples.reserve(t.num_rows());
  f.lines.reserve(t.num_rows());
  for (std::size_t r = 0; r < t.num_rows(); ++r) {
    GradiometerSample s;
    if (c_id) s.sensor_id = t.uint32(r, *c_id);
    s.t_s = c_t ? t.number(r, *c_t) : 0.0;
    s.p_SinW = {t.number(r, sx), t.number(r, sy), t.number(r, sz)};
    for (int i = 0; i < 3; ++i) s.B[i] = t.number(r, b[i]);
    for (int k = 0; k < 9; ++k) s.T(k / 3, k % 3) = t.number(r, tt[k]);
    s.sigma_B = c_sigma_B ? t.number(r, *c_sigma_B) : f.sigma_B.value_or(0.0);
    s.sigma_T = c_sigma_T ? t.number(r, *c_sigma_T) : f.sigma_T.value_or(0.0);
    if (!(s.sigma_B >= 0.0) || !(s.sigma_T >= 0.0)) {
      throw InputError(path + ":" + std::to_string(t.line_of(r)) + ": sigma_B and sigma_T must be >= 0");
    }
    double T_values[9];
    for (int k = 0; k < 9; ++k) T_values[k] = s.T(k / 3, k % 3);
    CheckRange(t, r, s_cols, s.p_SinW.data(), kLimitPosition);
    CheckRange(t, r, b, s.B.data(), kLimitB);
    CheckRange(t, r, tt, T_values, kLimitT);
    if (c_case) f.case_ids.push_back(t.integer(r, *c_case));
    f.samples.push_back(s);
    f.lines.push_back(t.line_of(r));
  }
  return f;
}

}  // namespace magnav
