#include "bgkmap/proto/params_codec.h"

#include <string>

#include "bgkmap/core/map_param_table.h"

namespace bgkmap {
namespace {

using google::protobuf::FieldDescriptor;

// Null only if admin.proto lacks the key, which params_codec_test rules out.
const FieldDescriptor* FieldOf(const MapParamInfo& info) {
  return v1::MapParameters::descriptor()->FindFieldByName(std::string(ProtoFieldName(info.key)));
}

}  // namespace

std::string_view ProtoFieldName(std::string_view yaml_key) {
  return yaml_key == "lambda" ? "prior_weight" : yaml_key;
}

void ToProto(const MapParams& p, v1::MapParameters* out) {
  const google::protobuf::Reflection* r = out->GetReflection();
  for (const MapParamInfo& info : MapParamTable()) {
    const FieldDescriptor* f = FieldOf(info);
    if (f == nullptr) continue;
    switch (info.kind) {
      case MapParamKind::kDouble:
        r->SetDouble(out, f, p.*info.real);
        break;
      case MapParamKind::kInt:
        r->SetInt32(out, f, p.*info.integer);
        break;
      case MapParamKind::kDouble3:
        r->ClearField(out, f);
        for (double x : p.*info.triple) r->AddDouble(out, f, x);
        break;
      case MapParamKind::kEnum:
        r->SetString(out, f, std::string(info.enum_name(p)));
        break;
    }
  }
}

MapParams FromProto(const v1::MapParameters& in) {
  MapParams p;
  const google::protobuf::Reflection* r = in.GetReflection();
  for (const MapParamInfo& info : MapParamTable()) {
    const FieldDescriptor* f = FieldOf(info);
    if (f == nullptr) continue;
    switch (info.kind) {
      case MapParamKind::kDouble:
        p.*info.real = r->GetDouble(in, f);
        break;
      case MapParamKind::kInt:
        p.*info.integer = r->GetInt32(in, f);
        break;
      case MapParamKind::kDouble3:
        for (int i = 0; i < 3 && i < r->FieldSize(in, f); ++i) {
          (p.*info.triple)[i] = r->GetRepeatedDouble(in, f, i);
        }
        break;
      case MapParamKind::kEnum:
        (void)info.enum_parse(r->GetString(in, f), p);  // an unknown name keeps the default
        break;
    }
  }
  return p;
}

}  // namespace bgkmap
