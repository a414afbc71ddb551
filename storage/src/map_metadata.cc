#include "bgkmap/storage/map_metadata.h"

#include <charconv>

#include "bgkmap/core/map_param_table.h"
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

std::string Triple(const std::array<double, 3>& v) {
  return FormatDouble(v[0]) + "," + FormatDouble(v[1]) + "," + FormatDouble(v[2]);
}

// "a,b,c" into three doubles.
bool ParseTriple(std::string_view text, std::array<double, 3>* v) {
  std::string_view rest = text;
  for (size_t i = 0; i < 3; ++i) {
    const size_t comma = rest.find(',');
    if ((i < 2) == (comma == std::string_view::npos) ||
        !ParseDouble(rest.substr(0, comma), &(*v)[i]))
      return false;
    rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
  }
  return true;
}

Status BadKey(std::string_view key, std::string_view why) {
  return Status::DataLoss("stored map parameter " + std::string(key) + " " + std::string(why));
}

// A parameter's stored text: doubles in shortest round-trip form, weights as "a,b,c".
std::string ParamText(const MapParamInfo& info, const MapParams& p) {
  switch (info.kind) {
    case MapParamKind::kDouble:
      return FormatDouble(p.*info.real);
    case MapParamKind::kInt:
      return std::to_string(p.*info.integer);
    case MapParamKind::kDouble3:
      return Triple(p.*info.triple);
    case MapParamKind::kEnum:
      return std::string(info.enum_name(p));
  }
  return "";
}

Status ParseParamText(const MapParamInfo& info, std::string_view text, MapParams& p) {
  switch (info.kind) {
    case MapParamKind::kDouble:
      if (!ParseDouble(text, &(p.*info.real)))
        return BadKey(info.key, "is not a number: " + std::string(text));
      return Status::Ok();
    case MapParamKind::kInt: {
      const auto res = std::from_chars(text.data(), text.data() + text.size(), p.*info.integer);
      if (res.ec != std::errc() || res.ptr != text.data() + text.size()) {
        return BadKey(info.key, "is not an integer: " + std::string(text));
      }
      return Status::Ok();
    }
    case MapParamKind::kDouble3:
      if (!ParseTriple(text, &(p.*info.triple)))
        return BadKey(info.key, "is not three numbers: " + std::string(text));
      return Status::Ok();
    case MapParamKind::kEnum:
      if (Status s = info.enum_parse(text, p); !s.ok()) return BadKey(info.key, s.message());
      return Status::Ok();
  }
  return Status::Ok();
}

// Where EncodeMetadata keeps the georeference among the parameters' pairs.
constexpr std::string_view kGeoreferencePrefix = "georeference/";

}  // namespace

std::vector<std::pair<std::string, std::string>> ParamsToKeyValues(const MapParams& p) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const MapParamInfo& info : MapParamTable()) out.emplace_back(info.key, ParamText(info, p));
  return out;
}

Result<MapParams> ParamsFromKeyValues(const std::map<std::string, std::string, std::less<>>& kv) {
  for (const MapParamInfo& info : MapParamTable()) {
    if (kv.find(info.key) == kv.end() && info.legacy_text.empty()) {
      return BadKey(info.key, "is missing");
    }
  }
  MapParams p;
  for (const MapParamInfo& info : MapParamTable()) {
    // A key added after the store was written: the value the store was built with.
    const auto it = kv.find(info.key);
    const std::string_view text = it != kv.end() ? std::string_view(it->second) : info.legacy_text;
    if (Status s = ParseParamText(info, text, p); !s.ok()) return s;
  }
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

Status CheckGeoreferenceCompatible(const Georeference& stored, const Georeference& requested,
                                   std::string_view roles) {
  if (stored.empty() || requested.empty() || stored == requested) return Status::Ok();
  // Appended piecewise: GCC 12 warns falsely on "[" + std::string.
  std::string message;
  if (stored.crs != requested.crs) {
    message += "georeference.crs differs: \"";
    message += stored.crs;
    message += "\" vs \"";
    message += requested.crs;
    message += "\"";
  } else {
    message += "georeference.origin differs: [";
    message += Triple(stored.origin);
    message += "] vs [";
    message += Triple(requested.origin);
    message += "]";
  }
  message += " (";
  message += roles;
  message += "); a map is tied to one coordinate system, or its cells would be placed wrongly";
  return Status::FailedPrecondition(message);
}

std::vector<std::pair<std::string, std::string>> GeoreferenceToKeyValues(const Georeference& g) {
  if (g.empty()) return {};
  return {{"crs", g.crs}, {"origin", Triple(g.origin)}};
}

Result<Georeference> GeoreferenceFromKeyValues(
    const std::map<std::string, std::string, std::less<>>& kv) {
  Georeference g;
  if (kv.empty()) return g;
  const auto crs = kv.find("crs"), origin = kv.find("origin");
  if (crs == kv.end() || crs->second.empty()) {
    return Status::DataLoss("stored georeference.crs is missing");
  }
  g.crs = crs->second;
  if (origin == kv.end() || !ParseTriple(origin->second, &g.origin)) {
    return Status::DataLoss("stored georeference.origin is not three numbers" +
                            (origin == kv.end() ? std::string() : ": " + origin->second));
  }
  return g;
}

std::string EncodeMetadata(const MapMetadata& m) {
  std::string out;
  ByteWriter w(&out);
  w.PutVarint(m.format);
  w.PutVarint(m.checkpoint_version);
  w.PutVarint(m.map_version);
  auto params = ParamsToKeyValues(m.params);
  for (auto& [key, value] : GeoreferenceToKeyValues(m.georeference)) {
    params.emplace_back(std::string(kGeoreferencePrefix) + key, std::move(value));
  }
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
  std::map<std::string, std::string, std::less<>> kv, geo;
  for (uint64_t i = 0; i < count; ++i) {
    std::string_view key, value;
    if (!r.GetLengthPrefixed(&key) || !r.GetLengthPrefixed(&value)) return malformed;
    if (key.starts_with(kGeoreferencePrefix)) {
      geo.emplace(key.substr(kGeoreferencePrefix.size()), value);
    } else {
      kv.emplace(key, value);
    }
  }
  Result<MapParams> params = ParamsFromKeyValues(kv);
  if (!params.ok()) return params.status();
  m.params = *params;
  Result<Georeference> georeference = GeoreferenceFromKeyValues(geo);
  if (!georeference.ok()) return georeference.status();
  m.georeference = *georeference;
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
