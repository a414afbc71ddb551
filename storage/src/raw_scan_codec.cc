#include "bgkmap/storage/raw_scan_codec.h"

#include <cstring>
#include <optional>

#include "bgkmap/proto/compact_points.h"
#include "bgkmap/storage/crc32c.h"
#include "byte_coding.h"

namespace bgkmap::storage {
namespace {

constexpr uint8_t kFloatFormat = 1;
constexpr uint8_t kCompactFormat = 2;

bool SamePoints(const std::vector<Point3f>& a, const std::vector<Point3f>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(Point3f)) == 0);
}

// The compact form of `source`'s points if it gives back exactly these points in this order:
// the smaller order first (a spatially sorted scan's points are already sorted), else along the
// rays (or, where those residuals overflow, the plain scan order). None for points that are not all on the quantum's grid.
std::optional<CompactPoints> CompactForm(const RawScan& source) {
  if (!(source.quantum > 0.0)) return std::nullopt;
  for (std::optional<PointOrder> order : {std::optional<PointOrder>(), {PointOrder::kScanRay}}) {
    uint64_t skipped = 0;
    Result<CompactPoints> compact =
        EncodeCompactPoints(source.points, source.quantum, &skipped, order);
    if (!compact.ok() || skipped > 0) return std::nullopt;
    Result<std::vector<Point3f>> back = DecodeCompactPoints(*compact, source.points.size());
    if (back.ok() && SamePoints(*back, source.points)) return std::move(compact).value();
  }
  return std::nullopt;
}

// Format 2's points: step, count, order, the zstd frame's length and bytes, nothing after.
bool DecodeCompactTail(ByteReader* r, RawScan* source) {
  CompactPoints compact;
  uint64_t count = 0, size = 0;
  uint8_t order = 0;
  std::string_view data;
  if (!r->GetDouble(&compact.step) || !r->GetVarint(&count) || count > UINT32_MAX ||
      !r->GetU8(&order) || !r->GetVarint(&size) || size != r->remaining() ||
      !r->GetBytes(size, &data)) {
    return false;
  }
  compact.count = static_cast<uint32_t>(count);
  compact.order = static_cast<PointOrder>(order);
  compact.data.assign(data);
  Result<std::vector<Point3f>> points = DecodeCompactPoints(compact, count);
  if (!points.ok()) return false;
  source->points = std::move(points).value();
  source->quantum = compact.step;
  return true;
}

}  // namespace

std::string EncodeRawScan(const RawScan& source) {
  const std::optional<CompactPoints> compact = CompactForm(source);
  std::string out;
  out.reserve(128 + (compact ? compact->data.size() : source.points.size() * sizeof(Point3f)));
  ByteWriter w(&out);
  w.PutU8(compact ? kCompactFormat : kFloatFormat);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) w.PutDouble(source.pose.rotation(r, c));
  }
  for (int i = 0; i < 3; ++i) w.PutDouble(source.pose.translation(i));
  w.PutU8(source.frame_is_map ? 1 : 0);
  if (compact) {
    w.PutDouble(compact->step);
    w.PutVarint(compact->count);
    w.PutU8(static_cast<uint8_t>(compact->order));
    w.PutVarint(compact->data.size());
    w.PutBytes(compact->data);
  } else {
    w.PutVarint(source.points.size());
    static_assert(sizeof(Point3f) == 3 * sizeof(float));
    w.PutShuffled(source.points.data(), source.points.size() * 3, sizeof(float));
  }
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
  if (!r.GetU8(&format) || (format != kFloatFormat && format != kCompactFormat)) {
    return malformed;
  }
  RawScan source;
  for (int row = 0; row < 3; ++row) {
    for (int c = 0; c < 3; ++c) {
      if (!r.GetDouble(&source.pose.rotation(row, c))) return malformed;
    }
  }
  for (int i = 0; i < 3; ++i) {
    if (!r.GetDouble(&source.pose.translation(i))) return malformed;
  }
  if (!r.GetU8(&frame_is_map) || frame_is_map > 1) return malformed;
  source.frame_is_map = frame_is_map == 1;
  if (format == kCompactFormat) {
    if (!DecodeCompactTail(&r, &source)) return malformed;
    return source;
  }
  uint64_t n;
  if (!r.GetVarint(&n) || n > r.remaining() / sizeof(Point3f)) return malformed;
  source.points.resize(n);
  if (!r.GetShuffled(source.points.data(), n * 3, sizeof(float)) || r.remaining() != 0) {
    return malformed;
  }
  return source;
}

}  // namespace bgkmap::storage
