#include "gdal_grid_runner.h"

#include <gdal.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>

namespace bgkmap::cli {

float SampledGrid::At(double x, double y) const {
  const double c = std::floor((x - geotransform[0]) / geotransform[1]);
  const double r = std::floor((y - geotransform[3]) / geotransform[5]);
  if (!(c >= 0 && c < cols && r >= 0 && r < rows)) return std::numeric_limits<float>::quiet_NaN();
  return values[static_cast<size_t>(r) * cols + static_cast<size_t>(c)];
}

Status WritePointsCsv(const std::string& csv, const std::vector<std::array<double, 3>>& points) {
  {
    std::ofstream out(csv);
    out << "x,y,z\n";
    char line[96];
    for (const auto& p : points) {
      std::snprintf(line, sizeof line, "%.4f,%.4f,%.4f\n", p[0], p[1], p[2]);
      out << line;
    }
    if (!out) return Status::IoError(csv + ": cannot write");
  }
  const std::filesystem::path path(csv);
  std::ofstream vrt(path.string() + ".vrt");
  vrt << "<OGRVRTDataSource><OGRVRTLayer name=\"" << path.stem().string() << "\"><SrcDataSource>"
      << std::filesystem::absolute(path).string()
      << "</SrcDataSource><GeometryType>wkbPoint25D</GeometryType>"
      << "<GeometryField encoding=\"PointFromColumns\" x=\"x\" y=\"y\" z=\"z\"/>"
      << "</OGRVRTLayer></OGRVRTDataSource>\n";
  if (!vrt) return Status::IoError(csv + ".vrt: cannot write");
  return Status::Ok();
}

Result<SampledGrid> RunGdalGrid(const std::string& csv, const std::string& algorithm,
                                const GridExtent& e, const std::string& out_tif) {
  const std::string layer = std::filesystem::path(csv).stem().string();
  char extent[256];
  std::snprintf(extent, sizeof extent, "-txe %.6f %.6f -tye %.6f %.6f -outsize %d %d", e.x0, e.x1,
                e.y0, e.y1, e.cols, e.rows);
  constexpr float kEmpty = -3.0e38f;  // below any elevation
  const std::string cmd = "gdal_grid -q -ot Float32 -of GTiff -a " + algorithm + ":nodata=-3e38 " +
                          extent + " -l " + layer + " '" + csv + ".vrt' '" + out_tif +
                          "' > /dev/null 2>&1";
  const auto t0 = std::chrono::steady_clock::now();
  const int rc = std::system(cmd.c_str());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (rc != 0) return Status::IoError("gdal_grid failed (exit " + std::to_string(rc) + "): " + cmd);

  GDALAllRegister();
  GDALDatasetH ds = GDALOpen(out_tif.c_str(), GA_ReadOnly);
  if (ds == nullptr) return Status::IoError(out_tif + ": gdal_grid wrote no readable raster");
  SampledGrid g;
  g.seconds = seconds;
  GDALGetGeoTransform(ds, g.geotransform.data());
  g.cols = GDALGetRasterXSize(ds);
  g.rows = GDALGetRasterYSize(ds);
  g.values.resize(static_cast<size_t>(g.cols) * g.rows);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  int has_nodata = 0;
  const double nodata = GDALGetRasterNoDataValue(band, &has_nodata);
  const CPLErr err = GDALRasterIO(band, GF_Read, 0, 0, g.cols, g.rows, g.values.data(), g.cols,
                                  g.rows, GDT_Float32, 0, 0);
  GDALClose(ds);
  if (err != CE_None) return Status::IoError(out_tif + ": cannot read the gdal_grid raster");
  for (float& v : g.values) {
    if (v == kEmpty || (has_nodata && v == static_cast<float>(nodata)))
      v = std::numeric_limits<float>::quiet_NaN();
  }
  return g;
}

}  // namespace bgkmap::cli
