// The one description of every map parameter: its key, where it lives in MapParams, its kind,
// its rule, whether it shapes the stored statistics, and what it means. The YAML adapter, the
// store's metadata, the proto codec, MapParamKeys(), Validate() and StatisticsCompatibleWith()
// all walk this table, so a new parameter is one entry here (plus its field in admin.proto).
#pragma once

#include <array>
#include <span>
#include <string_view>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

enum class MapParamKind {
  kDouble,   // double MapParams::*
  kInt,      // int MapParams::*
  kDouble3,  // std::array<double, 3> MapParams::*
  kEnum,     // read and written as a name (enum_name / enum_parse)
};

struct MapParamInfo {
  std::string_view key;  // YAML key, store metadata key and MapParameters field name
  MapParamKind kind;
  // Maps merge or reopen only if every such parameter is equal; the others (noise, priors of the
  // classification, thresholds) only enter derived layers.
  bool shapes_statistics;
  std::string_view doc;  // one line, with the unit

  // The field, by kind; the others are null.
  double MapParams::*real = nullptr;
  int MapParams::*integer = nullptr;
  std::array<double, 3> MapParams::*triple = nullptr;
  std::string_view (*enum_name)(const MapParams&) = nullptr;
  // Sets the field from its name; InvalidArgument "key = name: must be one of ..." otherwise.
  Status (*enum_parse)(std::string_view name, MapParams& params) = nullptr;

  // The rule a valid value obeys (null: any); `value` is the field for kDouble and kInt. The
  // message names the key, the value and the rule broken.
  Status (*check)(std::string_view key, double value, const MapParams& params) = nullptr;

  // The value, as text, that a store or archive written before this key existed was built with
  // (empty: the key has always been stored, and is required).
  std::string_view legacy_text = {};

  // True if the field holds the same value in `a` and `b` (exactly, for doubles).
  bool Equal(const MapParams& a, const MapParams& b) const;
};

// Every parameter, in documentation order (the order of MapParamKeys(), YAML output and stored
// metadata).
std::span<const MapParamInfo> MapParamTable();

// The entry of `key`, or null.
const MapParamInfo* FindMapParam(std::string_view key);

}  // namespace bgkmap
