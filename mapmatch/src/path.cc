#include "magnav/mapmatch/path.h"

#include <cmath>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/limits.h"

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
    if (!WithinLimit(kLimitLatitude, lat_deg[i])) {
      throw InputError("path: point k = " + std::to_string(k[i]) + ": latitude " + OutOfRange(kLimitLatitude, lat_deg[i]));
    }
    if (!WithinLimit(kLimitLongitude, lon_deg[i])) {
      throw InputError("path: point k = " + std::to_string(k[i]) + ": longitude " +
                       OutOfRange(kLimitLongitude, lon_deg[i]));
    }
    // A non-finite measurement is allowed (left out, counted); a finite one beyond the limit is not a reading.
    if (std::isfinite(measured_nT[i]) && !WithinLimit(kLimitMapValue, measured_nT[i])) {
      throw InputError("path: point k = " + std::to_string(k[i]) + ": measurement " +
                       OutOfRange(kLimitMapValue, measured_nT[i]));
    }
  }
}

MatchPath ReadMatchPath(const std::string& path, const std::string& meas_column) {
  const CsvTable t = CsvTable::Read(path);
  const std::size_t ck = t.column("k"), clat = t.column("ins_lat"), clon = t.column("ins_lon"),
                    cm = t.column(meas_column);
  if (t.num_rows() == 0) throw InputError(path + ": no data rows");
  MatchPath p;
  // The door (core/limits.h): "FILE:LINE: column 'NAME': V UNIT is out of range (...)".
  const auto checked = [&](std::size_t r, std::size_t c, const Limit& limit) {
    const double v = t.number(r, c);
    if (!WithinLimit(limit, v)) {
      throw InputError(path + ":" + std::to_string(t.line_of(r)) + ": column '" + t.header()[c] +
                       "': " + OutOfRange(limit, v));
    }
    return v;
  };
  for (std::size_t r = 0; r < t.num_rows(); ++r) {
    p.k.push_back(t.integer(r, ck));
    p.lat_deg.push_back(checked(r, clat, kLimitLatitude));
    p.lon_deg.push_back(checked(r, clon, kLimitLongitude));
    p.measured_nT.push_back(checked(r, cm, kLimitMapValue));
  }
  return p;
}

std::string MatchResult::BriefReport() const {
  const int n = static_cast<int>(lat_deg.size());
  std::string s = "method " + method + ", iterations " + std::to_string(iterations) + ", score " +
                  FormatNumber(score) + " (" + score_name + "), " +
                  (converged ? std::string("converged") : "not converged: " + reason) + ", used " +
                  std::to_string(points_used) + "/" + std::to_string(n) + ", off map " +
                  std::to_string(points_off_map) + ", bad measurement " + std::to_string(points_bad_measurement) +
                  ", outliers " + std::to_string(points_outlier);
  if (converged && !reason.empty()) s += " (" + reason + ")";
  if (!notes.empty()) s += "; " + notes;
  if (!observability.empty()) s += "; " + observability;
  return s;
}

}  // namespace magnav::mapmatch
