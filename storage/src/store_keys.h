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
//   sources     version (8 bytes)  -> EncodeRawScan (the raw scan, kept for corrections)
//   history     checkpoint version C (8 bytes) + tile key (8 bytes) -> the tile's stored bytes
//               just before checkpoint C replaced them ("" : there was no tile)
//   meta "bases" -> varint count, varint versions: the retained checkpoints a correction may
//               rebuild from (scan_history.h)
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/grid.h"

namespace bgkmap::storage {

inline constexpr char kMetaFamily[] = "meta";
inline constexpr char kTilesFamily[] = "tiles";
inline constexpr char kTileIndexFamily[] = "tile_index";
inline constexpr char kLogFamily[] = "log";
inline constexpr char kSourcesFamily[] = "sources";
inline constexpr char kHistoryFamily[] = "history";

inline constexpr std::string_view kFormatKey = "format";
inline constexpr std::string_view kParamPrefix = "param/";
inline constexpr std::string_view kCheckpointVersionKey = "checkpoint_version";
inline constexpr std::string_view kMapVersionKey = "map_version";
inline constexpr std::string_view kRobotPrefix = "robot/";
inline constexpr std::string_view kBasesKey = "bases";
// u64: a checkpoint below this version is never a base (it may predate a correction above it).
inline constexpr std::string_view kBasesFloorKey = "bases_floor";
inline constexpr std::string_view kGeoreferencePrefix = "georeference/";

// Signed coordinates are offset by 2^31 so that negative keys sort first.
std::string TileKeyBytes(TileKey key);
bool ParseTileKeyBytes(std::string_view bytes, TileKey* key);

std::string VersionKeyBytes(uint64_t version);
bool ParseVersionKeyBytes(std::string_view bytes, uint64_t* version);

// Fixed 8-byte little-endian u64, the value of the max-merged meta keys.
std::string U64Bytes(uint64_t v);
bool ParseU64Bytes(std::string_view bytes, uint64_t* v);

// Varint count, then varint deltas of ascending versions (the meta "bases" value).
std::string EncodeVersionList(const std::vector<uint64_t>& versions);
bool DecodeVersionList(std::string_view bytes, std::vector<uint64_t>* versions);

// "(x, y)": how messages name a tile.
std::string TileKeyName(TileKey key);

}  // namespace bgkmap::storage
