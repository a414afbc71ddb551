// What a store knows about its map besides the tiles: the store format, every map parameter,
// the georeference, the checkpoint and map versions, and each robot's last logged sequence number.
//
// Parameters are stored as text key/value pairs under their YAML names (MapParamKeys()), with
// doubles written in shortest round-trip form, so a store reopens with bit-identical parameters
// and stays readable with generic RocksDB tools.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "bgkmap/core/georeference.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"

namespace bgkmap::storage {

// Version of the store layout (column families, keys, tile and log formats). A store written by
// a newer format is refused rather than misread. Format 2 (dynamics): tile format 2 (second
// moments), log record format 2 (sensor position), parameters keys of dynamics; format 1 stores
// and archives are read (their missing keys take MapParamInfo::legacy_text) and upgraded. Format
// 3: the sources and history families. Format 4 (forgetting): tile format 3 (a tile's stamp), the
// half_life_s key (legacy 0), the log's stamp is the scan's map time; formats 1-3 upgrade.
inline constexpr uint32_t kStoreFormat = 5;

struct MapMetadata {
  uint32_t format = kStoreFormat;
  MapParams params;
  Georeference georeference;  // empty for stores and archives written before it was kept
  // The stored tiles are exactly the map after every change with version <= this one.
  uint64_t checkpoint_version = 0;
  // Highest version checkpointed or logged: the next change gets map_version + 1.
  uint64_t map_version = 0;
  // Last sequence number logged per robot id: scans at or below it are duplicates.
  std::map<std::string, uint64_t> robot_sequences;
};

// Every parameter as (YAML key, text value), in MapParamKeys() order.
std::vector<std::pair<std::string, std::string>> ParamsToKeyValues(const MapParams& params);

// Inverse of ParamsToKeyValues. DataLoss naming the key if one is missing or unparsable;
// the result is validated (MapParams::Validate) as well.
Result<MapParams> ParamsFromKeyValues(const std::map<std::string, std::string, std::less<>>& kv);

// OK if a map stored with `stored` may be reopened (or merged into) with `requested`: every
// parameter that shapes the statistics is equal. Otherwise FailedPrecondition with a message
// naming the differing key and both values. Parameters of derived layers only (sigma2, alpha0,
// beta0, thresholds) may differ.
Status CheckParamsCompatible(const MapParams& stored, const MapParams& requested);

// OK if a map georeferenced as `stored` may take `requested`: either is empty (local frame) or
// they are equal. Otherwise FailedPrecondition naming the differing key (georeference.crs or
// georeference.origin) and both values, stored first, as `roles` says.
Status CheckGeoreferenceCompatible(const Georeference& stored, const Georeference& requested,
                                   std::string_view roles = "stored vs requested");

// The georeference as text key/value pairs ("crs", "origin" as "e,n,h" in shortest round-trip
// form); none for an empty one. Inverse: GeoreferenceFromKeyValues, DataLoss naming a malformed
// key; no keys give an empty georeference.
std::vector<std::pair<std::string, std::string>> GeoreferenceToKeyValues(const Georeference& g);
Result<Georeference> GeoreferenceFromKeyValues(
    const std::map<std::string, std::string, std::less<>>& kv);

// Whole-metadata encoding (used by map archives): the key/value pairs, length-prefixed. The
// georeference rides among the parameters' pairs under "georeference/<key>", which builds
// before it ignore, so archives stay readable both ways.
std::string EncodeMetadata(const MapMetadata& metadata);
Result<MapMetadata> DecodeMetadata(std::string_view bytes);

}  // namespace bgkmap::storage
