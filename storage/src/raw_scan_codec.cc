#include "bgkmap/storage/raw_scan_codec.h"

#include <cstring>

#include "bgkmap/storage/crc32c.h"
#include "byte_coding.h"

namespace bgkmap::storage {
namespace {
constexpr uint8_t kRawScanFormat = 1;
}

std::string EncodeRawScan(const RawScan& source) {
  std::string out;
  out.reserve(128 + source.points.size() * sizeof(Point3f));
  ByteWriter w(&out);
  w.PutU8(kRawScanFormat);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) w.PutDouble(source.pose.rotation(r, c));
  }
  for (int i = 0; i < 3; ++i) w.PutDouble(source.pose.translation(i));
  w.PutU8(source.frame_is_map ? 1 : 0);
  w.PutVarint(source.points.size());
  static_assert(sizeof(Point3f) == 3 * sizeof(float));
  w.PutShuffled(source.points.data(), source.points.size() * 3, sizeof(float));
  w.PutFixed32(Crc32c(out));
  return out;
}

Result<RawScan> DecodeRawScan(std::string_view encoded) {
  const Status malformed = Status::DataLoss("raw scan is malformed");
  if (encoded.size() < 4) return malformed;
  const std::string_view body = encoded.substr(0, encoded.size() - 4);
  uint32_t stored_crc;
  std::memcpy(&stored_crc, encoded.data() + body.size(), 4);
  if (Crc32c(body) != stored_crc) return Status::DataLoss("raw scan checksum mismatch");
  ByteReader r(body);
  uint8_t format, frame_is_map;
  if (!r.GetU8(&format) || format != kRawScanFormat) return malformed;
  RawScan source;
  for (int row = 0; row < 3; ++row) {
    for (int c = 0; c < 3; ++c) {
      if (!r.GetDouble(&source.pose.rotation(row, c))) return malformed;
    }
  }
  for (int i = 0; i < 3; ++i) {
    if (!r.GetDouble(&source.pose.translation(i))) return malformed;
  }
  uint64_t n;
  if (!r.GetU8(&frame_is_map) || frame_is_map > 1 || !r.GetVarint(&n) ||
      n > r.remaining() / sizeof(Point3f)) {
    return malformed;
  }
  source.frame_is_map = frame_is_map == 1;
  source.points.resize(n);
  if (!r.GetShuffled(source.points.data(), n * 3, sizeof(float)) || r.remaining() != 0) {
    return malformed;
  }
  return source;
}

}  // namespace bgkmap::storage
