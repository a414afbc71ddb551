// The raw scan behind a logged scan record: its points in the sensor frame and the pose it was
// integrated with. The log record holds only the prepared training set, which depends on the
// pose; a pose correction prepares the scan again from this (scan_history.h).
//
// Layout (format 1), little-endian: u8 format, 12 f64 (rotation row-major, translation),
// u8 frame_is_map, varint point count, the points' f32 bits byte-shuffled (PutShuffled),
// fixed32 crc32c of every byte before it.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"

namespace bgkmap::storage {

struct ScanSource {
  Pose pose;                  // T_map_sensor the scan was sent with
  bool frame_is_map = false;  // PrepareScan's flag
  std::vector<Point3f> points;
};

std::string EncodeScanSource(const ScanSource& source);
// DataLoss if the checksum fails or the bytes are malformed.
Result<ScanSource> DecodeScanSource(std::string_view encoded);

}  // namespace bgkmap::storage
