#include "bgkmap/io/nav2_map_files.h"

#include <fmt/format.h>

#include <filesystem>

#include "binary_file.h"

namespace bgkmap::io {

Status WriteNav2Map(const Raster& raster, const std::string& yaml_path) {
  const std::vector<float>* state = raster.Find(Layer::kState);
  if (state == nullptr) return Status::InvalidArgument("a Nav2 map needs the state layer");
  std::filesystem::path pgm = yaml_path;
  pgm.replace_extension(".pgm");
  std::string image = fmt::format("P5\n{} {}\n255\n", raster.cols, raster.rows);
  image.reserve(image.size() + state->size());
  for (float s : *state) {  // the raster's rows already run north to south
    const auto cell = static_cast<CellState>(s);
    image.push_back(static_cast<char>(cell == CellState::kNonTraversable ? 0
                                      : cell == CellState::kTraversable  ? 254
                                                                         : 205));
  }
  if (Status s = internal::WriteWholeFile(pgm.string(), image); !s.ok()) return s;
  const double south = raster.y1 - static_cast<double>(raster.rows) * raster.resolution;
  const std::string yaml = fmt::format(
      "image: {}\nmode: trinary\nresolution: {:.17g}\norigin: [{:.17g}, {:.17g}, 0.0]\n"
      "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\n",
      pgm.filename().string(), raster.resolution, raster.x0, south);
  return internal::WriteWholeFile(yaml_path, yaml);
}

}  // namespace bgkmap::io
