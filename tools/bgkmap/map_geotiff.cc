#include "map_geotiff.h"

#include <algorithm>
#include <deque>
#include <future>
#include <memory>

#include "bgkmap/io/geotiff_writer.h"

namespace bgkmap::cli {

Status WriteMapGeoTiff(const TerrainMap& map, const CellBox& box, const std::vector<Layer>& layers,
                       const std::string& path, const io::GeoTiffOptions& tiff, int threads) {
  const Raster geometry = RasterGeometry(map.params().resolution, box, layers);
  Result<std::unique_ptr<io::GeoTiffWriter>> writer =
      io::GeoTiffWriter::Create(geometry, path, tiff);
  if (!writer.ok()) return writer.status();
  // Strips of whole block rows, north to south: each block is compressed once, when its strip
  // is written.
  const int64_t strip_rows = io::kGeoTiffBlockPixels;
  const int64_t strips = (geometry.rows + strip_rows - 1) / strip_rows;
  auto extract = [&](int64_t s) {
    const int top = static_cast<int>(box.max.y - s * strip_rows);
    const int bottom = static_cast<int>(std::max<int64_t>(box.min.y, top - strip_rows + 1));
    return ExtractRaster(map, CellBox{{box.min.x, bottom}, {box.max.x, top}}, layers);
  };
  // Up to `threads` strips extracted ahead of the one being written (the map is only read), and
  // no more than kAheadBytes of them: a strip of a raster 20,000 pixels wide is ~100 MB.
  constexpr int64_t kAheadBytes = int64_t{256} << 20;
  const int64_t strip_bytes =
      strip_rows * geometry.cols * static_cast<int64_t>(layers.size() * sizeof(float));
  const size_t most = static_cast<size_t>(std::clamp<int64_t>(
      kAheadBytes / std::max<int64_t>(strip_bytes, 1), 1, std::max(1, threads)));
  std::deque<std::future<Raster>> ahead;
  int64_t next = 0;
  const auto fill = [&] {
    while (next < strips && ahead.size() < most) {
      ahead.push_back(std::async(std::launch::async, extract, next++));
    }
  };
  fill();
  while (!ahead.empty()) {
    const Raster strip = ahead.front().get();
    ahead.pop_front();
    fill();
    if (Status s = (*writer)->Write(strip); !s.ok()) return s;
  }
  return (*writer)->Finish();
}

}  // namespace bgkmap::cli
