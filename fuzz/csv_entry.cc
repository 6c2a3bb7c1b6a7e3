// FuzzCsv: the CSV reader and the typed readers built on it (entries.h).
#include <cstdlib>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "entries.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/localizer/input.h"
#include "magnav/mapmatch/path.h"
#include "mem_file.h"

namespace magnav::fuzz {
namespace {

// Well-formed companions (as tests/data/bad/*_ok.csv) for the readers that
// take several files, so that the fuzzed one is read past the others.
constexpr const char* kDeployment = "sensor_id,x,y,z,sigma_xy\n1,0,0,20,5\n2,40,0,20,5\n";
constexpr const char* kMeasurements =
    "# moment_body_Am2: 0, 0, 1e5\n# vessel_z_m: 0\n# sigma_B_T: 1e-10\nt,sensor_id,B_x,B_y,B_z\n"
    "0,1,1e-09,2e-09,3e-09\n0,2,1e-09,2e-09,3e-09\n1,1,1e-09,2e-09,3e-09\n1,2,1e-09,2e-09,3e-09\n";
constexpr const char* kGnss = "t,x,y,sigma\n0,0,0,1\n1,5,0,1\n";

template <class F>
void Refused(F&& f) {
  try {
    f();
  } catch (const InputError&) {
  }
}

// Every accessor of a parsed table, every field and parameter.
void Walk(const CsvTable& t) {
  for (const auto& name : t.header()) {
    if (t.column(name) >= t.header().size()) std::abort();
  }
  for (std::size_t r = 0; r < t.num_rows(); ++r) {
    (void)t.line_of(r);
    for (std::size_t c = 0; c < t.header().size(); ++c) {
      Refused([&] { (void)t.number(r, c); });
      Refused([&] { (void)t.integer(r, c); });
      Refused([&] { (void)t.uint32(r, c); });
      // A number read back from its shortest form is the same number.
      if (const auto v = ParseNumber(t.text(r, c))) {
        const auto again = ParseNumber(FormatNumber(*v));
        if (!again || *again != *v) std::abort();
      }
      (void)ParseNumberList(t.text(r, c));
    }
  }
  for (const auto& param : t.params()) {
    const std::string& key = param.first;
    Refused([&] { (void)t.param_numbers(key); });
    Refused([&] { (void)t.param_numbers(key, 3); });
    Refused([&] { (void)t.param_vec3(key); });
    Refused([&] { (void)t.param_number(key); });
  }
}

}  // namespace

void FuzzCsv(const std::uint8_t* data, std::size_t size) {
  static MemFile input;
  static MemFile deployment(kDeployment), measurements(kMeasurements), gnss(kGnss);
  const std::string_view text = AsText(data, size);
  Refused([&] { Walk(CsvTable::Parse(text, "fuzz")); });

  const std::string& path = input.Write(text);
  Refused([&] { (void)ReadGradiometerFile(path); });
  Refused([&] { (void)ReadGradiometerFile(path, GradiometerColumns{"Bn_", "Tn"}); });
  Refused([&] { mapmatch::ReadMatchPath(path, "meas_nT").Check(); });
  Refused([&] { (void)localizer::ReadDeploymentFile(path); });
  const Eigen::Vector3d moment(0, 0, 1e5);
  Refused([&] { (void)localizer::ReadPassFiles(path, deployment.path(), gnss.path(), std::nullopt); });
  Refused([&] { (void)localizer::ReadPassFiles(path, deployment.path(), "", moment); });
  Refused([&] { (void)localizer::ReadPassFiles(measurements.path(), path, gnss.path(), std::nullopt); });
  Refused([&] {
    (void)localizer::ReadPassFiles(measurements.path(), deployment.path(), path, std::nullopt);
  });
}

}  // namespace magnav::fuzz
