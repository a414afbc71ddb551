#include "bgkmap/io/geotiff.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <fmt/format.h>
#include <gdal_priv.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#include "bgkmap/io/geotiff_writer.h"
#include "gdal_dataset.h"

namespace bgkmap::io {
namespace {

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

Status WriteGeoTiff(const Raster& raster, const std::string& path, const GeoTiffOptions& options) {
  for (size_t i = 0; i < raster.data.size() && raster.data.size() == raster.layers.size(); ++i) {
    if (static_cast<int64_t>(raster.data[i].size()) != raster.rows * raster.cols) {
      return Status::InvalidArgument(fmt::format("{}: layer {} has {} values, expected {} x {}",
                                                 path, LayerName(raster.layers[i]),
                                                 raster.data[i].size(), raster.rows, raster.cols));
    }
  }
  if (raster.data.size() != raster.layers.size()) {
    return Status::InvalidArgument(fmt::format("{}: {} layers but {} data arrays", path,
                                               raster.layers.size(), raster.data.size()));
  }
  Result<std::unique_ptr<GeoTiffWriter>> writer = GeoTiffWriter::Create(raster, path, options);
  if (!writer.ok()) return writer.status();
  if (Status s = (*writer)->Write(raster); !s.ok()) return s;
  return (*writer)->Finish();
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
