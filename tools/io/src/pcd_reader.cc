#include "bgkmap/io/pcd_reader.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstring>
#include <string_view>

#include "binary_file.h"

namespace bgkmap::io {
namespace {

static_assert(std::endian::native == std::endian::little,
              "PCD binary decoding assumes little-endian");

struct Field {
  std::string name;
  int size = 4;
  char type = 'F';
  int count = 1;
  size_t byte_offset = 0;   // within a binary record
  size_t token_offset = 0;  // within an ascii line
};

struct Header {
  std::vector<Field> fields;
  uint64_t width = 0, height = 0, points = 0;
  bool have_points = false;
  std::string data;
  size_t data_start = 0;  // byte after the DATA line
};

// Whitespace-separated tokens, viewing into `line` (no copies: ascii clouds can be large).
std::vector<std::string_view> Split(std::string_view line) {
  std::vector<std::string_view> out;
  size_t pos = 0;
  while (true) {
    pos = line.find_first_not_of(" \t\r", pos);
    if (pos == std::string_view::npos) break;
    const size_t end = std::min(line.find_first_of(" \t\r", pos), line.size());
    out.push_back(line.substr(pos, end - pos));
    pos = end;
  }
  return out;
}

template <typename T>
bool ParseNumber(std::string_view s, T& out) {
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && end == s.data() + s.size();
}

// Parses the header lines; the error message has no file prefix.
Result<Header> ParseHeader(std::string_view text) {
  Header h;
  size_t pos = 0;
  std::vector<std::string> sizes, types, counts;
  while (pos < text.size()) {
    size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    const std::string_view line = text.substr(pos, nl - pos);
    pos = std::min(nl + 1, text.size());
    const std::vector<std::string_view> tok = Split(line);
    if (tok.empty() || tok[0][0] == '#') continue;
    const std::string key(tok[0]);
    const std::vector<std::string> args(tok.begin() + 1, tok.end());
    if (key == "VERSION" || key == "VIEWPOINT") {
      continue;
    } else if (key == "FIELDS") {
      for (const auto& name : args) h.fields.push_back({.name = name});
    } else if (key == "SIZE") {
      sizes = args;
    } else if (key == "TYPE") {
      types = args;
    } else if (key == "COUNT") {
      counts = args;
    } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
      uint64_t v = 0;
      if (args.size() != 1 || !ParseNumber(args[0], v))
        return Status::DataLoss("bad " + key + " line");
      (key == "WIDTH" ? h.width : key == "HEIGHT" ? h.height : h.points) = v;
      if (key == "POINTS") h.have_points = true;
    } else if (key == "DATA") {
      if (args.size() != 1) return Status::DataLoss("bad DATA line");
      h.data = args[0];
      h.data_start = pos;
      break;
    } else {
      return Status::DataLoss("unknown header line '" + std::string(line) + "'");
    }
  }
  if (h.data.empty()) return Status::DataLoss("no DATA line");
  if (h.fields.empty()) return Status::DataLoss("no FIELDS line");
  const size_t nf = h.fields.size();
  if (sizes.size() != nf || types.size() != nf || (!counts.empty() && counts.size() != nf)) {
    return Status::DataLoss(fmt::format("{} FIELDS but {} SIZE, {} TYPE, {} COUNT entries", nf,
                                        sizes.size(), types.size(), counts.size()));
  }
  size_t bytes = 0, tokens = 0;
  for (size_t i = 0; i < nf; ++i) {
    Field& f = h.fields[i];
    if (!ParseNumber(sizes[i], f.size) ||
        (f.size != 1 && f.size != 2 && f.size != 4 && f.size != 8))
      return Status::DataLoss("bad SIZE '" + sizes[i] + "'");
    if (types[i].size() != 1 || std::string_view("FIU").find(types[i][0]) == std::string_view::npos)
      return Status::DataLoss("bad TYPE '" + types[i] + "'");
    f.type = types[i][0];
    if (!counts.empty() && (!ParseNumber(counts[i], f.count) || f.count < 1))
      return Status::DataLoss("bad COUNT '" + counts[i] + "'");
    f.byte_offset = bytes;
    f.token_offset = tokens;
    bytes += static_cast<size_t>(f.size) * f.count;
    tokens += f.count;
  }
  if (!h.have_points) h.points = h.width * std::max<uint64_t>(h.height, 1);
  return h;
}

}  // namespace

Result<PcdCloud> ReadPcd(const std::string& path) {
  Result<std::string> file = internal::ReadWholeFile(path);
  if (!file.ok()) return file.status();
  const std::string& text = *file;

  Result<Header> parsed = ParseHeader(text);
  if (!parsed.ok()) return Status::DataLoss(path + ": " + parsed.status().message());
  const Header& h = *parsed;

  const Field* xyz[3] = {};
  for (const Field& f : h.fields) {
    for (int a = 0; a < 3; ++a) {
      if (f.name == std::string(1, "xyz"[a])) xyz[a] = &f;
    }
  }
  for (int a = 0; a < 3; ++a) {
    if (!xyz[a]) return Status::DataLoss(fmt::format("{}: no '{}' field", path, "xyz"[a]));
    const Field& f = *xyz[a];
    if (f.type != 'F' || (f.size != 4 && f.size != 8) || f.count != 1) {
      return Status::DataLoss(
          fmt::format("{}: field '{}' must be TYPE F, SIZE 4 or 8, COUNT 1", path, f.name));
    }
  }

  PcdCloud cloud;
  for (const Field& f : h.fields) cloud.fields.push_back(f.name);
  cloud.width = h.width;
  cloud.height = h.height;
  const Field& last = h.fields.back();

  if (h.data == "binary") {
    const size_t record = last.byte_offset + static_cast<size_t>(last.size) * last.count;
    const size_t available = text.size() - h.data_start;
    if (h.points > available / record) {
      return Status::DataLoss(
          fmt::format("{}: truncated: {} points of {} bytes need {} bytes of "
                      "data, file has {}",
                      path, h.points, record, h.points * record, available));
    }
    cloud.points.resize(h.points);
    const char* base = text.data() + h.data_start;
    for (uint64_t i = 0; i < h.points; ++i) {
      double v[3];
      for (int a = 0; a < 3; ++a) {
        const char* at = base + i * record + xyz[a]->byte_offset;
        if (xyz[a]->size == 4) {
          float f;
          std::memcpy(&f, at, 4);
          v[a] = f;
        } else {
          std::memcpy(&v[a], at, 8);
        }
      }
      cloud.points[i] = {v[0], v[1], v[2]};
    }
  } else if (h.data == "ascii") {
    const size_t tokens = last.token_offset + last.count;
    std::string_view rest(text);
    rest.remove_prefix(h.data_start);
    // POINTS is not trusted for the allocation: a line takes at least 2 bytes per value.
    cloud.points.reserve(std::min<uint64_t>(h.points, rest.size() / (2 * tokens) + 1));
    size_t line_no = 0;
    while (cloud.points.size() < h.points && !rest.empty()) {
      const size_t nl = rest.find('\n');
      const std::string_view line = rest.substr(0, nl);
      rest = nl == std::string_view::npos ? std::string_view() : rest.substr(nl + 1);
      ++line_no;
      const std::vector<std::string_view> tok = Split(line);
      if (tok.empty()) continue;
      if (tok.size() != tokens) {
        return Status::DataLoss(fmt::format("{}: data line {} has {} values, expected {}", path,
                                            line_no, tok.size(), tokens));
      }
      double v[3];
      for (int a = 0; a < 3; ++a) {
        const std::string_view s = tok[xyz[a]->token_offset];
        if (!ParseNumber(s, v[a])) {
          return Status::DataLoss(
              fmt::format("{}: data line {}: '{}' is not a number", path, line_no, s));
        }
      }
      cloud.points.push_back({v[0], v[1], v[2]});
    }
    if (cloud.points.size() < h.points) {
      return Status::DataLoss(fmt::format("{}: truncated: {} of {} points present", path,
                                          cloud.points.size(), h.points));
    }
  } else if (h.data == "binary_compressed") {
    return Status::DataLoss(path +
                            ": DATA binary_compressed is unsupported; re-save as binary "
                            "(e.g. pcl_convert_pcd_ascii_binary <in> <out> 1)");
  } else {
    return Status::DataLoss(path + ": unknown DATA '" + h.data + "'");
  }
  return cloud;
}

}  // namespace bgkmap::io
