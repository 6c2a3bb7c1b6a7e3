// Raster maps through GDAL (GeoTIFF, NetCDF and every raster format GDAL
// reads): an optional build feature (MAGNAV_WITH_GDAL). Without it the reader
// refuses with a message saying how to get it.
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/limits.h"
#include "magnav/mapmatch/geo_grid.h"

#ifdef MAGNAV_WITH_GDAL
#include <gdal.h>
#include <ogr_srs_api.h>
#endif

namespace magnav::mapmatch {

#ifdef MAGNAV_WITH_GDAL

bool RasterMapsSupported() { return true; }

namespace {

struct DatasetCloser {
  void operator()(void* d) const {
    if (d != nullptr) GDALClose(static_cast<GDALDatasetH>(d));
  }
};
using Dataset = std::unique_ptr<void, DatasetCloser>;

Dataset Open(const std::string& name, const std::string& shown_as) {
  GDALAllRegister();
  CPLPushErrorHandler(CPLQuietErrorHandler);
  Dataset d(GDALOpenEx(name.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr));
  CPLPopErrorHandler();
  if (!d) {
    const char* why = CPLGetLastErrorMsg();
    throw InputError(shown_as + ": cannot read as a raster map" + (why && *why ? std::string(" (") + why + ")" : ""));
  }
  return d;
}

// The raster of one layer: a NetCDF-style subdataset named ...:LAYER, else a
// band whose description is LAYER, else the only band of a one-band file.
struct Band {
  Dataset owner;  // the subdataset, when the layer is one
  GDALRasterBandH band = nullptr;
  GDALDatasetH dataset = nullptr;
};

Band FindLayer(GDALDatasetH root, const std::string& path, const std::string& layer) {
  Band out;
  char** subs = GDALGetMetadata(root, "SUBDATASETS");
  for (int i = 0; subs != nullptr && subs[i] != nullptr; ++i) {
    const std::string item = subs[i];  // SUBDATASET_n_NAME=NETCDF:"file":var
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos || item.find("_NAME=") == std::string::npos) continue;
    const std::string name = item.substr(eq + 1);
    if (name.size() > layer.size() && name.ends_with(":" + layer)) {
      out.owner = Open(name, path + " (layer '" + layer + "')");
      out.dataset = static_cast<GDALDatasetH>(out.owner.get());
      if (GDALGetRasterCount(out.dataset) != 1) {
        throw InputError(path + ": layer '" + layer + "' has " + std::to_string(GDALGetRasterCount(out.dataset)) +
                         " bands (a map layer is one 2-D grid)");
      }
      out.band = GDALGetRasterBand(out.dataset, 1);
      return out;
    }
  }
  const int n = GDALGetRasterCount(root);
  std::string names;
  for (int b = 1; b <= n; ++b) {
    GDALRasterBandH h = GDALGetRasterBand(root, b);
    const std::string desc = GDALGetDescription(h);
    if (desc == layer) {
      out.band = h;
      out.dataset = root;
      return out;
    }
    names += (names.empty() ? "" : ", ") + (desc.empty() ? "band " + std::to_string(b) : "'" + desc + "'");
  }
  if (n == 1) {  // one unnamed grid: it is the layer asked for
    out.band = GDALGetRasterBand(root, 1);
    out.dataset = root;
    return out;
  }
  throw InputError(path + ": no layer '" + layer + "' (" + (n == 0 ? std::string("no bands") : names) +
                   (subs != nullptr ? "; subdatasets listed by gdalinfo" : "") + ")");
}

// Node centres of a north-up lat/lon raster: axes ascending, and whether the
// rows run north to south (GeoTIFF) and must be flipped.
struct Geometry {
  GridAxis lat, lon;
  bool flip_rows = false;
  int width = 0, height = 0;
};

// GDAL drivers of rasters stored as text: every cell is written out, so the
// file holds at least kMinTextBytesPerCell bytes per cell.
bool TextRaster(GDALDatasetH d) {
  const GDALDriverH driver = GDALGetDatasetDriver(d);
  if (driver == nullptr) return false;
  const std::string name = GDALGetDriverShortName(driver);
  for (const char* text : {"AAIGrid", "GRASSASCIIGrid", "XYZ", "ISG", "GSAG"}) {
    if (name == text) return true;
  }
  return false;
}

// The grid a header claims, refused before a byte of it is allocated: beyond
// the cap of core/limits.h (kLimitMapCells), or, for a text raster, more cells
// than the file's bytes could hold (a 107-byte .asc header claiming
// 16384 x 16384 cells made the reader allocate 2.1 GB before it failed).
void CheckClaimedSize(GDALDatasetH d, int width, int height, const std::string& where) {
  const double cells = static_cast<double>(width) * static_cast<double>(height);
  const std::string claim = std::to_string(height) + " rows x " + std::to_string(width) + " columns";
  if (cells > MaxAbs(kLimitMapCells)) {
    throw InputError(where + ": the header claims " + claim + " = " + FormatNumber(cells) +
                     " cells, more than the map cap of " + FormatNumber(MaxAbs(kLimitMapCells)) + " (" +
                     LimitWhy(kLimitMapCells) + ")");
  }
  if (TextRaster(d)) {
    std::error_code ec;
    const char* file = GDALGetDescription(d);
    const auto bytes = std::filesystem::file_size(file != nullptr ? file : "", ec);
    if (!ec && cells * kMinTextBytesPerCell > static_cast<double>(bytes)) {
      throw InputError(where + ": the header claims " + claim + " = " + FormatNumber(cells) + " cells, but the file has " +
                       std::to_string(bytes) + " bytes (a text raster needs at least " +
                       FormatNumber(kMinTextBytesPerCell) + " per cell): a truncated file or a wrong header");
    }
  }
}

Geometry GeometryOf(GDALDatasetH d, const std::string& where) {
  double gt[6];
  if (GDALGetGeoTransform(d, gt) != CE_None) throw InputError(where + ": no georeferencing (geotransform)");
  if (gt[2] != 0.0 || gt[4] != 0.0) {
    throw InputError(where + ": rotated or sheared grid (geotransform terms " + std::to_string(gt[2]) + ", " +
                     std::to_string(gt[4]) + "); a map must be a regular north-up lat/lon grid");
  }
  const char* wkt = GDALGetProjectionRef(d);
  if (wkt != nullptr && *wkt != '\0') {
    OGRSpatialReferenceH srs = OSRNewSpatialReference(wkt);
    const bool geographic = srs != nullptr && OSRIsGeographic(srs);
    if (srs != nullptr) OSRDestroySpatialReference(srs);
    if (!geographic) throw InputError(where + ": projected coordinates; a map must be on a latitude/longitude grid");
  }
  Geometry g;
  g.width = GDALGetRasterXSize(d);
  g.height = GDALGetRasterYSize(d);
  if (g.width < 2 || g.height < 2) throw InputError(where + ": a map needs at least 2 x 2 nodes");
  CheckClaimedSize(d, g.width, g.height, where);
  // GDAL's geotransform locates pixel corners; a map node is a pixel centre.
  g.lon = {gt[0] + 0.5 * gt[1], gt[1], g.width};
  if (gt[5] < 0.0) {
    g.flip_rows = true;
    g.lat = {gt[3] + (g.height - 0.5) * gt[5], -gt[5], g.height};
  } else {
    g.lat = {gt[3] + 0.5 * gt[5], gt[5], g.height};
  }
  if (!(g.lon.step_deg > 0.0) || !(g.lat.step_deg > 0.0)) throw InputError(where + ": zero grid step");
  return g;
}

}  // namespace

GeoGrid ReadGeoGridRaster(const std::string& path, const std::vector<std::string>& layers) {
  if (layers.empty()) throw InputError(path + ": no layer chosen");
  Dataset root = Open(path, path);
  std::vector<std::vector<double>> values;
  Geometry geometry;
  for (std::size_t l = 0; l < layers.size(); ++l) {
    const Band b = FindLayer(static_cast<GDALDatasetH>(root.get()), path, layers[l]);
    const Geometry g = GeometryOf(b.dataset, path + " (layer '" + layers[l] + "')");
    if (l == 0) {
      geometry = g;
    } else if (g.width != geometry.width || g.height != geometry.height || g.lat.first_deg != geometry.lat.first_deg ||
               g.lon.first_deg != geometry.lon.first_deg || g.lat.step_deg != geometry.lat.step_deg ||
               g.lon.step_deg != geometry.lon.step_deg) {
      throw InputError(path + ": layer '" + layers[l] + "' is on another grid than '" + layers[0] + "'");
    }
    std::vector<double> raw(static_cast<std::size_t>(g.width) * g.height);
    if (GDALRasterIO(b.band, GF_Read, 0, 0, g.width, g.height, raw.data(), g.width, g.height, GDT_Float64, 0, 0) !=
        CE_None) {
      throw InputError(path + ": layer '" + layers[l] + "': read failed (" + CPLGetLastErrorMsg() + ")");
    }
    int has_nodata = 0;
    const double nodata = GDALGetRasterNoDataValue(b.band, &has_nodata);
    std::vector<double> v(raw.size());
    for (int r = 0; r < g.height; ++r) {
      const int i = g.flip_rows ? g.height - 1 - r : r;  // latitude index, ascending
      for (int j = 0; j < g.width; ++j) {
        const double x = raw[static_cast<std::size_t>(r) * g.width + j];
        if (std::isfinite(x) && !(has_nodata && x == nodata) && !WithinLimit(kLimitMapValue, x)) {
          throw InputError(path + ": layer '" + layers[l] + "': row " + std::to_string(r) + ", column " +
                           std::to_string(j) + " (lat " + FormatNumber(g.lat.at(i)) + ", lon " +
                           FormatNumber(g.lon.at(j)) + "): " + OutOfRange(kLimitMapValue, x));
        }
        if (!std::isfinite(x) || (has_nodata && x == nodata)) {
          throw InputError(path + ": layer '" + layers[l] + "': hole (no data) at lat " +
                           std::to_string(g.lat.at(i)) + ", lon " + std::to_string(g.lon.at(j)) +
                           " (row " + std::to_string(r) + ", column " + std::to_string(j) +
                           "); a map must be complete");
        }
        v[static_cast<std::size_t>(i) * g.width + j] = x;
      }
    }
    values.push_back(std::move(v));
  }
  return GeoGrid(geometry.lat, geometry.lon, layers, std::move(values));
}

#else  // MAGNAV_WITH_GDAL

bool RasterMapsSupported() { return false; }

GeoGrid ReadGeoGridRaster(const std::string& path, const std::vector<std::string>&) {
  throw InputError(path + ": raster maps (GeoTIFF, NetCDF) need GDAL: this magnav was built without it "
                          "(install libgdal-dev and rebuild; scripts/bootstrap does)");
}

#endif  // MAGNAV_WITH_GDAL

GeoGrid ReadGeoGridFile(const std::string& path, const std::vector<std::string>& layers) {
  if (path.ends_with(".csv")) return ReadGeoGridCsv(path, layers);
  if (path.ends_with(".xyz") || path.ends_with(".txt")) {
    if (layers.size() != 1) throw InputError(path + ": an NGDC text map has one layer; name exactly one");
    return ReadGeoGridXyz(path, layers[0]);
  }
  return ReadGeoGridRaster(path, layers);
}

}  // namespace magnav::mapmatch
