#include "bgkmap/config/map_params_yaml.h"

#include <algorithm>
#include <charconv>
#include <fstream>
#include <sstream>
#include <system_error>

#include "bgkmap/core/map_param_table.h"

namespace bgkmap {
namespace {

std::string Where(const YAML::Node& node) {
  const YAML::Mark m = node.Mark();
  if (m.line < 0) return "";
  return " (line " + std::to_string(m.line + 1) + ")";
}

Status TypeError(std::string_view key, const YAML::Node& node, std::string_view expected) {
  std::string got = node.IsScalar() ? "'" + node.Scalar() + "'" : "a non-scalar value";
  return Status::InvalidArgument(std::string(key) + ": expected " + std::string(expected) +
                                 ", got " + got + Where(node));
}

Status ReadDouble(std::string_view key, const YAML::Node& node, double* out) {
  if (!node.IsScalar()) return TypeError(key, node, "a number");
  try {
    *out = node.as<double>();
  } catch (const YAML::Exception&) {
    return TypeError(key, node, "a number");
  }
  return Status::Ok();
}

Status ReadInt(std::string_view key, const YAML::Node& node, int* out) {
  if (!node.IsScalar()) return TypeError(key, node, "an integer");
  try {
    *out = node.as<int>();
  } catch (const YAML::Exception&) {
    return TypeError(key, node, "an integer");
  }
  return Status::Ok();
}

Status ReadTriple(std::string_view key, const YAML::Node& node, std::array<double, 3>* out,
                  std::string_view doc) {
  if (!node.IsSequence() || node.size() != 3) {
    return Status::InvalidArgument(std::string(key) + ": expected a list of 3 numbers " +
                                   std::string(doc) + Where(node));
  }
  for (size_t i = 0; i < 3; ++i) {
    if (Status s = ReadDouble(key, node[i], &(*out)[i]); !s.ok()) return s;
  }
  return Status::Ok();
}

Status ReadKey(const std::string& key, const YAML::Node& v, MapParams& p) {
  const MapParamInfo* info = FindMapParam(key);
  if (info == nullptr) {
    std::string known;
    for (std::string_view k : MapParamKeys()) known += (known.empty() ? "" : ", ") + std::string(k);
    return Status::InvalidArgument("unknown key '" + key + "'" + Where(v) +
                                   "; known keys: " + known);
  }
  switch (info->kind) {
    case MapParamKind::kDouble:
      return ReadDouble(key, v, &(p.*info->real));
    case MapParamKind::kInt:
      return ReadInt(key, v, &(p.*info->integer));
    case MapParamKind::kDouble3:
      return ReadTriple(key, v, &(p.*info->triple), info->doc);
    case MapParamKind::kEnum:
      if (!v.IsScalar()) return TypeError(key, v, "a name");
      return info->enum_parse(v.Scalar(), p);
  }
  return Status::Ok();
}

}  // namespace

Result<MapParams> MapParamsFromYaml(const YAML::Node& root,
                                    const std::vector<std::string_view>& other_sections,
                                    const MapParams& base) {
  MapParams p = base;
  if (!root || root.IsNull()) return p;  // an empty file means all defaults
  if (!root.IsMap()) {
    return Status::InvalidArgument("config: expected a mapping of key: value at the top level");
  }
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    if (std::find(other_sections.begin(), other_sections.end(), key) != other_sections.end()) {
      continue;
    }
    if (Status s = ReadKey(key, entry.second, p); !s.ok()) return s;
  }
  if (Status s = p.Validate(); !s.ok()) return s;
  return p;
}

Result<YAML::Node> LoadYamlFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::IoError(path + ": cannot open");
  try {
    return YAML::Load(in);
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument(path + ": not valid YAML: " + e.what());
  }
}

Result<MapParams> LoadMapParamsFile(const std::string& path,
                                    const std::vector<std::string_view>& other_sections) {
  Result<YAML::Node> root = LoadYamlFile(path);
  if (!root.ok()) return root.status();
  Result<MapParams> p = MapParamsFromYaml(*root, other_sections);
  if (!p.ok()) return Status::InvalidArgument(path + ": " + p.status().message());
  return p;
}

namespace {

// The shortest text that reads back as exactly `v` (0.1, not 0.10000000000000001).
YAML::Node Number(double v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return YAML::Node(std::string(buf, ec == std::errc() ? end : buf));
}

}  // namespace

Result<MapParams> LoadMapParamsFileOrDefaults(const std::string& path) {
  if (path.empty()) return MapParams{};
  return LoadMapParamsFile(path);
}

YAML::Node MapParamsToYaml(const MapParams& p) {
  YAML::Node n;
  for (const MapParamInfo& info : MapParamTable()) {
    const std::string key(info.key);
    switch (info.kind) {
      case MapParamKind::kDouble:
        n[key] = Number(p.*info.real);
        break;
      case MapParamKind::kInt:
        n[key] = p.*info.integer;
        break;
      case MapParamKind::kDouble3: {
        YAML::Node list(YAML::NodeType::Sequence);
        for (double x : p.*info.triple) list.push_back(Number(x));
        list.SetStyle(YAML::EmitterStyle::Flow);
        n[key] = list;
        break;
      }
      case MapParamKind::kEnum:
        n[key] = std::string(info.enum_name(p));
        break;
    }
  }
  return n;
}

}  // namespace bgkmap
