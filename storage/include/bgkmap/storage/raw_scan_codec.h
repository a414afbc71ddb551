// The encoding of a retained raw scan (core/raw_scan.h): the points and pose behind a logged
// scan record. The log record holds only the prepared training set, which depends on the pose;
// a pose correction prepares the scan again from this (reintegration.h). The scan log keeps it
// in its own column family ("sources") while corrections may need it.
//
// Layout (format 1), little-endian: u8 format, 12 f64 (rotation row-major, translation),
// u8 frame_is_map, varint point count, the points' f32 bits byte-shuffled (PutShuffled),
// fixed32 crc32c of every byte before it.
#pragma once

#include <string>
#include <string_view>

#include "bgkmap/core/raw_scan.h"
#include "bgkmap/core/status.h"

namespace bgkmap::storage {

std::string EncodeRawScan(const RawScan& scan);
// DataLoss if the checksum fails or the bytes are malformed.
Result<RawScan> DecodeRawScan(std::string_view encoded);

}  // namespace bgkmap::storage
