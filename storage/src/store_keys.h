// Key layout of the store's column families. Integers are big-endian so that RocksDB's
// bytewise order is numeric order: log records iterate in version order, tiles in (x, y) order.
//
//   meta        "format" -> decimal            "param/<yaml key>" -> text value
//               "checkpoint_version" -> u64    "map_version" -> u64 (max-merged)
//               "robot/<id>" -> u64 last logged sequence (max-merged)
//               "georeference/crs", "georeference/origin" -> text (absent: a local frame)
//   tiles       tile key (8 bytes) -> TileCodec encoding
//   tile_index  tile key (8 bytes) -> varint version, known cells, encoded bytes
//   log         version (8 bytes)  -> LogRecord encoding
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "bgkmap/core/grid.h"

namespace bgkmap::storage {

inline constexpr char kMetaFamily[] = "meta";
inline constexpr char kTilesFamily[] = "tiles";
inline constexpr char kTileIndexFamily[] = "tile_index";
inline constexpr char kLogFamily[] = "log";

inline constexpr std::string_view kFormatKey = "format";
inline constexpr std::string_view kParamPrefix = "param/";
inline constexpr std::string_view kCheckpointVersionKey = "checkpoint_version";
inline constexpr std::string_view kMapVersionKey = "map_version";
inline constexpr std::string_view kRobotPrefix = "robot/";
inline constexpr std::string_view kGeoreferencePrefix = "georeference/";

// Signed coordinates are offset by 2^31 so that negative keys sort first.
std::string TileKeyBytes(TileKey key);
bool ParseTileKeyBytes(std::string_view bytes, TileKey* key);

std::string VersionKeyBytes(uint64_t version);
bool ParseVersionKeyBytes(std::string_view bytes, uint64_t* version);

// Fixed 8-byte little-endian u64, the value of the max-merged meta keys.
std::string U64Bytes(uint64_t v);
bool ParseU64Bytes(std::string_view bytes, uint64_t* v);

// "(x, y)": how messages name a tile.
std::string TileKeyName(TileKey key);

}  // namespace bgkmap::storage
