#include "bgkmap/config/map_params_yaml.h"

#include <algorithm>
#include <charconv>
#include <fstream>
#include <sstream>
#include <system_error>

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

Status ReadKey(const std::string& key, const YAML::Node& v, MapParams& p) {
  if (key == "resolution") return ReadDouble(key, v, &p.resolution);
  if (key == "kernel_length") return ReadDouble(key, v, &p.kernel_length);
  if (key == "lambda") return ReadDouble(key, v, &p.lambda);
  if (key == "prior_mean") return ReadDouble(key, v, &p.prior_mean);
  if (key == "sigma2") return ReadDouble(key, v, &p.sigma2);
  if (key == "alpha0") return ReadDouble(key, v, &p.alpha0);
  if (key == "beta0") return ReadDouble(key, v, &p.beta0);
  if (key == "robot_radius") return ReadDouble(key, v, &p.robot_radius);
  if (key == "step_crit") return ReadDouble(key, v, &p.step_crit);
  if (key == "slope_crit_deg") return ReadDouble(key, v, &p.slope_crit_deg);
  if (key == "roughness_crit") return ReadDouble(key, v, &p.roughness_crit);
  if (key == "trav_threshold") return ReadDouble(key, v, &p.trav_threshold);
  if (key == "variance_threshold") return ReadDouble(key, v, &p.variance_threshold);
  if (key == "min_range") return ReadDouble(key, v, &p.min_range);
  if (key == "max_range") return ReadDouble(key, v, &p.max_range);
  if (key == "max_height_above_sensor") return ReadDouble(key, v, &p.max_height_above_sensor);
  if (key == "tile_size") return ReadInt(key, v, &p.tile_size);
  if (key == "weights") {
    if (!v.IsSequence() || v.size() != 3) {
      return Status::InvalidArgument(
          "weights: expected a list of 3 numbers [w_step, w_slope, "
          "w_rough]" +
          Where(v));
    }
    for (size_t i = 0; i < 3; ++i) {
      if (Status s = ReadDouble("weights", v[i], &p.weights[i]); !s.ok()) return s;
    }
    return Status::Ok();
  }
  if (key == "observation" || key == "method") {
    if (!v.IsScalar()) return TypeError(key, v, "a name");
    if (key == "method") {
      Result<Method> m = ParseMethod(v.Scalar());
      if (!m.ok()) return m.status();
      p.method = *m;
    } else {
      Result<Observation> o = ParseObservation(v.Scalar());
      if (!o.ok()) return o.status();
      p.observation = *o;
    }
    return Status::Ok();
  }
  std::string known;
  for (std::string_view k : MapParamKeys()) known += (known.empty() ? "" : ", ") + std::string(k);
  return Status::InvalidArgument("unknown key '" + key + "'" + Where(v) + "; known keys: " + known);
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
  n["resolution"] = Number(p.resolution);
  n["kernel_length"] = Number(p.kernel_length);
  n["lambda"] = Number(p.lambda);
  n["prior_mean"] = Number(p.prior_mean);
  n["sigma2"] = Number(p.sigma2);
  n["alpha0"] = Number(p.alpha0);
  n["beta0"] = Number(p.beta0);
  n["robot_radius"] = Number(p.robot_radius);
  n["step_crit"] = Number(p.step_crit);
  n["slope_crit_deg"] = Number(p.slope_crit_deg);
  n["roughness_crit"] = Number(p.roughness_crit);
  YAML::Node w(YAML::NodeType::Sequence);
  for (double x : p.weights) w.push_back(Number(x));
  w.SetStyle(YAML::EmitterStyle::Flow);
  n["weights"] = w;
  n["trav_threshold"] = Number(p.trav_threshold);
  n["variance_threshold"] = Number(p.variance_threshold);
  n["min_range"] = Number(p.min_range);
  n["max_range"] = Number(p.max_range);
  n["max_height_above_sensor"] = Number(p.max_height_above_sensor);
  n["observation"] = std::string(ObservationName(p.observation));
  n["tile_size"] = p.tile_size;
  n["method"] = std::string(MethodName(p.method));
  return n;
}

}  // namespace bgkmap
