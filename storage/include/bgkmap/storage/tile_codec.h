// The on-disk encoding of one tile's statistics: exact (bitwise) and compact.
//
// Layout (format 5; format 4 is format 5 without kTilePending, format 3 format 4 without
// kTilePlane, format 2 format 3 without kTileStamp, format 1 format 2 without kTileMoments; all
// still read), little-endian:
//   u8      format            5 with kTilePending, else 4 with kTilePlane, else 3 with
//                             kTileStamp, else 2 (the oldest that holds the tile, so maps
//                             without the newer rules encode byte for byte as before)
//   u8      layout flags      kTileShuffled | kTileXorDelta | kTileMoments | kTileStamp |
//                             kTilePlane | kTilePending
//   varint  tile_size         cells per edge
//   varint  version           map version of the tile's last change
//   zigzag  stamp             with kTileStamp: the map time (ns) the statistics are as of
//                             (forgetting, docs/semantics.md); absent: 0
//   varint  n                 cells with any non-zero bit in W, S, Q, A or B ("present" cells)
//   bytes   presence bitmap   ceil(tile_size^2 / 8) bytes, row-major, bit i%8 of byte i/8;
//                             omitted when n == 0 or n == tile_size^2
//   W[n] S[n] (8 bytes each), Q[n] (8 bytes, with kTileMoments: a map with dynamics),
//   A[n] B[n] (4 bytes each), then with kTilePlane (bgk-ll) the seven plane moments
//   (Tile::Plane order, 8 bytes each, n of each), present cells only, in cell order,
//                             each array optionally XOR-delta coded and byte-shuffled
//   with kTilePending: varint count, then per entry of Tile::pending() (sorted by cell):
//     varint cell - previous cell (the first: cell + 1), W S Q (8 bytes each), A B (4 bytes
//     each), zigzag appeared_ns, zigzag last_seen_ns - appeared_ns
//   fixed32 crc32c            of every byte before it
// Cells that are bitwise +0 in all five arrays are skipped: a missing cell decodes to +0. Every
// other bit pattern (-0, NaN payloads, denormals) round-trips unchanged.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"

namespace bgkmap::storage {

inline constexpr uint8_t kTileFormat = 5;    // the newest format this build reads and writes
inline constexpr uint8_t kTileShuffled = 1;  // arrays stored as byte planes
inline constexpr uint8_t kTileXorDelta = 2;  // each value XOR the previous present value
inline constexpr uint8_t kTileMoments = 4;   // the Q array is stored (format >= 2)
inline constexpr uint8_t kTileStamp = 8;     // the tile's stamp is stored (format >= 3)
inline constexpr uint8_t kTilePlane = 16;    // the plane moments are stored (format >= 4)
inline constexpr uint8_t kTilePending = 32;  // ground kept aside is stored (format >= 5)

// Both transforms are off by default: measured on the real street map with zstd, the plain
// arrays compress best (18.6 bytes per known cell; shuffled 19.9, XOR-delta 20.2; see
// docs/storage.md). The statistics' mantissas are close to random, so the transforms mostly
// disturb the byte patterns zstd finds on its own. Decoding handles every combination.
struct TileEncodeOptions {
  // Byte planes: all first bytes, then all second bytes...
  bool shuffle = false;
  // Each value XOR the previous present one, zeroing the high bits neighbours share.
  bool xor_delta = false;
};

// Encodes `tile` (statistics, version and stamp). Never fails.
std::string EncodeTile(const Tile& tile, const TileEncodeOptions& options = {});

// Decodes an encoding made by EncodeTile. Returns DataLoss if the checksum fails, the bytes are
// malformed or truncated, or the tile is not `tile_size` cells wide (a tile from another map);
// FailedPrecondition for a format newer than this build reads.
// `plane_moments`: whether the map's tiles keep plane moments (KeepsPlaneMoments of its method);
// a tile that disagrees is DataLoss, not a tile the map could not use.
Result<std::unique_ptr<Tile>> DecodeTile(std::string_view encoded, int tile_size,
                                         bool plane_moments = false);

// True if every cell of `tile` is bitwise +0: such a tile is stored as no tile at all.
bool IsZeroTile(const Tile& tile);

}  // namespace bgkmap::storage
