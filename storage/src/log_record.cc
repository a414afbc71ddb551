#include "bgkmap/storage/log_record.h"

#include <bit>
#include <cstring>
#include <vector>

#include "bgkmap/storage/crc32c.h"
#include "byte_coding.h"
#include "store_keys.h"

namespace bgkmap::storage {
namespace {

void PutTileKeys(ByteWriter& w, const std::vector<TileKey>& keys) {
  w.PutVarint(keys.size());
  TileKey prev{0, 0};
  for (const TileKey& k : keys) {
    w.PutSignedVarint(int64_t{k.x} - prev.x);
    w.PutSignedVarint(int64_t{k.y} - prev.y);
    prev = k;
  }
}

// Reads one delta-coded int32 coordinate; false if it leaves the int32 range.
bool GetDelta(ByteReader& r, int* coordinate) {
  int64_t delta;
  // Any step between two int32 values is within +-2^32; a larger one is damage, and would
  // overflow the sum below.
  if (!r.GetSignedVarint(&delta) || delta < -(int64_t{1} << 32) || delta > (int64_t{1} << 32)) {
    return false;
  }
  const int64_t v = int64_t{*coordinate} + delta;
  if (v < INT32_MIN || v > INT32_MAX) return false;
  *coordinate = static_cast<int>(v);
  return true;
}

bool GetTileKeys(ByteReader& r, std::vector<TileKey>* keys) {
  uint64_t n;
  if (!r.GetVarint(&n) || n > r.remaining() / 2) return false;
  keys->resize(n);
  TileKey prev{0, 0};
  for (TileKey& k : *keys) {
    if (!GetDelta(r, &prev.x) || !GetDelta(r, &prev.y)) return false;
    k = prev;
  }
  return true;
}

void PutCells(ByteWriter& w, const std::vector<ObservedCell>& cells, uint8_t format) {
  w.PutVarint(cells.size());
  CellIndex prev{0, 0};
  for (const ObservedCell& cell : cells) {
    w.PutSignedVarint(int64_t{cell.cell.x} - prev.x);
    w.PutSignedVarint(int64_t{cell.cell.y} - prev.y);
    prev = cell.cell;
  }
  uint64_t previous = 0;
  for (const ObservedCell& cell : cells) {
    const uint64_t bits = std::bit_cast<uint64_t>(cell.y);
    w.PutFixed64(bits ^ previous);
    previous = bits;
  }
  if (format < kLogFormatWithSpans) return;
  for (const ObservedCell& cell : cells) w.PutVarint(cell.span_mm);
}

void PutScan(ByteWriter& w, const LogRecord& record) {
  static const PreparedScan kNone;
  const PreparedScan& scan = record.scan ? *record.scan : kNone;
  const ScanPointCounts& c = scan.counts;
  for (uint64_t v : {c.input, c.kept, c.dropped_nonfinite, c.dropped_range, c.dropped_height,
                     c.dropped_out_of_bounds}) {
    w.PutVarint(v);
  }
  w.PutDouble(scan.sensor_z);
  w.PutU8(scan.has_sensor ? 1 : 0);
  w.PutDouble(scan.sensor_x);
  w.PutDouble(scan.sensor_y);
  PutTileKeys(w, scan.write_tiles);
  PutTileKeys(w, scan.read_tiles);
  PutTileKeys(w, scan.clear_tiles);
  w.PutU8(record.cells_in_source ? 1 : 0);
  if (record.cells_in_source) {
    w.PutFixed32(record.cells_crc);
  } else {
    PutCells(w, scan.cells, kLogRecordFormat);
  }
}

bool GetScan(ByteReader& r, uint8_t format, PreparedScan* scan, LogRecord* record) {
  ScanPointCounts& c = scan->counts;
  for (uint64_t* v : {&c.input, &c.kept, &c.dropped_nonfinite, &c.dropped_range, &c.dropped_height,
                      &c.dropped_out_of_bounds}) {
    if (!r.GetVarint(v)) return false;
  }
  if (!r.GetDouble(&scan->sensor_z)) return false;
  if (format >= 2) {  // format 1 had no sensor position: its scans bring no free-space evidence
    uint8_t has_sensor;
    if (!r.GetU8(&has_sensor) || has_sensor > 1 || !r.GetDouble(&scan->sensor_x) ||
        !r.GetDouble(&scan->sensor_y)) {
      return false;
    }
    scan->has_sensor = has_sensor == 1;
  }
  if (!GetTileKeys(r, &scan->write_tiles) || !GetTileKeys(r, &scan->read_tiles) ||
      (format >= 2 && !GetTileKeys(r, &scan->clear_tiles))) {
    return false;
  }
  if (format >= 4) {
    uint8_t in_source;
    if (!r.GetU8(&in_source) || in_source > 1) return false;
    record->cells_in_source = in_source == 1;
    if (record->cells_in_source) return r.GetFixed32(&record->cells_crc);
  }
  uint64_t n;
  const uint64_t min_cell_bytes = format >= kLogFormatWithSpans ? 2 + 8 + 1 : 2 + 8;
  if (!r.GetVarint(&n) || n > r.remaining() / min_cell_bytes) return false;
  scan->cells.resize(n);
  CellIndex prev{0, 0};
  for (ObservedCell& cell : scan->cells) {
    if (!GetDelta(r, &prev.x) || !GetDelta(r, &prev.y)) return false;
    cell.cell = prev;
  }
  uint64_t previous = 0;
  for (ObservedCell& cell : scan->cells) {
    uint64_t bits;
    if (!r.GetFixed64(&bits)) return false;
    previous ^= bits;
    cell.y = std::bit_cast<double>(previous);
  }
  if (format < kLogFormatWithSpans) return true;
  for (ObservedCell& cell : scan->cells) {
    uint64_t span;
    if (!r.GetVarint(&span) || span > UINT16_MAX) return false;
    cell.span_mm = static_cast<uint16_t>(span);
  }
  return true;
}

}  // namespace

LogRecord LogRecord::Scan(uint64_t version, std::string robot_id, uint64_t sequence,
                          std::shared_ptr<const PreparedScan> scan, int64_t stamp_ns) {
  LogRecord r;
  r.type = Type::kScan;
  r.version = version;
  r.robot_id = std::move(robot_id);
  r.sequence = sequence;
  r.stamp_ns = stamp_ns;
  r.scan = std::move(scan);
  return r;
}

LogRecord LogRecord::Clear(uint64_t version, const CellBox& box) {
  LogRecord r;
  r.type = Type::kClear;
  r.version = version;
  r.clear_box = box;
  return r;
}

LogRecord LogRecord::Correction(uint64_t version, std::string robot_id, uint64_t base_version,
                                std::vector<TileKey> seed_tiles,
                                std::vector<uint64_t> revised_versions) {
  LogRecord r;
  r.type = Type::kCorrection;
  r.version = version;
  r.robot_id = std::move(robot_id);
  r.base_version = base_version;
  r.seed_tiles = std::move(seed_tiles);
  r.revised_versions = std::move(revised_versions);
  return r;
}

uint32_t LoggedCellsCrc(const PreparedScan& scan, uint8_t format) {
  std::string bytes;
  bytes.reserve(8 + scan.cells.size() * 12);
  ByteWriter w(&bytes);
  PutCells(w, scan.cells, format);
  return Crc32c(bytes);
}

std::string EncodeLogRecord(const LogRecord& record) {
  std::string out;
  if (record.type == LogRecord::Type::kScan && record.scan && !record.cells_in_source) {
    out.reserve(64 + record.scan->cells.size() * 12);
  }
  ByteWriter w(&out);
  w.PutU8(kLogRecordFormat);
  w.PutU8(static_cast<uint8_t>(record.type));
  w.PutVarint(record.version);
  w.PutLengthPrefixed(record.robot_id);
  w.PutVarint(record.sequence);
  w.PutSignedVarint(record.stamp_ns);
  if (record.type == LogRecord::Type::kScan) {
    PutScan(w, record);
  } else if (record.type == LogRecord::Type::kClear) {
    const CellBox& b = record.clear_box;
    for (int v : {b.min.x, b.min.y, b.max.x, b.max.y}) w.PutSignedVarint(v);
  } else {
    w.PutVarint(record.base_version);
    PutTileKeys(w, record.seed_tiles);
    w.PutBytes(EncodeVersionList(record.revised_versions));  // last: it runs to the checksum
  }
  w.PutFixed32(Crc32c(out));
  return out;
}

Result<LogRecord> DecodeLogRecord(std::string_view encoded) {
  const Status malformed = Status::DataLoss("log record is malformed");
  if (encoded.size() < 4) return malformed;
  const std::string_view body = encoded.substr(0, encoded.size() - 4);
  uint32_t stored_crc;
  std::memcpy(&stored_crc, encoded.data() + body.size(), 4);
  if (Crc32c(body) != stored_crc) return Status::DataLoss("log record checksum mismatch");
  ByteReader r(body);
  uint8_t format, type;
  if (!r.GetU8(&format) || !r.GetU8(&type)) return malformed;
  if (format > kLogRecordFormat) {
    return Status::FailedPrecondition("log record format " + std::to_string(format) +
                                      " is newer than this build reads");
  }
  LogRecord record;
  record.format = format;
  std::string_view robot;
  if (format < 1 || !r.GetVarint(&record.version) || !r.GetLengthPrefixed(&robot) ||
      !r.GetVarint(&record.sequence) || !r.GetSignedVarint(&record.stamp_ns)) {
    return malformed;
  }
  record.robot_id = std::string(robot);
  if (type == static_cast<uint8_t>(LogRecord::Type::kScan)) {
    auto scan = std::make_shared<PreparedScan>();
    if (!GetScan(r, format, scan.get(), &record)) return malformed;
    scan->stamp_ns = record.stamp_ns;  // the map time forgetting replays with
    record.type = LogRecord::Type::kScan;
    record.scan = std::move(scan);
  } else if (type == static_cast<uint8_t>(LogRecord::Type::kClear)) {
    record.type = LogRecord::Type::kClear;
    CellBox& b = record.clear_box;
    for (int* v : {&b.min.x, &b.min.y, &b.max.x, &b.max.y}) {
      int64_t x;
      if (!r.GetSignedVarint(&x) || x < INT32_MIN || x > INT32_MAX) return malformed;
      *v = static_cast<int>(x);
    }
  } else if (type == static_cast<uint8_t>(LogRecord::Type::kCorrection) && format >= 3) {
    record.type = LogRecord::Type::kCorrection;
    std::string_view versions;
    if (!r.GetVarint(&record.base_version) || !GetTileKeys(r, &record.seed_tiles) ||
        !r.GetBytes(r.remaining(), &versions) ||
        !DecodeVersionList(versions, &record.revised_versions)) {
      return malformed;
    }
  } else {
    return malformed;
  }
  if (r.remaining() != 0) return malformed;
  return record;
}

}  // namespace bgkmap::storage
