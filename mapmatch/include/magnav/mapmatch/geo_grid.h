// A geomagnetic map: a regular latitude/longitude grid with one or more named
// value layers (e.g. X_north_nT, F_nT, anomaly_nT).
//
// Frames and units: latitude and longitude in degrees (WGS84), treated as a
// plane (the matchers of METHODS.md §4–5 work in degree units); values in
// nanotesla (nT); gradients in nT per degree. Node (i, j) is at latitude
// lat_first_deg + i·lat_step_deg and longitude lon_first_deg + j·lon_step_deg;
// values are stored row-major, latitude index slowest.
//
// A query is either inside the grid (its bilinear value and gradient) or
// outside it (std::nullopt): every matcher counts such points and leaves them
// out of its fit — a path may leave the map.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace magnav::mapmatch {

// One regular axis of the grid: count ≥ 2 nodes, first value, step > 0 (deg).
struct GridAxis {
  double first_deg = 0.0;
  double step_deg = 1.0;
  int count = 2;

  double at(int i) const { return first_deg + step_deg * i; }
  double last_deg() const { return at(count - 1); }
};

// Bilinear value of a layer at a point and its gradient.
struct MapSample {
  double value_nT = 0.0;
  double dvalue_dlat_nT_per_deg = 0.0;
  double dvalue_dlon_nT_per_deg = 0.0;
};

class GeoGrid {
 public:
  // values[layer] holds lat.count × lon.count finite values, latitude index
  // slowest. Throws InputError on a size mismatch, a non-finite value, an
  // axis with fewer than 2 nodes or a non-positive step, duplicate names.
  GeoGrid(GridAxis lat, GridAxis lon, std::vector<std::string> layer_names,
          std::vector<std::vector<double>> values);

  // A one-layer grid from a function value_nT(lat_deg, lon_deg) (tests,
  // benchmarks, synthetic maps).
  static GeoGrid FromFunction(GridAxis lat, GridAxis lon, const std::string& layer_name,
                              const std::function<double(double, double)>& value_nT);

  const GridAxis& lat() const { return lat_; }
  const GridAxis& lon() const { return lon_; }
  std::size_t num_nodes() const { return static_cast<std::size_t>(lat_.count) * lon_.count; }
  const std::vector<std::string>& layer_names() const { return names_; }
  // Index of a layer; throws InputError "no layer 'NAME' (layers: ...)".
  std::size_t layer(std::string_view name) const;
  const std::vector<double>& values(std::size_t layer) const { return values_[layer]; }
  double node(std::size_t layer, int i_lat, int j_lon) const {
    return values_[layer][static_cast<std::size_t>(i_lat) * lon_.count + j_lon];
  }
  // Smallest and largest value of a layer (nT).
  double min_value(std::size_t layer) const { return min_[layer]; }
  double max_value(std::size_t layer) const { return max_[layer]; }
  // RMS of |∇value| over the grid cells (nT/deg), a scale of the layer.
  double rms_gradient_nT_per_deg(std::size_t layer) const;

  // Inside the closed rectangle of the nodes (a query exactly on the edge is inside).
  bool Contains(double lat_deg, double lon_deg) const;
  // Bilinear value and gradient, or nullopt outside the grid (or a NaN query).
  std::optional<MapSample> Sample(std::size_t layer, double lat_deg, double lon_deg) const;

 private:
  GridAxis lat_, lon_;
  std::vector<std::string> names_;
  std::vector<std::vector<double>> values_;
  std::vector<double> min_, max_;
};

// Reads a map from CSV (core/csv.h format): the latitude and longitude columns
// and the named value columns, any row order. The nodes must form a complete
// regular grid: an irregular spacing, a missing node (hole), a node given twice,
// a NaN value or a missing column is an InputError naming file, line and column.
GeoGrid ReadGeoGridCsv(const std::string& path, const std::vector<std::string>& value_columns,
                       const std::string& lat_column = "lat", const std::string& lon_column = "lon");

// Reads NGDC-style whitespace text: one "lon lat value" node per line ('#'
// comment and blank lines skipped), any order; the one layer is named
// `layer_name`. Same checks and errors as ReadGeoGridCsv.
GeoGrid ReadGeoGridXyz(const std::string& path, const std::string& layer_name);

// Whether this build reads raster maps (built with GDAL: MAGNAV_WITH_GDAL).
bool RasterMapsSupported();

// Reads a raster map through GDAL: GeoTIFF, NetCDF (CF lat/lon grids) and the
// other raster formats GDAL knows. Each layer is a NetCDF variable
// (subdataset ...:NAME), or a band whose description is NAME, or the only band
// of a one-band file. The raster must be north-up on a latitude/longitude grid
// (no rotation, no projection); its pixel centres are the nodes; a no-data or
// NaN pixel is a hole (InputError naming layer, row, column and position);
// all layers must share one grid. Values are taken as nT. Without GDAL it
// throws InputError saying so.
GeoGrid ReadGeoGridRaster(const std::string& path, const std::vector<std::string>& layers);

// By the file's ending: *.csv (ReadGeoGridCsv, columns lat, lon), *.xyz and
// *.txt (ReadGeoGridXyz, one layer), anything else a raster (ReadGeoGridRaster).
GeoGrid ReadGeoGridFile(const std::string& path, const std::vector<std::string>& layers);

}  // namespace magnav::mapmatch
