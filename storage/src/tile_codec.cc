#include "bgkmap/storage/tile_codec.h"

#include <bit>
#include <cstring>
#include <vector>

#include "bgkmap/storage/crc32c.h"
#include "byte_coding.h"

namespace bgkmap::storage {
namespace {

bool PlaneIsZero(const Tile& t, int i) {
  for (int m = 0; t.has_plane() && m < Tile::kPlaneMoments; ++m) {
    if (std::bit_cast<uint64_t>(t.plane(m)[i]) != 0) return false;
  }
  return true;
}

bool CellIsZero(const Tile& t, int i) {
  return std::bit_cast<uint64_t>(t.w()[i]) == 0 && std::bit_cast<uint64_t>(t.s()[i]) == 0 &&
         std::bit_cast<uint64_t>(t.q()[i]) == 0 && std::bit_cast<uint32_t>(t.a()[i]) == 0 &&
         std::bit_cast<uint32_t>(t.b()[i]) == 0 && PlaneIsZero(t, i);
}

// Gathers the present cells of one array as raw bits, optionally XOR-delta coded.
template <typename Bits, typename Value>
std::vector<Bits> Gather(std::span<const Value> values, const std::vector<int>& cells,
                         bool xor_delta) {
  std::vector<Bits> out(cells.size());
  Bits previous = 0;
  for (size_t k = 0; k < cells.size(); ++k) {
    const Bits bits = std::bit_cast<Bits>(values[cells[k]]);
    out[k] = xor_delta ? bits ^ previous : bits;
    previous = bits;
  }
  return out;
}

template <typename Bits, typename Value>
void PutArray(ByteWriter& w, std::span<const Value> values, const std::vector<int>& cells,
              uint8_t flags) {
  const std::vector<Bits> bits = Gather<Bits>(values, cells, (flags & kTileXorDelta) != 0);
  if (flags & kTileShuffled) {
    w.PutShuffled(bits.data(), bits.size(), sizeof(Bits));
  } else {
    w.PutBytes({reinterpret_cast<const char*>(bits.data()), bits.size() * sizeof(Bits)});
  }
}

template <typename Bits, typename Value>
bool GetArray(ByteReader& r, std::span<Value> values, const std::vector<int>& cells,
              uint8_t flags) {
  std::vector<Bits> bits(cells.size());
  if (flags & kTileShuffled) {
    if (!r.GetShuffled(bits.data(), bits.size(), sizeof(Bits))) return false;
  } else {
    std::string_view raw;
    if (!r.GetBytes(bits.size() * sizeof(Bits), &raw)) return false;
    // memcpy with a null pointer is undefined even for 0 bytes (an empty tile: no cells).
    if (!raw.empty()) std::memcpy(bits.data(), raw.data(), raw.size());
  }
  Bits previous = 0;
  for (size_t k = 0; k < cells.size(); ++k) {
    const Bits value = (flags & kTileXorDelta) ? bits[k] ^ previous : bits[k];
    values[cells[k]] = std::bit_cast<Value>(value);
    previous = value;
  }
  return true;
}

// Ground kept aside (Tile::pending): a count, then per cell its index (the gap to the previous
// one), W, S, Q (IEEE bits), A, B (fixed32 bits), the appearance's stamp and how long it was
// seen (zigzag varints).
void PutPending(ByteWriter& w, const Tile& tile) {
  w.PutVarint(tile.pending().size());
  int32_t previous = -1;
  for (const Tile::PendingGround& p : tile.pending()) {
    w.PutVarint(static_cast<uint64_t>(p.local - previous));
    previous = p.local;
    w.PutDouble(p.saved.w);
    w.PutDouble(p.saved.s);
    w.PutDouble(p.saved.q);
    w.PutFixed32(std::bit_cast<uint32_t>(p.saved.a));
    w.PutFixed32(std::bit_cast<uint32_t>(p.saved.b));
    w.PutSignedVarint(p.appeared_ns);
    // Wrapping: an entry that cannot be (seen before it appeared, or out of range) is written as
    // it is and refused by the decoder, never undefined here.
    w.PutSignedVarint(static_cast<int64_t>(static_cast<uint64_t>(p.last_seen_ns) -
                                           static_cast<uint64_t>(p.appeared_ns)));
  }
}

bool GetPending(ByteReader& r, Tile& tile) {
  uint64_t count;
  if (!r.GetVarint(&count) || count > static_cast<uint64_t>(tile.cell_count())) return false;
  std::vector<Tile::PendingGround>& out = tile.pending();
  out.resize(count);
  int64_t previous = -1;
  for (Tile::PendingGround& p : out) {
    uint64_t gap;
    uint32_t a, b;
    int64_t seen_for;
    if (!r.GetVarint(&gap) || gap == 0 || gap > static_cast<uint64_t>(tile.cell_count()) ||
        !r.GetDouble(&p.saved.w) || !r.GetDouble(&p.saved.s) || !r.GetDouble(&p.saved.q) ||
        !r.GetFixed32(&a) || !r.GetFixed32(&b) || !r.GetSignedVarint(&p.appeared_ns) ||
        !r.GetSignedVarint(&seen_for)) {
      return false;
    }
    previous += static_cast<int64_t>(gap);  // strictly increasing: each cell once, sorted
    if (previous >= tile.cell_count()) return false;
    p.local = static_cast<int32_t>(previous);
    p.saved.a = std::bit_cast<float>(a);
    p.saved.b = std::bit_cast<float>(b);
    if (seen_for < 0 || __builtin_add_overflow(p.appeared_ns, seen_for, &p.last_seen_ns)) {
      return false;  // last seen before it appeared, or beyond 64 bits
    }
  }
  return true;
}

Status Malformed(std::string_view what) {
  return Status::DataLoss("tile encoding is malformed: " + std::string(what));
}

}  // namespace

bool IsZeroTile(const Tile& tile) {
  if (!tile.pending().empty()) return false;
  if (tile.is_packed()) {
    Tile dense(tile);
    dense.Unpack();
    return IsZeroTile(dense);
  }
  for (int i = 0; i < tile.cell_count(); ++i) {
    if (!CellIsZero(tile, i)) return false;
  }
  return true;
}

std::string EncodeTile(const Tile& tile, const TileEncodeOptions& options) {
  if (tile.is_packed()) {  // the coding reads the dense arrays (the same bits either way)
    Tile dense(tile);
    dense.Unpack();
    return EncodeTile(dense, options);
  }
  const int cell_count = tile.cell_count();
  std::vector<int> present;
  for (int i = 0; i < cell_count; ++i) {
    if (!CellIsZero(tile, i)) present.push_back(i);
  }
  bool moments = false;  // a map without dynamics keeps Q at zero: not stored
  for (int i : present) moments |= std::bit_cast<uint64_t>(tile.q()[i]) != 0;
  const bool stamped = tile.stamp_ns() != 0;  // a map without forgetting has none: not stored
  const bool plane = tile.has_plane();
  const bool pending = !tile.pending().empty();  // only with transient objects: not stored
  const uint8_t flags = static_cast<uint8_t>(
      (options.shuffle ? kTileShuffled : 0) | (options.xor_delta ? kTileXorDelta : 0) |
      (moments ? kTileMoments : 0) | (stamped ? kTileStamp : 0) | (plane ? kTilePlane : 0) |
      (pending ? kTilePending : 0));
  std::string out;
  out.reserve(16 + cell_count / 8 + present.size() * tile.bytes_per_cell());
  ByteWriter w(&out);
  w.PutU8(pending ? 5 : plane ? 4 : stamped ? 3 : 2);
  w.PutU8(flags);
  w.PutVarint(static_cast<uint64_t>(tile.tile_size()));
  w.PutVarint(tile.version());
  if (stamped) w.PutSignedVarint(tile.stamp_ns());
  w.PutVarint(present.size());
  if (!present.empty() && static_cast<int>(present.size()) < cell_count) {
    std::string bitmap((cell_count + 7) / 8, '\0');
    for (int i : present) bitmap[i / 8] = static_cast<char>(bitmap[i / 8] | (1 << (i % 8)));
    w.PutBytes(bitmap);
  }
  PutArray<uint64_t>(w, tile.w(), present, flags);
  PutArray<uint64_t>(w, tile.s(), present, flags);
  if (moments) PutArray<uint64_t>(w, tile.q(), present, flags);
  PutArray<uint32_t>(w, tile.a(), present, flags);
  PutArray<uint32_t>(w, tile.b(), present, flags);
  if (plane) {
    for (int m = 0; m < Tile::kPlaneMoments; ++m)
      PutArray<uint64_t>(w, tile.plane(m), present, flags);
  }
  if (pending) PutPending(w, tile);
  w.PutFixed32(Crc32c(out));
  return out;
}

Result<std::unique_ptr<Tile>> DecodeTile(std::string_view encoded, int tile_size,
                                         bool plane_moments) {
  if (encoded.size() < 4) return Malformed("shorter than its checksum");
  const std::string_view body = encoded.substr(0, encoded.size() - 4);
  uint32_t stored_crc;
  std::memcpy(&stored_crc, encoded.data() + body.size(), 4);
  if (Crc32c(body) != stored_crc) {
    return Status::DataLoss("tile checksum mismatch (" + std::to_string(encoded.size()) +
                            " bytes)");
  }
  ByteReader r(body);
  uint8_t format, flags;
  uint64_t size, version, n;
  if (!r.GetU8(&format) || !r.GetU8(&flags)) return Malformed("truncated header");
  if (format > kTileFormat) {
    return Status::FailedPrecondition("tile format " + std::to_string(format) +
                                      " is newer than this build reads (" +
                                      std::to_string(kTileFormat) + ")");
  }
  // Format 1 is format 2 without moments (written before dynamics), format 2 format 3 without
  // a stamp (written before forgetting): both still read.
  const uint8_t known_flags = kTileShuffled | kTileXorDelta | (format >= 2 ? kTileMoments : 0) |
                              (format >= 3 ? kTileStamp : 0) | (format >= 4 ? kTilePlane : 0) |
                              (format >= 5 ? kTilePending : 0);
  if (format < 1 || (flags & ~known_flags) != 0) {
    return Malformed("unknown format or flags");
  }
  int64_t stamp = 0;
  if (!r.GetVarint(&size) || !r.GetVarint(&version) ||
      ((flags & kTileStamp) && !r.GetSignedVarint(&stamp)) || !r.GetVarint(&n)) {
    return Malformed("truncated header");
  }
  if (size != static_cast<uint64_t>(tile_size)) {
    return Status::DataLoss("tile is " + std::to_string(size) + " cells wide, the map's are " +
                            std::to_string(tile_size));
  }
  const bool plane = (flags & kTilePlane) != 0;
  if (plane != plane_moments) {
    return Status::DataLoss(plane ? "tile keeps plane moments, the map's method does not"
                                  : "tile lacks the plane moments the map's method keeps");
  }
  auto tile = std::make_unique<Tile>(tile_size, plane);
  tile->set_version(version);
  tile->set_stamp_ns(stamp);
  const int cell_count = tile->cell_count();
  if (n > static_cast<uint64_t>(cell_count)) return Malformed("more present cells than cells");
  std::vector<int> present;
  present.reserve(n);
  if (n == static_cast<uint64_t>(cell_count)) {
    for (int i = 0; i < cell_count; ++i) present.push_back(i);
  } else if (n > 0) {
    std::string_view bitmap;
    if (!r.GetBytes((cell_count + 7) / 8, &bitmap)) return Malformed("truncated bitmap");
    for (int i = 0; i < cell_count; ++i) {
      if (bitmap[i / 8] & (1 << (i % 8))) present.push_back(i);
    }
    if (present.size() != n) return Malformed("bitmap disagrees with the cell count");
  }
  if (!GetArray<uint64_t>(r, tile->w(), present, flags) ||
      !GetArray<uint64_t>(r, tile->s(), present, flags) ||
      ((flags & kTileMoments) && !GetArray<uint64_t>(r, tile->q(), present, flags)) ||
      !GetArray<uint32_t>(r, tile->a(), present, flags) ||
      !GetArray<uint32_t>(r, tile->b(), present, flags)) {
    return Malformed("truncated cell values");
  }
  for (int m = 0; plane && m < Tile::kPlaneMoments; ++m) {
    if (!GetArray<uint64_t>(r, tile->plane(m), present, flags)) {
      return Malformed("truncated plane moments");
    }
  }
  if ((flags & kTilePending) && !GetPending(r, *tile)) {
    return Malformed("bad or truncated ground kept aside");
  }
  if (r.remaining() != 0) return Malformed("trailing bytes");
  return tile;
}

}  // namespace bgkmap::storage
