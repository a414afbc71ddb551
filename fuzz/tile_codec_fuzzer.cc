// DecodeTile on arbitrary bytes: never crashes, and whatever decodes re-encodes to a tile that
// decodes bitwise equal (with every layout option).
//
// Input: one byte choosing the map's tile size (its low 3 bits: 8 << k cells, clamped to the
// limits) and whether its tiles keep plane moments (bit 3: a bgk-ll map), then the encoding; its
// trailing CRC-32C is restored first (fuzz_input.h).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "bgkmap/core/map_params.h"
#include "bgkmap/storage/tile_codec.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bgkmap;
  if (size < 1) return 0;
  int tile_size = 8 << (data[0] & 7);  // 8 .. 1024
  if (tile_size > kMaxTileSize) tile_size = kMaxTileSize;
  const bool plane = (data[0] & 8) != 0;
  std::string encoded(reinterpret_cast<const char*>(data) + 1, size - 1);
  fuzz::FixTrailingCrc(encoded.data(), encoded.size());

  Result<std::unique_ptr<Tile>> tile = storage::DecodeTile(encoded, tile_size, plane);
  if (!tile.ok()) return 0;
  for (int flags = 0; flags < 4; ++flags) {
    const std::string again = storage::EncodeTile(
        **tile, storage::TileEncodeOptions{.shuffle = (flags & 1) != 0, .xor_delta = flags >= 2});
    Result<std::unique_ptr<Tile>> back = storage::DecodeTile(again, tile_size, plane);
    if (!back.ok() || !(**back == **tile)) std::abort();
  }
  return 0;
}
