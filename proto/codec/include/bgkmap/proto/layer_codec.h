// Layer <-> bgkmap.v1.Layer: the proto value is the engine's plus one (0 is LAYER_UNSPECIFIED).
#pragma once

#include <google/protobuf/repeated_field.h>

#include <string_view>
#include <vector>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/status.h"
#include "bgkmap/v1/types.pb.h"

namespace bgkmap {

v1::Layer ToProto(Layer layer);
// Unchecked: `layer` must be known (IsKnownLayer).
Layer FromProto(v1::Layer layer);
bool IsKnownLayer(int value);

// A request's layer list; empty means every layer. LAYER_UNSPECIFIED or an unknown value is
// InvalidArgument naming `field`[i].
Status LayerListFromProto(const google::protobuf::RepeatedField<int>& layers,
                          std::string_view field, std::vector<Layer>* out);

}  // namespace bgkmap
