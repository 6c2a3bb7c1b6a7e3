#include "magnav/mapmatch/geo_grid.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/limits.h"

namespace magnav::mapmatch {
namespace {

std::string Num(double v) { return FormatNumber(v); }

// The door (core/limits.h): "WHERE: column 'NAME': V UNIT is out of range (...)".
void CheckLimit(const Limit& limit, double value, const std::string& where, const std::string& column,
                const char* field_word = "column") {
  if (!WithinLimit(limit, value)) {
    throw InputError(where + ": " + field_word + " '" + column + "': " + OutOfRange(limit, value));
  }
}

// One node as read from a file, with the line it came from.
struct FileNode {
  double lat_deg, lon_deg;
  int line;
  std::vector<double> values;
};

// The regular axis through a set of coordinates; throws naming the first gap
// that is not one step (an irregular grid or a missing row/column).
GridAxis RegularAxis(std::vector<double> v, const std::string& source, const std::string& what) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  if (v.size() < 2) {
    throw InputError(source + ": the map needs at least 2 distinct " + what + " values, found " +
                     std::to_string(v.size()));
  }
  // Coordinates of ±1e308 are finite, their span is not: the step would be
  // inf and every node's place NaN (an index far outside the grid).
  if (!std::isfinite(v.back() - v.front())) {
    throw InputError(source + ": " + what + " values from " + Num(v.front()) + " to " + Num(v.back()) +
                     " span more than a double holds: not map coordinates in degrees");
  }
  GridAxis a;
  a.first_deg = v.front();
  a.count = static_cast<int>(v.size());
  a.step_deg = (v.back() - v.front()) / (a.count - 1);
  // Smallest gap: a regular grid has all gaps equal; a missing row shows as a
  // double gap, an irregular one as unequal gaps.
  double min_gap = std::numeric_limits<double>::infinity();
  for (std::size_t k = 1; k < v.size(); ++k) min_gap = std::min(min_gap, v[k] - v[k - 1]);
  const double tol = 1e-6 * min_gap;
  for (std::size_t k = 1; k < v.size(); ++k) {
    const double gap = v[k] - v[k - 1];
    if (std::abs(gap - min_gap) > tol) {
      throw InputError(source + ": irregular " + what + " spacing: " + Num(v[k - 1]) + " -> " + Num(v[k]) +
                       " (step " + Num(gap) + ") where the smallest step is " + Num(min_gap) +
                       " (an irregular grid or a missing row of nodes)");
    }
  }
  return a;  // step = (last - first) / (count - 1): the rounding of each node averages out
}

GeoGrid BuildGrid(const std::vector<FileNode>& nodes, std::vector<std::string> names, const std::string& source) {
  if (nodes.empty()) throw InputError(source + ": no map nodes");
  std::vector<double> lats, lons;
  lats.reserve(nodes.size());
  lons.reserve(nodes.size());
  for (const FileNode& n : nodes) {
    lats.push_back(n.lat_deg);
    lons.push_back(n.lon_deg);
  }
  const GridAxis lat = RegularAxis(lats, source, "latitude");
  const GridAxis lon = RegularAxis(lons, source, "longitude");
  const std::size_t n_nodes = static_cast<std::size_t>(lat.count) * lon.count;
  // The grid place of every node, sorted, with the node's number in the file:
  // a node given twice and a hole are found from the nodes alone. The grid is
  // allocated only once it is known to be complete, so it is never larger
  // than the file (n nodes on a diagonal span an n x n grid: 20 000 of them
  // asked for 3 GB before).
  std::vector<std::pair<std::size_t, std::size_t>> place;  // (grid index, node)
  place.reserve(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const FileNode& n = nodes[k];
    const double fi = std::round((n.lat_deg - lat.first_deg) / lat.step_deg);
    const double fj = std::round((n.lon_deg - lon.first_deg) / lon.step_deg);
    if (!(fi >= 0 && fi < lat.count && fj >= 0 && fj < lon.count)) {  // also NaN; RegularAxis rules it out
      throw InputError(source + ":" + std::to_string(n.line) + ": node lat " + Num(n.lat_deg) + ", lon " +
                       Num(n.lon_deg) + " is not on the grid");
    }
    place.emplace_back(static_cast<std::size_t>(fi) * lon.count + static_cast<std::size_t>(fj), k);
  }
  std::sort(place.begin(), place.end());
  // A node given twice: the first, in file order, whose place an earlier node took.
  std::size_t twice = nodes.size(), first = 0;
  for (std::size_t m = 1; m < place.size(); ++m) {
    const bool second_of_place =
        place[m].first == place[m - 1].first && (m < 2 || place[m - 2].first != place[m].first);
    if (second_of_place && place[m].second < twice) {
      twice = place[m].second;
      first = place[m - 1].second;
    }
  }
  if (twice < nodes.size()) {
    const FileNode& n = nodes[twice];
    throw InputError(source + ":" + std::to_string(n.line) + ": node lat " + Num(n.lat_deg) + ", lon " +
                     Num(n.lon_deg) + " given twice (first on line " + std::to_string(nodes[first].line) +
                     ")");
  }
  if (nodes.size() != n_nodes) {  // fewer: the first grid place no node took
    std::size_t idx = 0;
    while (idx < place.size() && place[idx].first == idx) ++idx;
    const int i = static_cast<int>(idx / lon.count), j = static_cast<int>(idx % lon.count);
    throw InputError(source + ": hole in the map: no node at lat " + Num(lat.at(i)) + ", lon " +
                     Num(lon.at(j)) + " (" + std::to_string(nodes.size()) + " nodes for a " +
                     std::to_string(lat.count) + " x " + std::to_string(lon.count) + " grid)");
  }
  std::vector<std::vector<double>> values(names.size(), std::vector<double>(n_nodes, 0.0));
  for (const auto& [idx, k] : place) {
    for (std::size_t l = 0; l < names.size(); ++l) values[l][idx] = nodes[k].values[l];
  }
  return GeoGrid(lat, lon, std::move(names), std::move(values));
}

bool IsNanText(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '-' || s.front() == '+')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\r')) s.remove_suffix(1);
  std::string low(s);
  for (char& c : low) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return low == "nan" || low == "inf" || low == "infinity";
}

std::string Hole(const std::string& where, const std::string& column, double lat, double lon) {
  return where + ": column '" + column + "': no value (NaN or inf) at lat " + Num(lat) + ", lon " + Num(lon) +
         ": the map has a hole; fill or crop it";
}

}  // namespace

GeoGrid::GeoGrid(GridAxis lat, GridAxis lon, std::vector<std::string> layer_names,
                 std::vector<std::vector<double>> values)
    : lat_(lat), lon_(lon), names_(std::move(layer_names)), values_(std::move(values)) {
  if (lat_.count < 2 || lon_.count < 2) throw InputError("map: needs at least 2 x 2 nodes");
  if (!(lat_.step_deg > 0.0) || !(lon_.step_deg > 0.0) || !std::isfinite(lat_.first_deg) ||
      !std::isfinite(lon_.first_deg)) {
    throw InputError("map: grid steps must be > 0 and the origin finite");
  }
  if (names_.empty() || names_.size() != values_.size()) throw InputError("map: one name per layer needed");
  for (const auto& [axis, limit] : {std::pair{&lat_, &kLimitLatitude}, std::pair{&lon_, &kLimitLongitude}}) {
    if (!WithinLimit(*limit, axis->first_deg) || !WithinLimit(*limit, axis->last_deg())) {
      throw InputError("map: " + std::string(limit->quantity) + " axis " + Num(axis->first_deg) + " .. " +
                       Num(axis->last_deg()) + " deg: " + OutOfRange(*limit, !WithinLimit(*limit, axis->first_deg)
                                                                                     ? axis->first_deg
                                                                                     : axis->last_deg()));
    }
  }
  for (std::size_t l = 0; l < names_.size(); ++l) {
    if (std::count(names_.begin(), names_.end(), names_[l]) != 1) {
      throw InputError("map: layer '" + names_[l] + "' given twice");
    }
    if (values_[l].size() != num_nodes()) {
      throw InputError("map: layer '" + names_[l] + "' has " + std::to_string(values_[l].size()) +
                       " values for " + std::to_string(num_nodes()) + " nodes");
    }
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t k = 0; k < values_[l].size(); ++k) {
      const double v = values_[l][k];
      if (!std::isfinite(v)) {
        throw InputError(Hole("map", names_[l], lat_.at(static_cast<int>(k / lon_.count)),
                              lon_.at(static_cast<int>(k % lon_.count))));
      }
      if (!WithinLimit(kLimitMapValue, v)) {
        throw InputError("map: layer '" + names_[l] + "' at lat " + Num(lat_.at(static_cast<int>(k / lon_.count))) +
                         ", lon " + Num(lon_.at(static_cast<int>(k % lon_.count))) + ": " +
                         OutOfRange(kLimitMapValue, v));
      }
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    min_.push_back(lo);
    max_.push_back(hi);
  }
}

GeoGrid GeoGrid::FromFunction(GridAxis lat, GridAxis lon, const std::string& layer_name,
                              const std::function<double(double, double)>& value_nT) {
  std::vector<double> v(static_cast<std::size_t>(lat.count) * lon.count);
  for (int i = 0; i < lat.count; ++i) {
    for (int j = 0; j < lon.count; ++j) v[static_cast<std::size_t>(i) * lon.count + j] = value_nT(lat.at(i), lon.at(j));
  }
  return GeoGrid(lat, lon, {layer_name}, {std::move(v)});
}

std::size_t GeoGrid::layer(std::string_view name) const {
  for (std::size_t l = 0; l < names_.size(); ++l) {
    if (names_[l] == name) return l;
  }
  std::string all;
  for (const auto& n : names_) all += (all.empty() ? "" : ", ") + n;
  throw InputError("map: no layer '" + std::string(name) + "' (layers: " + all + ")");
}

double GeoGrid::rms_gradient_nT_per_deg(std::size_t layer) const {
  double sum = 0.0;
  for (int i = 0; i + 1 < lat_.count; ++i) {
    for (int j = 0; j + 1 < lon_.count; ++j) {
      const double glat = (node(layer, i + 1, j) - node(layer, i, j)) / lat_.step_deg;
      const double glon = (node(layer, i, j + 1) - node(layer, i, j)) / lon_.step_deg;
      sum += glat * glat + glon * glon;
    }
  }
  return std::sqrt(sum / ((lat_.count - 1.0) * (lon_.count - 1.0)));
}

bool GeoGrid::Contains(double lat_deg, double lon_deg) const {
  const double fi = (lat_deg - lat_.first_deg) / lat_.step_deg;
  const double fj = (lon_deg - lon_.first_deg) / lon_.step_deg;
  constexpr double kEdge = 1e-9;  // a query on the last node, up to rounding, is inside
  return fi >= -kEdge && fj >= -kEdge && fi <= lat_.count - 1 + kEdge && fj <= lon_.count - 1 + kEdge;
}

std::optional<MapSample> GeoGrid::Sample(std::size_t layer, double lat_deg, double lon_deg) const {
  if (!Contains(lat_deg, lon_deg)) return std::nullopt;  // also NaN
  const double fi = (lat_deg - lat_.first_deg) / lat_.step_deg;
  const double fj = (lon_deg - lon_.first_deg) / lon_.step_deg;
  const int i = std::clamp(static_cast<int>(std::floor(fi)), 0, lat_.count - 2);
  const int j = std::clamp(static_cast<int>(std::floor(fj)), 0, lon_.count - 2);
  const double u = fi - i, v = fj - j;
  const double* row0 = values_[layer].data() + static_cast<std::size_t>(i) * lon_.count + j;
  const double* row1 = row0 + lon_.count;
  const double v00 = row0[0], v01 = row0[1], v10 = row1[0], v11 = row1[1];
  MapSample s;
  s.value_nT = (1 - u) * ((1 - v) * v00 + v * v01) + u * ((1 - v) * v10 + v * v11);
  s.dvalue_dlat_nT_per_deg = ((1 - v) * (v10 - v00) + v * (v11 - v01)) / lat_.step_deg;
  s.dvalue_dlon_nT_per_deg = ((1 - u) * (v01 - v00) + u * (v11 - v10)) / lon_.step_deg;
  return s;
}

GeoGrid ReadGeoGridCsv(const std::string& path, const std::vector<std::string>& value_columns,
                       const std::string& lat_column, const std::string& lon_column) {
  if (value_columns.empty()) throw InputError(path + ": no value column chosen");
  const CsvTable t = CsvTable::Read(path);
  const std::size_t c_lat = t.column(lat_column), c_lon = t.column(lon_column);
  std::vector<std::size_t> cols;
  for (const auto& name : value_columns) cols.push_back(t.column(name));
  std::vector<FileNode> nodes;
  nodes.reserve(t.num_rows());
  for (std::size_t r = 0; r < t.num_rows(); ++r) {
    FileNode n{t.number(r, c_lat), t.number(r, c_lon), t.line_of(r), {}};
    const std::string where = path + ":" + std::to_string(t.line_of(r));
    CheckLimit(kLimitLatitude, n.lat_deg, where, lat_column);
    CheckLimit(kLimitLongitude, n.lon_deg, where, lon_column);
    for (std::size_t l = 0; l < cols.size(); ++l) {
      if (IsNanText(t.text(r, cols[l]))) {
        throw InputError(Hole(path + ":" + std::to_string(t.line_of(r)), value_columns[l], n.lat_deg, n.lon_deg));
      }
      n.values.push_back(t.number(r, cols[l]));
      CheckLimit(kLimitMapValue, n.values.back(), where, value_columns[l]);
    }
    nodes.push_back(std::move(n));
  }
  return BuildGrid(nodes, value_columns, path);
}

GeoGrid ReadGeoGridXyz(const std::string& path, const std::string& layer_name) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  std::vector<FileNode> nodes;
  std::string line;
  int line_no = 0;
  static const char* kField[3] = {"lon", "lat", "value"};
  while (std::getline(in, line)) {
    ++line_no;
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ss(line);
    std::string f[3], extra;
    double v[3];
    for (int k = 0; k < 3; ++k) {
      if (!(ss >> f[k])) {
        throw InputError(path + ":" + std::to_string(line_no) + ": expected 'lon lat value', field '" + kField[k] +
                         "' missing");
      }
      if (k == 2 && IsNanText(f[k])) throw InputError(Hole(path + ":" + std::to_string(line_no), layer_name, v[1], v[0]));
      const auto x = ParseNumber(f[k]);
      if (!x) {
        throw InputError(path + ":" + std::to_string(line_no) + ": field '" + kField[k] + "': '" + f[k] +
                         "' is not a number");
      }
      v[k] = *x;
      static const Limit* kLimit[3] = {&kLimitLongitude, &kLimitLatitude, &kLimitMapValue};
      CheckLimit(*kLimit[k], v[k], path + ":" + std::to_string(line_no), kField[k], "field");
    }
    if (ss >> extra) {
      throw InputError(path + ":" + std::to_string(line_no) + ": more than 3 fields (expected 'lon lat value')");
    }
    nodes.push_back(FileNode{v[1], v[0], line_no, {v[2]}});
  }
  if (nodes.empty()) throw InputError(path + ": empty file (no 'lon lat value' lines)");
  return BuildGrid(nodes, {layer_name}, path);
}

}  // namespace magnav::mapmatch
