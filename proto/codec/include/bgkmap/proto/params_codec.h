// MapParams <-> bgkmap.v1.MapParameters, by reflection: every MapParamTable() key is the name of
// its MapParameters field (but `lambda`, a Python keyword, is `prior_weight`), so a new parameter
// needs no line here (params_codec_test checks the names and types).
#pragma once

#include <string_view>

#include "bgkmap/core/map_params.h"
#include "bgkmap/v1/admin.pb.h"

namespace bgkmap {

// The MapParameters field of a parameter's YAML key.
std::string_view ProtoFieldName(std::string_view yaml_key);

void ToProto(const MapParams& params, v1::MapParameters* out);
// Fields this build cannot read (an unknown enum name, fewer than 3 weights) keep their defaults.
MapParams FromProto(const v1::MapParameters& params);

}  // namespace bgkmap
