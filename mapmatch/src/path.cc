#include "magnav/mapmatch/path.h"

#include <cmath>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"

namespace magnav::mapmatch {

void MatchPath::Check() const {
  if (lat_deg.empty()) throw InputError("path: no points");
  if (lon_deg.size() != size() || measured_nT.size() != size() || k.size() != size()) {
    throw InputError("path: k, lat, lon and measurement differ in length");
  }
  for (std::size_t i = 0; i < size(); ++i) {
    if (!std::isfinite(lat_deg[i]) || !std::isfinite(lon_deg[i])) {
      throw InputError("path: point k = " + std::to_string(k[i]) + " has a non-finite position");
    }
  }
}

MatchPath ReadMatchPath(const std::string& path, const std::string& meas_column) {
  const CsvTable t = CsvTable::Read(path);
  const std::size_t ck = t.column("k"), clat = t.column("ins_lat"), clon = t.column("ins_lon"),
                    cm = t.column(meas_column);
  if (t.num_rows() == 0) throw InputError(path + ": no data rows");
  MatchPath p;
  for (std::size_t r = 0; r < t.num_rows(); ++r) {
    p.k.push_back(t.integer(r, ck));
    p.lat_deg.push_back(t.number(r, clat));
    p.lon_deg.push_back(t.number(r, clon));
    p.measured_nT.push_back(t.number(r, cm));
  }
  return p;
}

std::string MatchResult::BriefReport() const {
  const int n = static_cast<int>(lat_deg.size());
  std::string s = "method " + method + ", iterations " + std::to_string(iterations) + ", score " +
                  FormatNumber(score) + " (" + score_name + "), " +
                  (converged ? std::string("converged") : "not converged: " + reason) + ", used " +
                  std::to_string(points_used) + "/" + std::to_string(n) + ", off map " +
                  std::to_string(points_off_map) + ", bad measurement " + std::to_string(points_bad_measurement);
  if (converged && !reason.empty()) s += " (" + reason + ")";
  if (!notes.empty()) s += "; " + notes;
  return s;
}

}  // namespace magnav::mapmatch
