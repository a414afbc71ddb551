#include "bgkmap/io/las_reader.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

namespace bgkmap::io {
namespace {

static_assert(std::endian::native == std::endian::little, "LAS decoding assumes little-endian");

// Header field offsets (ASPRS LAS 1.4 R15, Table 3; identical in 1.0-1.3 up to byte 227).
constexpr size_t kVersionMajor = 24, kVersionMinor = 25, kHeaderSize = 94, kPointOffset = 96,
                 kPointFormat = 104, kRecordLength = 105, kLegacyCount = 107, kScale = 131,
                 kVlrCount = 100, kOffset = 155, kMaxX = 179, kPointCount14 = 247;
constexpr size_t kMinHeader = 227, kMinHeader14 = 375;

// Minimum record length of point formats 0-10.
constexpr uint16_t kMinRecordLength[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

template <typename T>
T Get(const char* bytes, size_t at) {
  T v;
  std::memcpy(&v, bytes + at, sizeof(T));
  return v;
}

// The CRS of the variable-length records between the header and the points (LAS 1.4 R15,
// section 2.5 and 2.6): the OGC WKT record (LASF_Projection 2112) wins, else the GeoTIFF keys
// (34735) ProjectedCSTypeGeoKey (3072), else GeographicTypeGeoKey (2048).
std::string ReadCrs(std::ifstream& in, const LasHeader& h, uint32_t vlr_count) {
  constexpr size_t kVlrHeader = 54;
  std::string wkt, epsg;
  uint64_t at = h.header_size;
  for (uint32_t i = 0; i < vlr_count && at + kVlrHeader <= h.point_data_offset; ++i) {
    char raw[kVlrHeader];
    in.clear();
    in.seekg(static_cast<std::streamoff>(at));
    if (!in.read(raw, sizeof(raw))) break;
    const std::string user(raw + 2, strnlen(raw + 2, 16));
    const uint16_t record = Get<uint16_t>(raw, 18), length = Get<uint16_t>(raw, 20);
    if (at + kVlrHeader + length > h.point_data_offset) break;
    std::string data(length, '\0');
    if (!in.read(data.data(), length)) break;
    at += kVlrHeader + length;
    if (user != "LASF_Projection") continue;
    if (record == 2112) {
      wkt.assign(data.c_str());  // NUL-terminated
    } else if (record == 34735 && length >= 8) {
      // Header {version, revision, minor, key count}, then keys {id, location, count, value}.
      const uint16_t keys = Get<uint16_t>(data.data(), 6);
      for (uint16_t k = 0; k < keys && 8 + 8 * (k + 1) <= length; ++k) {
        const char* key = data.data() + 8 + 8 * k;
        const uint16_t id = Get<uint16_t>(key, 0), location = Get<uint16_t>(key, 2);
        const uint16_t value = Get<uint16_t>(key, 6);
        if (location != 0 || value == 0 || value == 32767) continue;  // not an inline code
        if (id == 3072 || (id == 2048 && epsg.empty())) epsg = "EPSG:" + std::to_string(value);
      }
    }
  }
  return !wkt.empty() ? wkt : epsg;
}

}  // namespace

Result<LasHeader> ReadLasHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IoError(path + ": cannot open");
  std::error_code ec;
  const uintmax_t file_size = std::filesystem::file_size(path, ec);
  if (ec) return Status::IoError(path + ": cannot stat (" + ec.message() + ")");

  char raw[kMinHeader14] = {};
  in.read(raw, sizeof(raw));
  const size_t got = static_cast<size_t>(in.gcount());
  if (got < 4 || std::memcmp(raw, "LASF", 4) != 0) {
    return Status::DataLoss(path + ": not a LAS file (no LASF signature)");
  }
  if (got < kMinHeader) {
    return Status::DataLoss(
        fmt::format("{}: truncated header ({} bytes, need {})", path, got, kMinHeader));
  }
  LasHeader h;
  h.version_major = Get<uint8_t>(raw, kVersionMajor);
  h.version_minor = Get<uint8_t>(raw, kVersionMinor);
  h.header_size = Get<uint16_t>(raw, kHeaderSize);
  h.point_data_offset = Get<uint32_t>(raw, kPointOffset);
  const uint8_t format_byte = Get<uint8_t>(raw, kPointFormat);
  h.point_record_length = Get<uint16_t>(raw, kRecordLength);
  h.point_count = Get<uint32_t>(raw, kLegacyCount);
  for (int i = 0; i < 3; ++i) {
    h.scale[i] = Get<double>(raw, kScale + 8 * i);
    h.offset[i] = Get<double>(raw, kOffset + 8 * i);
    h.max[i] = Get<double>(raw, kMaxX + 16 * i);
    h.min[i] = Get<double>(raw, kMaxX + 16 * i + 8);
  }

  if (h.version_major != 1 || h.version_minor > 4) {
    return Status::DataLoss(
        fmt::format("{}: unsupported LAS version {}.{}", path, h.version_major, h.version_minor));
  }
  const size_t min_header = h.version_minor >= 4 ? kMinHeader14 : kMinHeader;
  if (h.header_size < min_header || got < min_header) {
    return Status::DataLoss(fmt::format("{}: header size {} too small for LAS 1.{} (need {})", path,
                                        h.header_size, h.version_minor, min_header));
  }
  if (h.version_minor >= 4) {
    const uint64_t count64 = Get<uint64_t>(raw, kPointCount14);
    if (count64 != 0) h.point_count = count64;
  }
  // LAZ writers set bit 7 (and sometimes bit 6) of the format byte.
  if (format_byte & 0xC0) {
    return Status::DataLoss(path +
                            ": compressed point data (LAZ) is unsupported; decompress it "
                            "first (e.g. laszip or pdal translate)");
  }
  h.point_format = format_byte;
  if (h.point_format > 10) {
    return Status::DataLoss(fmt::format("{}: unsupported point format {}", path, h.point_format));
  }
  if (h.point_record_length < kMinRecordLength[h.point_format]) {
    return Status::DataLoss(
        fmt::format("{}: point record length {} is below the {} bytes of "
                    "point format {}",
                    path, h.point_record_length, kMinRecordLength[h.point_format], h.point_format));
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(h.scale[i]) || h.scale[i] == 0 || !std::isfinite(h.offset[i])) {
      return Status::DataLoss(fmt::format("{}: invalid scale/offset of axis {}", path, "xyz"[i]));
    }
  }
  if (h.point_data_offset < h.header_size) {
    return Status::DataLoss(fmt::format("{}: point data offset {} lies inside the {}-byte header",
                                        path, h.point_data_offset, h.header_size));
  }
  // Divide rather than multiply so a corrupt 64-bit count cannot overflow.
  const uintmax_t available = file_size > h.point_data_offset ? file_size - h.point_data_offset : 0;
  if (h.point_count > available / h.point_record_length) {
    return Status::DataLoss(
        fmt::format("{}: truncated: header promises {} points of {} bytes from "
                    "offset {}, file has {} bytes",
                    path, h.point_count, h.point_record_length, h.point_data_offset, file_size));
  }
  h.crs = ReadCrs(in, h, Get<uint32_t>(raw, kVlrCount));
  return h;
}

Result<LasCloud> ReadLas(const std::string& path, const LasReadOptions& options) {
  Result<LasHeader> header = ReadLasHeader(path);
  if (!header.ok()) return header.status();
  const LasHeader& h = *header;

  bool keep[256];
  std::fill(std::begin(keep), std::end(keep), options.classes.empty());
  for (uint8_t c : options.classes) keep[c] = true;
  // Formats 0-5 pack 5 class bits with 3 flag bits; 6-10 have a whole byte at offset 16.
  const bool extended = h.point_format >= 6;
  const size_t class_at = extended ? 16 : 15;
  const uint8_t class_mask = extended ? 0xFF : 0x1F;

  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IoError(path + ": cannot open");
  in.seekg(h.point_data_offset);

  LasCloud cloud;
  cloud.header = h;
  if (options.classes.empty()) {
    cloud.points.reserve(h.point_count);
    cloud.classification.reserve(h.point_count);
  }
  constexpr uint64_t kChunk = 1 << 16;
  std::vector<char> buffer;
  for (uint64_t done = 0; done < h.point_count;) {
    const uint64_t n = std::min(kChunk, h.point_count - done);
    buffer.resize(n * h.point_record_length);
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    if (static_cast<size_t>(in.gcount()) != buffer.size()) {
      return Status::DataLoss(fmt::format(
          "{}: truncated point data at point {} of {}", path,
          done + static_cast<uint64_t>(in.gcount()) / h.point_record_length, h.point_count));
    }
    for (uint64_t i = 0; i < n; ++i) {
      const char* rec = buffer.data() + i * h.point_record_length;
      const uint8_t cls = Get<uint8_t>(rec, class_at) & class_mask;
      if (!keep[cls]) continue;
      cloud.points.push_back({Get<int32_t>(rec, 0) * h.scale[0] + h.offset[0],
                              Get<int32_t>(rec, 4) * h.scale[1] + h.offset[1],
                              Get<int32_t>(rec, 8) * h.scale[2] + h.offset[2]});
      cloud.classification.push_back(cls);
    }
    done += n;
  }
  return cloud;
}

}  // namespace bgkmap::io
