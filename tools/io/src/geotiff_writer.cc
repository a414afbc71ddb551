#include "bgkmap/io/geotiff_writer.h"

#include <cpl_string.h>
#include <fmt/format.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <vector>

#include "gdal_dataset.h"

namespace bgkmap::io {
namespace {

// DEFLATE at level 3 without a predictor: on the real drives' maps it writes in about half the
// time of level 6 with the floating-point predictor (whose byte shuffling alone cost a third of
// the output's CPU), files within -8..+8 % (docs/benchmarks.md, "The GeoTIFF's share").
constexpr const char* kDeflateLevel = "3";

Status CheckGeometry(const Raster& r, const std::string& path) {
  if (r.cols <= 0 || r.rows <= 0 || r.cols > std::numeric_limits<int>::max() ||
      r.rows > std::numeric_limits<int>::max()) {
    return Status::InvalidArgument(
        fmt::format("{}: raster size {} x {} is empty or too large", path, r.cols, r.rows));
  }
  if (r.layers.empty()) return Status::InvalidArgument(path + ": raster has no layers");
  if (!(r.resolution > 0) || !std::isfinite(r.resolution) || !std::isfinite(r.x0) ||
      !std::isfinite(r.y1) || r.stride < 1) {
    return Status::InvalidArgument(path + ": raster resolution/origin is not finite and positive");
  }
  return Status::Ok();
}

// Geotransform, CRS, BGKMAP_* metadata, band descriptions and NoData of `geometry` into `ds`.
Status DescribeDataset(GDALDataset& ds, const Raster& geometry, const std::string& path,
                       const GeoTiffOptions& options) {
  const auto& [easting, northing, height] = options.origin;
  double gt[6] = {geometry.x0 + easting, geometry.resolution, 0.0, geometry.y1 + northing, 0.0,
                  -geometry.resolution};
  if (ds.SetGeoTransform(gt) != CE_None) return GdalError(path, "cannot set geotransform");
  if (!options.spatial_reference.empty()) {
    OGRSpatialReference srs;
    if (srs.SetFromUserInput(options.spatial_reference.c_str()) != OGRERR_NONE) {
      return Status::InvalidArgument(path + ": unknown spatial reference '" +
                                     options.spatial_reference + "'");
    }
    if (ds.SetSpatialRef(&srs) != CE_None) return GdalError(path, "cannot set spatial reference");
  }
  ds.SetMetadataItem("BGKMAP_STRIDE", std::to_string(geometry.stride).c_str());
  ds.SetMetadataItem("BGKMAP_BOX",
                     fmt::format("{} {} {} {}", geometry.box.min.x, geometry.box.min.y,
                                 geometry.box.max.x, geometry.box.max.y)
                         .c_str());
  for (size_t b = 0; b < geometry.layers.size(); ++b) {
    GDALRasterBand* band = ds.GetRasterBand(static_cast<int>(b) + 1);
    band->SetDescription(std::string(LayerName(geometry.layers[b])).c_str());
    band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
  }
  return Status::Ok();
}

}  // namespace

struct GeoTiffWriter::Impl {
  Raster geometry;  // without data
  std::string path;
  std::string tiff_path;  // `path`, or the staging file of a COG
  GeoTiffOptions options;
  DatasetPtr ds;
  bool finished = false;
};

GeoTiffWriter::GeoTiffWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

GeoTiffWriter::~GeoTiffWriter() {
  if (impl_->finished) return;
  impl_->ds.reset();
  std::error_code ignored;  // an unfinished file is not a result
  std::filesystem::remove(impl_->tiff_path, ignored);
}

Result<std::unique_ptr<GeoTiffWriter>> GeoTiffWriter::Create(const Raster& geometry,
                                                             const std::string& path,
                                                             const GeoTiffOptions& options) {
  if (Status s = CheckGeometry(geometry, path); !s.ok()) return s;
  InitGdal();
  CPLErrorReset();
  auto impl = std::make_unique<Impl>();
  // The geometry without the data: copying a whole raster only to drop it cost more than its
  // compression (tens of MB of page faults).
  Raster& g = impl->geometry;
  g.box = geometry.box;
  g.stride = geometry.stride;
  g.cols = geometry.cols;
  g.rows = geometry.rows;
  g.resolution = geometry.resolution;
  g.x0 = geometry.x0;
  g.y1 = geometry.y1;
  g.layers = geometry.layers;
  impl->path = path;
  impl->tiff_path = options.cloud_optimized ? path + ".staging.tif" : path;
  impl->options = options;
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!driver) return GdalError(path, "GDAL has no GTiff driver");
  CPLStringList create_options;
  create_options.SetNameValue("COMPRESS", "DEFLATE");
  create_options.SetNameValue("ZLEVEL", kDeflateLevel);
  create_options.SetNameValue("TILED", "YES");
  create_options.SetNameValue("BLOCKXSIZE", std::to_string(kGeoTiffBlockPixels).c_str());
  create_options.SetNameValue("BLOCKYSIZE", std::to_string(kGeoTiffBlockPixels).c_str());
  create_options.SetNameValue("BIGTIFF", "IF_SAFER");
  create_options.SetNameValue("NUM_THREADS", std::to_string(std::max(1, options.threads)).c_str());
  const int bands = static_cast<int>(geometry.layers.size());
  if (bands > 1) create_options.SetNameValue("INTERLEAVE", "BAND");
  impl->ds.reset(driver->Create(impl->tiff_path.c_str(), static_cast<int>(geometry.cols),
                                static_cast<int>(geometry.rows), bands, GDT_Float32,
                                create_options.List()));
  if (!impl->ds) return GdalError(impl->tiff_path, "cannot create GeoTIFF");
  std::unique_ptr<GeoTiffWriter> writer(new GeoTiffWriter(std::move(impl)));
  Impl& w = *writer->impl_;
  if (Status s = DescribeDataset(*w.ds, w.geometry, w.tiff_path, options); !s.ok()) return s;
  return writer;
}

Status GeoTiffWriter::Write(const Raster& part) {
  Impl& w = *impl_;
  const Raster& g = w.geometry;
  if (w.finished) return Status::InvalidArgument(w.path + ": written already");
  if (part.stride != g.stride || part.resolution != g.resolution || part.layers != g.layers ||
      part.data.size() != g.layers.size()) {
    return Status::InvalidArgument(w.path + ": a part of another stride, resolution or layers");
  }
  const int64_t s = g.stride;
  const int64_t dx = part.box.min.x - g.box.min.x, dy = g.box.max.y - part.box.max.y;
  if (dx < 0 || dy < 0 || dx % s != 0 || dy % s != 0 || part.cols <= 0 || part.rows <= 0 ||
      dx / s + part.cols > g.cols || dy / s + part.rows > g.rows) {
    return Status::InvalidArgument(
        fmt::format("{}: a part of {} x {} pixels at cells ({}, {}) is not inside the raster on "
                    "its stride grid",
                    w.path, part.cols, part.rows, part.box.min.x, part.box.max.y));
  }
  const int col0 = static_cast<int>(dx / s), row0 = static_cast<int>(dy / s);
  const int cols = static_cast<int>(part.cols), rows = static_cast<int>(part.rows);
  const double height = w.options.origin[2];
  for (size_t b = 0; b < part.layers.size(); ++b) {
    if (static_cast<int64_t>(part.data[b].size()) != part.rows * part.cols) {
      return Status::InvalidArgument(fmt::format("{}: layer {} has {} values, expected {} x {}",
                                                 w.path, LayerName(part.layers[b]),
                                                 part.data[b].size(), part.rows, part.cols));
    }
    // RasterIO takes a non-const buffer even for writes.
    float* values = const_cast<float*>(part.data[b].data());
    std::vector<float> shifted;
    if (part.layers[b] == Layer::kElevation && height != 0) {
      shifted.assign(part.data[b].begin(), part.data[b].end());
      for (float& v : shifted) v = static_cast<float>(v + height);  // NaN stays NaN
      values = shifted.data();
    }
    GDALRasterBand* band = w.ds->GetRasterBand(static_cast<int>(b) + 1);
    if (band->RasterIO(GF_Write, col0, row0, cols, rows, values, cols, rows, GDT_Float32, 0, 0) !=
        CE_None) {
      return GdalError(w.path, fmt::format("cannot write band {}", b + 1));
    }
  }
  // The part's blocks go to the file now, so memory holds one part at a time.
  CPLErrorReset();
  w.ds->FlushCache(false);
  if (CPLGetLastErrorType() >= CE_Failure) return GdalError(w.path, "cannot write blocks");
  return Status::Ok();
}

Status GeoTiffWriter::Finish() {
  Impl& w = *impl_;
  if (w.finished) return Status::InvalidArgument(w.path + ": finished already");
  if (Status s = CloseDataset(w.ds, w.tiff_path); !s.ok()) return s;
  if (!w.options.cloud_optimized) {
    w.finished = true;
    return Status::Ok();
  }
  GDALDriver* cog = GetGDALDriverManager()->GetDriverByName("COG");
  if (!cog) return GdalError(w.path, "GDAL has no COG driver");
  const char* const drivers[] = {"GTiff", nullptr};
  DatasetPtr staged(GDALDataset::FromHandle(GDALOpenEx(
      w.tiff_path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, drivers, nullptr, nullptr)));
  if (!staged) return GdalError(w.tiff_path, "cannot reopen the staging file");
  CPLStringList cog_options;
  cog_options.SetNameValue("COMPRESS", "DEFLATE");
  cog_options.SetNameValue("LEVEL", kDeflateLevel);
  // Overviews pick cells rather than average them: state is a class, and averaging unknown
  // (NaN) with known cells would invent values.
  cog_options.SetNameValue("OVERVIEWS", "AUTO");
  cog_options.SetNameValue("RESAMPLING", "NEAREST");
  cog_options.SetNameValue("BIGTIFF", "IF_SAFER");
  cog_options.SetNameValue("NUM_THREADS", std::to_string(std::max(1, w.options.threads)).c_str());
  const GIntBig cache_before = GDALGetCacheMax64();
  if (w.options.cog_cache_bytes > 0) {
    GDALSetCacheMax64(static_cast<GIntBig>(w.options.cog_cache_bytes));
  }
  CPLErrorReset();
  DatasetPtr ds(
      cog->CreateCopy(w.path.c_str(), staged.get(), FALSE, cog_options.List(), nullptr, nullptr));
  Status closed =
      ds ? CloseDataset(ds, w.path) : GdalError(w.path, "cannot write Cloud-Optimized GeoTIFF");
  GDALSetCacheMax64(cache_before);
  staged.reset();
  std::error_code ignored;  // the staging file is no result; a leftover is only disk
  std::filesystem::remove(w.tiff_path, ignored);
  if (!closed.ok()) return closed;
  w.finished = true;
  return Status::Ok();
}

}  // namespace bgkmap::io
