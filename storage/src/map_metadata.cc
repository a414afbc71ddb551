#include "bgkmap/storage/map_metadata.h"

#include <charconv>

#include "byte_coding.h"

namespace bgkmap::storage {
namespace {

std::string FormatDouble(double v) {
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof(buf), v);  // shortest exact round trip
  return std::string(buf, res.ptr);
}

bool ParseDouble(std::string_view text, double* v) {
  const auto res = std::from_chars(text.data(), text.data() + text.size(), *v);
  return res.ec == std::errc() && res.ptr == text.data() + text.size();
}

// The scalar double parameters, in MapParamKeys() order, by key.
std::vector<std::pair<std::string_view, double MapParams::*>> DoubleFields() {
  return {{"resolution", &MapParams::resolution},
          {"kernel_length", &MapParams::kernel_length},
          {"lambda", &MapParams::lambda},
          {"prior_mean", &MapParams::prior_mean},
          {"sigma2", &MapParams::sigma2},
          {"alpha0", &MapParams::alpha0},
          {"beta0", &MapParams::beta0},
          {"robot_radius", &MapParams::robot_radius},
          {"step_crit", &MapParams::step_crit},
          {"slope_crit_deg", &MapParams::slope_crit_deg},
          {"roughness_crit", &MapParams::roughness_crit},
          {"trav_threshold", &MapParams::trav_threshold},
          {"variance_threshold", &MapParams::variance_threshold},
          {"min_range", &MapParams::min_range},
          {"max_range", &MapParams::max_range},
          {"max_height_above_sensor", &MapParams::max_height_above_sensor}};
}

Status BadKey(std::string_view key, std::string_view why) {
  return Status::DataLoss("stored map parameter " + std::string(key) + " " + std::string(why));
}

}  // namespace

std::vector<std::pair<std::string, std::string>> ParamsToKeyValues(const MapParams& p) {
  std::map<std::string_view, std::string> values;
  for (const auto& [key, field] : DoubleFields()) values[key] = FormatDouble(p.*field);
  values["weights"] = FormatDouble(p.weights[0]) + "," + FormatDouble(p.weights[1]) + "," +
                      FormatDouble(p.weights[2]);
  values["observation"] = std::string(ObservationName(p.observation));
  values["tile_size"] = std::to_string(p.tile_size);
  values["method"] = std::string(MethodName(p.method));
  std::vector<std::pair<std::string, std::string>> out;
  for (std::string_view key : MapParamKeys()) out.emplace_back(key, values.at(key));
  return out;
}

Result<MapParams> ParamsFromKeyValues(const std::map<std::string, std::string, std::less<>>& kv) {
  auto get = [&](std::string_view key) -> const std::string* {
    auto it = kv.find(key);
    return it == kv.end() ? nullptr : &it->second;
  };
  for (std::string_view key : MapParamKeys()) {
    if (!get(key)) return BadKey(key, "is missing");
  }
  MapParams p;
  for (const auto& [key, field] : DoubleFields()) {
    if (!ParseDouble(*get(key), &(p.*field))) return BadKey(key, "is not a number: " + *get(key));
  }
  {
    const std::string& text = *get("weights");
    std::string_view rest = text;
    for (int i = 0; i < 3; ++i) {
      const size_t comma = rest.find(',');
      const std::string_view part = rest.substr(0, comma);
      if ((i < 2) == (comma == std::string_view::npos) || !ParseDouble(part, &p.weights[i])) {
        return BadKey("weights", "is not three numbers: " + text);
      }
      rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
    }
  }
  {
    const std::string& text = *get("tile_size");
    const auto res = std::from_chars(text.data(), text.data() + text.size(), p.tile_size);
    if (res.ec != std::errc() || res.ptr != text.data() + text.size()) {
      return BadKey("tile_size", "is not an integer: " + text);
    }
  }
  Result<Observation> observation = ParseObservation(*get("observation"));
  if (!observation.ok()) return BadKey("observation", observation.status().message());
  p.observation = *observation;
  Result<Method> method = ParseMethod(*get("method"));
  if (!method.ok()) return BadKey("method", method.status().message());
  p.method = *method;
  if (Status s = p.Validate(); !s.ok()) {
    return Status::DataLoss("stored map parameters are invalid: " + s.message());
  }
  return p;
}

Status CheckParamsCompatible(const MapParams& stored, const MapParams& requested) {
  std::string why;
  if (stored.StatisticsCompatibleWith(requested, &why)) return Status::Ok();
  return Status::FailedPrecondition(
      "map parameters are incompatible with the stored map: " + why +
      " (stored vs requested); the statistics of one cannot be continued with the other");
}

std::string EncodeMetadata(const MapMetadata& m) {
  std::string out;
  ByteWriter w(&out);
  w.PutVarint(m.format);
  w.PutVarint(m.checkpoint_version);
  w.PutVarint(m.map_version);
  const auto params = ParamsToKeyValues(m.params);
  w.PutVarint(params.size());
  for (const auto& [key, value] : params) {
    w.PutLengthPrefixed(key);
    w.PutLengthPrefixed(value);
  }
  w.PutVarint(m.robot_sequences.size());
  for (const auto& [robot, sequence] : m.robot_sequences) {
    w.PutLengthPrefixed(robot);
    w.PutVarint(sequence);
  }
  return out;
}

Result<MapMetadata> DecodeMetadata(std::string_view bytes) {
  const Status malformed = Status::DataLoss("map metadata is malformed");
  MapMetadata m;
  ByteReader r(bytes);
  uint64_t format, count;
  if (!r.GetVarint(&format) || !r.GetVarint(&m.checkpoint_version) ||
      !r.GetVarint(&m.map_version) || !r.GetVarint(&count)) {
    return malformed;
  }
  if (format > kStoreFormat) {
    return Status::FailedPrecondition("map metadata format " + std::to_string(format) +
                                      " is newer than this build reads (" +
                                      std::to_string(kStoreFormat) + ")");
  }
  m.format = static_cast<uint32_t>(format);
  std::map<std::string, std::string, std::less<>> kv;
  for (uint64_t i = 0; i < count; ++i) {
    std::string_view key, value;
    if (!r.GetLengthPrefixed(&key) || !r.GetLengthPrefixed(&value)) return malformed;
    kv.emplace(key, value);
  }
  Result<MapParams> params = ParamsFromKeyValues(kv);
  if (!params.ok()) return params.status();
  m.params = *params;
  if (!r.GetVarint(&count)) return malformed;
  for (uint64_t i = 0; i < count; ++i) {
    std::string_view robot;
    uint64_t sequence;
    if (!r.GetLengthPrefixed(&robot) || !r.GetVarint(&sequence)) return malformed;
    m.robot_sequences.emplace(robot, sequence);
  }
  if (r.remaining() != 0) return malformed;
  return m;
}

}  // namespace bgkmap::storage
