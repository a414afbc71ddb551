#include "bgkmap/proto/layer_codec.h"

#include <string>

namespace bgkmap {

v1::Layer ToProto(Layer layer) { return static_cast<v1::Layer>(static_cast<int>(layer) + 1); }

Layer FromProto(v1::Layer layer) { return static_cast<Layer>(static_cast<int>(layer) - 1); }

bool IsKnownLayer(int value) { return value >= 1 && value <= kLayerCount; }

Status LayerListFromProto(const google::protobuf::RepeatedField<int>& layers,
                          std::string_view field, std::vector<Layer>* out) {
  out->clear();
  if (layers.empty()) {
    for (int i = 0; i < kLayerCount; ++i) out->push_back(static_cast<Layer>(i));
    return Status::Ok();
  }
  for (int i = 0; i < layers.size(); ++i) {
    const int v = layers.Get(i);
    if (!IsKnownLayer(v)) {
      return Status::InvalidArgument(std::string(field) + "[" + std::to_string(i) +
                                     "]: " + std::to_string(v) + " is not a layer (1.." +
                                     std::to_string(kLayerCount) + ")");
    }
    out->push_back(FromProto(static_cast<v1::Layer>(v)));
  }
  return Status::Ok();
}

}  // namespace bgkmap
