// Raster maps through GDAL (built with MAGNAV_WITH_GDAL): a GeoTIFF and a
// NetCDF file written here with GDAL from a known function are read back
// node for node; a projected, a rotated and a holed raster are refused with
// a clear error.
#include <gdal.h>
#include <cpl_conv.h>
#include <ogr_srs_api.h>

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/core/error.h"
#include "magnav/mapmatch/geo_grid.h"
#include "test_data.h"

namespace magnav::mapmatch {
namespace {

double Field(double lat, double lon) { return 40000.0 + 120.0 * (lat - 45.0) - 35.0 * (lon - 10.0) + 3.0 * lat * lon; }

// A north-up raster of `bands` layers (band b: Field + 1000 b) with pixel
// centres at lat 44.0 + 0.1 i (i = 0..ny-1), lon 9.0 + 0.2 j, written by
// `driver` to `path`; `epsg` its coordinate system; `hole` puts a NaN in.
void WriteRaster(const std::string& driver, const std::string& path, int bands, int epsg = 4326,
                 bool rotate = false, bool hole = false) {
  GDALAllRegister();
  const int nx = 6, ny = 5;
  GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", nx, ny, bands, GDT_Float64, nullptr);
  // Top-left corner: the northernmost row first.
  double gt[6] = {9.0 - 0.1, 0.2, rotate ? 0.01 : 0.0, 44.0 + 0.1 * (ny - 1) + 0.05, 0.0, -0.1};
  GDALSetGeoTransform(mem, gt);
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(srs, epsg);
  char* wkt = nullptr;
  OSRExportToWkt(srs, &wkt);
  GDALSetProjection(mem, wkt);
  CPLFree(wkt);
  OSRDestroySpatialReference(srs);
  for (int b = 1; b <= bands; ++b) {
    std::vector<double> v(nx * ny);
    for (int r = 0; r < ny; ++r) {
      for (int j = 0; j < nx; ++j) {
        const double lat = 44.0 + 0.1 * (ny - 1 - r), lon = 9.0 + 0.2 * j;
        v[r * nx + j] = Field(lat, lon) + 1000.0 * b;
      }
    }
    if (hole) v[7] = std::nan("");
    GDALRasterBandH band = GDALGetRasterBand(mem, b);
    ASSERT_EQ(GDALRasterIO(band, GF_Write, 0, 0, nx, ny, v.data(), nx, ny, GDT_Float64, 0, 0), CE_None);
    GDALSetDescription(band, ("layer" + std::to_string(b)).c_str());
  }
  GDALDatasetH out = GDALCreateCopy(GDALGetDriverByName(driver.c_str()), path.c_str(), mem, FALSE, nullptr, nullptr,
                                    nullptr);
  ASSERT_NE(out, nullptr) << CPLGetLastErrorMsg();
  GDALClose(out);
  GDALClose(mem);
}

void ExpectNodes(const GeoGrid& g, std::size_t layer, int band) {
  ASSERT_EQ(g.lat().count, 5);
  ASSERT_EQ(g.lon().count, 6);
  EXPECT_NEAR(g.lat().first_deg, 44.0, 1e-12);
  EXPECT_NEAR(g.lat().step_deg, 0.1, 1e-12);
  EXPECT_NEAR(g.lon().first_deg, 9.0, 1e-12);
  EXPECT_NEAR(g.lon().step_deg, 0.2, 1e-12);
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 6; ++j) {
      EXPECT_NEAR(g.node(layer, i, j), Field(g.lat().at(i), g.lon().at(j)) + 1000.0 * band, 1e-6) << i << " " << j;
    }
  }
}

TEST(RasterMap, GeoTiffBandsReadNodeForNode) {
  ASSERT_TRUE(RasterMapsSupported());
  const std::string path = testing::TempDir() + "/map.tif";
  WriteRaster("GTiff", path, 2);
  const GeoGrid g = ReadGeoGridRaster(path, {"layer2", "layer1"});
  ExpectNodes(g, 0, 2);
  ExpectNodes(g, 1, 1);
  // And through the file-type dispatch magnav match uses.
  const GeoGrid h = ReadGeoGridFile(path, {"layer1"});
  const auto s = h.Sample(0, 44.15, 9.5);
  ASSERT_TRUE(s.has_value());
  EXPECT_NEAR(s->value_nT, 0.25 * (Field(44.1, 9.4) + Field(44.1, 9.6) + Field(44.2, 9.4) + Field(44.2, 9.6)) + 1000.0,
              1e-6);
  EXPECT_THROW(ReadGeoGridRaster(path, {"X_nT"}), InputError);
}

TEST(RasterMap, NetCdfVariablesReadNodeForNode) {
  const std::string path = testing::TempDir() + "/map.nc";
  WriteRaster("netCDF", path, 2);
  // Two bands become two variables (Band1, Band2): NetCDF subdatasets.
  const GeoGrid g = ReadGeoGridRaster(path, {"Band1", "Band2"});
  ExpectNodes(g, 0, 1);
  ExpectNodes(g, 1, 2);
  const std::string one = testing::TempDir() + "/one.nc";
  WriteRaster("netCDF", one, 1);
  ExpectNodes(ReadGeoGridRaster(one, {"anomaly_nT"}), 0, 1);  // the only grid takes the name asked for
}

TEST(RasterMap, ProjectedRotatedAndHoledRastersAreRefused) {
  const std::string dir = testing::TempDir();
  const auto message = [](const std::string& path) {
    try {
      ReadGeoGridRaster(path, {"layer1"});
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  WriteRaster("GTiff", dir + "/utm.tif", 1, 32632);
  EXPECT_NE(message(dir + "/utm.tif").find("projected coordinates"), std::string::npos) << message(dir + "/utm.tif");
  WriteRaster("GTiff", dir + "/rot.tif", 1, 4326, /*rotate=*/true);
  EXPECT_NE(message(dir + "/rot.tif").find("rotated or sheared"), std::string::npos) << message(dir + "/rot.tif");
  WriteRaster("GTiff", dir + "/hole.tif", 1, 4326, false, /*hole=*/true);
  EXPECT_NE(message(dir + "/hole.tif").find("hole (no data) at lat"), std::string::npos) << message(dir + "/hole.tif");
  EXPECT_NE(message(dir + "/missing.tif").find("cannot read as a raster map"), std::string::npos);
}

}  // namespace
}  // namespace magnav::mapmatch
