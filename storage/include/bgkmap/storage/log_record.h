// One entry of the scan log: a change applied to the map, recorded with everything needed to
// apply it again bit for bit (the prepared scan's training set, not its raw points).
//
// Layout (format 5), little-endian:
//   u8 format, u8 type, varint version, length-prefixed robot_id, varint sequence,
//   zigzag stamp_ns, then
//   scan:  varint counts (input, kept, nonfinite, range, height, out_of_bounds), f64 sensor_z,
//          u8 has_sensor, f64 sensor_x, f64 sensor_y (format >= 2; format 1 had no sensor),
//          write_tiles, read_tiles and (format >= 2) clear_tiles (varint count, zigzag deltas
//          of x and y),
//          (format >= 4) u8 cells_in_source, then if 1 a fixed32 CRC-32C of the cells' encoding
//          (LoggedCellsCrc), else (and always before format 4) the cells (varint count, zigzag
//          deltas of x and y), their y as f64 bits (XOR-delta), (format >= 5) their span_mm as
//          varints; a cell logged or prepared for a record before format 5 replays with span
//          0, as it was first integrated
//   clear: zigzag min.x, min.y, max.x, max.y
//   correction (format >= 3): varint base_version, seed_tiles (as write_tiles), varint count and
//          varint deltas of revised_versions (ascending)
//   fixed32 crc32c of every byte before it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/raw_scan.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"

namespace bgkmap::storage {

inline constexpr uint8_t kLogRecordFormat = 5;
// The first format whose cells carry their spans (ObservedCell::span_mm).
inline constexpr uint8_t kLogFormatWithSpans = 5;

struct LogRecord {
  // kCorrection: some earlier scan records were rewritten (a pose correction) or removed; the
  // map's tiles are rebuilt from a retained checkpoint (scan_history.h). robot_id names the robot.
  enum class Type : uint8_t { kScan = 1, kClear = 2, kCorrection = 3 };

  Type type = Type::kScan;
  uint8_t format = kLogRecordFormat;  // as decoded: what the record was written by
  uint64_t version = 0;               // map version the change was applied as; replay follows it
  std::string robot_id;               // kScan: the sending robot
  uint64_t sequence = 0;              // kScan: the robot's sequence number
  // kScan: the sender's stamp, the scan's map time: decoding sets scan->stamp_ns to it, so a
  // replay forgets as the first run did (docs/semantics.md "Forgetting").
  int64_t stamp_ns = 0;
  std::shared_ptr<const PreparedScan> scan;  // kScan: required
  CellBox clear_box;                         // kClear: the cleared cells
  // kScan, optional and not part of the encoding: the raw scan, which the log keeps beside the
  // record (in its own family) while corrections may need it.
  std::shared_ptr<const RawScan> raw_scan;
  // kScan: the observed cells are not in the record, only their CRC (cells_crc): they are
  // prepared again from the raw scan kept beside it (ScanLog::LoadCells), so a retained scan's
  // points are stored once (docs/storage.md). A decoded record of this kind has a scan with
  // every field but `cells`.
  bool cells_in_source = false;
  uint32_t cells_crc = 0;  // cells_in_source: LoggedCellsCrc of the prepared scan
  // kCorrection: the retained checkpoint the rebuild starts from, the tiles the revised scans
  // changed before they were revised, and the revised scans' versions (removed ones included).
  uint64_t base_version = 0;
  std::vector<TileKey> seed_tiles;
  std::vector<uint64_t> revised_versions;

  static LogRecord Scan(uint64_t version, std::string robot_id, uint64_t sequence,
                        std::shared_ptr<const PreparedScan> scan, int64_t stamp_ns = 0);
  static LogRecord Clear(uint64_t version, const CellBox& box);
  static LogRecord Correction(uint64_t version, std::string robot_id, uint64_t base_version,
                              std::vector<TileKey> seed_tiles,
                              std::vector<uint64_t> revised_versions);
};

std::string EncodeLogRecord(const LogRecord& record);

// CRC-32C of the encoding of `scan`'s observed cells in record format `format`: what a record
// with cells_in_source keeps to check that preparing the raw scan again gives the cells first
// logged.
uint32_t LoggedCellsCrc(const PreparedScan& scan, uint8_t format = kLogRecordFormat);

// DataLoss if the checksum fails or the bytes are malformed; FailedPrecondition for a newer
// format.
Result<LogRecord> DecodeLogRecord(std::string_view encoded);

}  // namespace bgkmap::storage
