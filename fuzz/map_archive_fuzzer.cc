// The map archive reader (MapArchiveReader, ImportMap) on arbitrary files, checksums restored
// (fuzz_input.h): never crashes nor allocates beyond the file. An archive that verifies is
// imported into an empty map of its own parameters, then once more (the merge path), and the
// tile count must agree with what the reader saw.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/storage/map_archive.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bgkmap;
  static fuzz::InputFile file(".bgkmap");
  std::string bytes(reinterpret_cast<const char*>(data), size);
  fuzz::FixArchiveCrcs(bytes);
  const std::string& path = file.Write(bytes);

  Result<std::unique_ptr<storage::MapArchiveReader>> reader = storage::MapArchiveReader::Open(path);
  if (!reader.ok()) return 0;
  uint64_t tiles = 0;
  for (;;) {
    TileKey key;
    std::unique_ptr<Tile> tile;
    Result<bool> more = (*reader)->Next(&key, &tile);
    if (!more.ok()) return 0;
    if (!*more) break;
    if (tile == nullptr || tile->tile_size() != (*reader)->metadata().params.tile_size)
      std::abort();
    ++tiles;
  }
  Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create((*reader)->metadata().params);
  if (!map.ok()) return 0;
  for (int round = 0; round < 2; ++round) {
    Result<storage::ImportReport> report = storage::ImportMap(path, **map);
    if (round == 0 && (!report.ok() || report->tiles != tiles)) std::abort();
  }
  return 0;
}
