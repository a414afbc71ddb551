#include "bgkmap/io/geotiff.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <fmt/format.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <vector>

namespace bgkmap::io {
namespace {

// GDAL prints to stderr by default; the message is still kept per thread for CPLGetLastErrorMsg.
void QuietGdalErrors(CPLErr, CPLErrorNum, const char*) {}

void InitGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(QuietGdalErrors);
  });
}

Status GdalError(const std::string& path, const std::string& what) {
  const char* msg = CPLGetLastErrorMsg();
  return Status::IoError(path + ": " + what + (msg && *msg ? std::string(": ") + msg : ""));
}

struct DatasetCloser {
  void operator()(GDALDataset* ds) const { GDALClose(GDALDataset::ToHandle(ds)); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

Status CheckRaster(const Raster& r, const std::string& path) {
  if (r.cols <= 0 || r.rows <= 0 || r.cols > std::numeric_limits<int>::max() ||
      r.rows > std::numeric_limits<int>::max()) {
    return Status::InvalidArgument(
        fmt::format("{}: raster size {} x {} is empty or too large", path, r.cols, r.rows));
  }
  if (r.layers.empty()) return Status::InvalidArgument(path + ": raster has no layers");
  if (r.data.size() != r.layers.size()) {
    return Status::InvalidArgument(
        fmt::format("{}: {} layers but {} data arrays", path, r.layers.size(), r.data.size()));
  }
  for (size_t i = 0; i < r.data.size(); ++i) {
    if (static_cast<int64_t>(r.data[i].size()) != r.rows * r.cols) {
      return Status::InvalidArgument(fmt::format("{}: layer {} has {} values, expected {} x {}",
                                                 path, LayerName(r.layers[i]), r.data[i].size(),
                                                 r.rows, r.cols));
    }
  }
  if (!(r.resolution > 0) || !std::isfinite(r.resolution) || !std::isfinite(r.x0) ||
      !std::isfinite(r.y1)) {
    return Status::InvalidArgument(path + ": raster resolution/origin is not finite and positive");
  }
  return Status::Ok();
}

bool ParseInts(const char* text, int* out, int n) {
  if (!text) return false;
  const char* p = text;
  const char* end = text + std::strlen(text);
  for (int i = 0; i < n; ++i) {
    while (p < end && *p == ' ') ++p;
    auto [next, ec] = std::from_chars(p, end, out[i]);
    if (ec != std::errc()) return false;
    p = next;
  }
  return true;
}

}  // namespace

namespace {

// Geotransform, CRS, BGKMAP_* metadata and every band of `raster` into `ds`.
Status FillDataset(GDALDataset& ds, const Raster& raster, const std::string& path,
                   const GeoTiffOptions& options) {
  const auto& [easting, northing, height] = options.origin;
  double gt[6] = {raster.x0 + easting, raster.resolution, 0.0, raster.y1 + northing, 0.0,
                  -raster.resolution};
  if (ds.SetGeoTransform(gt) != CE_None) return GdalError(path, "cannot set geotransform");
  if (!options.spatial_reference.empty()) {
    OGRSpatialReference srs;
    if (srs.SetFromUserInput(options.spatial_reference.c_str()) != OGRERR_NONE) {
      return Status::InvalidArgument(path + ": unknown spatial reference '" +
                                     options.spatial_reference + "'");
    }
    if (ds.SetSpatialRef(&srs) != CE_None) return GdalError(path, "cannot set spatial reference");
  }
  ds.SetMetadataItem("BGKMAP_STRIDE", std::to_string(raster.stride).c_str());
  ds.SetMetadataItem("BGKMAP_BOX", fmt::format("{} {} {} {}", raster.box.min.x, raster.box.min.y,
                                               raster.box.max.x, raster.box.max.y)
                                       .c_str());
  const int cols = static_cast<int>(raster.cols), rows = static_cast<int>(raster.rows);
  for (size_t b = 0; b < raster.layers.size(); ++b) {
    GDALRasterBand* band = ds.GetRasterBand(static_cast<int>(b) + 1);
    band->SetDescription(std::string(LayerName(raster.layers[b])).c_str());
    band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
    // RasterIO takes a non-const buffer even for writes.
    float* values = const_cast<float*>(raster.data[b].data());
    std::vector<float> shifted;
    if (raster.layers[b] == Layer::kElevation && height != 0) {
      shifted.assign(raster.data[b].begin(), raster.data[b].end());
      for (float& v : shifted) v = static_cast<float>(v + height);  // NaN stays NaN
      values = shifted.data();
    }
    if (band->RasterIO(GF_Write, 0, 0, cols, rows, values, cols, rows, GDT_Float32, 0, 0) !=
        CE_None) {
      return GdalError(path, fmt::format("cannot write band {}", b + 1));
    }
  }
  return Status::Ok();
}

// Closing flushes the compressed tiles: a failure there is a failed write. GDALClose returns
// void in GDAL 3.6, so check the error state it leaves.
Status Close(DatasetPtr& ds, const std::string& path) {
  CPLErrorReset();
  ds.reset();
  if (CPLGetLastErrorType() >= CE_Failure) return GdalError(path, "cannot finish file");
  return Status::Ok();
}

}  // namespace

Status WriteGeoTiff(const Raster& raster, const std::string& path, const GeoTiffOptions& options) {
  if (Status s = CheckRaster(raster, path); !s.ok()) return s;
  InitGdal();
  CPLErrorReset();
  const int cols = static_cast<int>(raster.cols), rows = static_cast<int>(raster.rows);
  const int bands = static_cast<int>(raster.layers.size());
  const int threads = std::max(1, options.threads);
  if (options.cloud_optimized) {
    // GDAL's COG driver only copies: fill an in-memory dataset, then write it with overviews.
    GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
    GDALDriver* cog = GetGDALDriverManager()->GetDriverByName("COG");
    if (!mem || !cog) return GdalError(path, "GDAL has no MEM or COG driver");
    DatasetPtr staged(mem->Create("", cols, rows, bands, GDT_Float32, nullptr));
    if (!staged) return GdalError(path, "cannot stage the raster in memory");
    if (Status s = FillDataset(*staged, raster, path, options); !s.ok()) return s;
    CPLStringList cog_options;
    cog_options.SetNameValue("COMPRESS", "DEFLATE");
    cog_options.SetNameValue("PREDICTOR", "YES");
    // Overviews pick cells rather than average them: state is a class, and averaging unknown
    // (NaN) with known cells would invent values.
    cog_options.SetNameValue("OVERVIEWS", "AUTO");
    cog_options.SetNameValue("RESAMPLING", "NEAREST");
    cog_options.SetNameValue("BIGTIFF", "IF_SAFER");
    cog_options.SetNameValue("NUM_THREADS", std::to_string(threads).c_str());
    DatasetPtr ds(
        cog->CreateCopy(path.c_str(), staged.get(), FALSE, cog_options.List(), nullptr, nullptr));
    if (!ds) return GdalError(path, "cannot write Cloud-Optimized GeoTIFF");
    return Close(ds, path);
  }
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!driver) return GdalError(path, "GDAL has no GTiff driver");
  CPLStringList create_options;
  create_options.SetNameValue("COMPRESS", "DEFLATE");
  create_options.SetNameValue("PREDICTOR", "3");  // floating-point predictor
  create_options.SetNameValue("TILED", "YES");
  create_options.SetNameValue("BIGTIFF", "IF_SAFER");
  create_options.SetNameValue("NUM_THREADS", std::to_string(threads).c_str());
  if (bands > 1) create_options.SetNameValue("INTERLEAVE", "BAND");
  DatasetPtr ds(
      driver->Create(path.c_str(), cols, rows, bands, GDT_Float32, create_options.List()));
  if (!ds) return GdalError(path, "cannot create GeoTIFF");
  if (Status s = FillDataset(*ds, raster, path, options); !s.ok()) return s;
  return Close(ds, path);
}

Result<Raster> ReadGeoTiff(const std::string& path) {
  InitGdal();
  CPLErrorReset();
  const char* const drivers[] = {"GTiff", nullptr};
  DatasetPtr ds(GDALDataset::FromHandle(
      GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, drivers, nullptr, nullptr)));
  if (!ds) return GdalError(path, "cannot open as GeoTIFF");

  double gt[6];
  if (ds->GetGeoTransform(gt) != CE_None) return GdalError(path, "no geotransform");
  if (gt[2] != 0 || gt[4] != 0 || !(gt[1] > 0) || gt[5] != -gt[1]) {
    return Status::DataLoss(path + ": geotransform is not north-up with square pixels");
  }
  Raster r;
  r.cols = ds->GetRasterXSize();
  r.rows = ds->GetRasterYSize();
  r.x0 = gt[0];
  r.y1 = gt[3];
  r.resolution = gt[1];

  int box[4];
  int stride = 1;
  const char* stride_text = ds->GetMetadataItem("BGKMAP_STRIDE");
  if (ParseInts(ds->GetMetadataItem("BGKMAP_BOX"), box, 4) && ParseInts(stride_text, &stride, 1) &&
      stride >= 1) {
    r.stride = stride;
    r.box = {{box[0], box[1]}, {box[2], box[3]}};
  } else {
    const int min_x = static_cast<int>(std::lround(r.x0 / r.resolution));
    const int max_y = static_cast<int>(std::lround(r.y1 / r.resolution)) - 1;
    r.box = {{min_x, max_y - static_cast<int>(r.rows) + 1},
             {min_x + static_cast<int>(r.cols) - 1, max_y}};
  }

  const int cols = static_cast<int>(r.cols), rows = static_cast<int>(r.rows);
  for (int b = 1; b <= ds->GetRasterCount(); ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b);
    const char* name = band->GetDescription();
    Result<Layer> layer = ParseLayer(name ? name : "");
    if (!layer.ok()) {
      return Status::DataLoss(fmt::format("{}: band {} description '{}' is not a layer name", path,
                                          b, name ? name : ""));
    }
    std::vector<float> values(static_cast<size_t>(r.rows * r.cols));
    if (band->RasterIO(GF_Read, 0, 0, cols, rows, values.data(), cols, rows, GDT_Float32, 0, 0) !=
        CE_None) {
      return GdalError(path, fmt::format("cannot read band {}", b));
    }
    // A foreign file may use a finite NoData; the Raster contract is NaN = unknown.
    int has_nodata = 0;
    const double nodata = band->GetNoDataValue(&has_nodata);
    if (has_nodata && !std::isnan(nodata)) {
      for (float& v : values) {
        if (v == static_cast<float>(nodata)) v = std::numeric_limits<float>::quiet_NaN();
      }
    }
    r.layers.push_back(*layer);
    r.data.push_back(std::move(values));
  }
  if (r.layers.empty()) return Status::DataLoss(path + ": no bands");
  return r;
}

}  // namespace bgkmap::io
