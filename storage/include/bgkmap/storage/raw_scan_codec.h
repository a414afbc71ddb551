// The encoding of a retained raw scan (core/raw_scan.h): the points and pose behind a logged
// scan record. The log record holds only the prepared training set, which depends on the pose;
// a pose correction prepares the scan again from this (reintegration.h). The scan log keeps it
// in its own column family ("sources") while corrections may need it.
//
// Layout, little-endian: u8 format, 12 f64 (rotation row-major, translation), u8 frame_is_map,
// then the points, then fixed32 crc32c of every byte before it. The points:
//   format 1: varint point count, the points' f32 bits byte-shuffled (PutShuffled);
//   format 2 (a scan that came compact, RawScan::quantum > 0, whose points the compact encoding
//     gives back exactly, in order): f64 step, varint count, u8 order, varint length and the
//     zstd frame of proto/codec's compact_points.h, about a sixth of format 1's bytes. Decoding
//     gives the same points, in the same order, and the quantum.
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
