#include "bgkmap/storage/tile_codec.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "bgkmap/storage/crc32c.h"

namespace bgkmap::storage {
namespace {

// Bitwise equality including the version (Tile::operator== compares statistics and stamp).
void ExpectIdentical(const Tile& a, const Tile& b) {
  ASSERT_EQ(a.tile_size(), b.tile_size());
  EXPECT_TRUE(a == b);
  EXPECT_EQ(a.version(), b.version());
}

std::unique_ptr<Tile> RoundTrip(const Tile& tile, const TileEncodeOptions& options = {}) {
  Result<std::unique_ptr<Tile>> decoded = DecodeTile(EncodeTile(tile, options), tile.tile_size());
  EXPECT_TRUE(decoded.ok()) << decoded.status().ToString();
  return decoded.ok() ? std::move(decoded).value() : nullptr;
}

// A tile with `fill` of its cells set to smooth, full-precision statistics.
Tile RandomTile(int size, double fill, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Tile t(size);
  t.set_version(rng());
  for (int i = 0; i < t.cell_count(); ++i) {
    if (u(rng) >= fill) continue;
    t.w()[i] = 3.0 * u(rng);
    t.s()[i] = t.w()[i] * (120.0 + u(rng));
    t.a()[i] = static_cast<float>(u(rng));
    t.b()[i] = static_cast<float>(u(rng));
  }
  return t;
}

TEST(TileCodecTest, EmptyTileRoundTripsAndIsSmall) {
  Tile t(64);
  t.set_version(7);
  const std::string bytes = EncodeTile(t);
  EXPECT_LT(bytes.size(), 16u);
  EXPECT_TRUE(IsZeroTile(t));
  ExpectIdentical(t, *RoundTrip(t));
}

// Found by tile_codec_fuzzer (UBSan: memcpy from a null pointer for the 0 bytes of a tile
// without present cells). Fails only under the sanitizers (scripts/sanitize.sh asan).
TEST(TileCodecTest, TileWithoutCellsDecodesInEveryLayout) {
  Tile t(8);
  t.set_version(41);
  for (bool shuffle : {false, true}) {
    for (bool xor_delta : {false, true}) {
      ExpectIdentical(t, *RoundTrip(t, {.shuffle = shuffle, .xor_delta = xor_delta}));
    }
  }
}

TEST(TileCodecTest, FullTileRoundTripsBitwise) {
  const Tile t = RandomTile(32, 1.0, 1);
  EXPECT_EQ(t.CountKnown(), t.cell_count());
  ExpectIdentical(t, *RoundTrip(t));
}

TEST(TileCodecTest, RandomTilesRoundTripBitwiseInEveryLayout) {
  for (unsigned seed = 0; seed < 20; ++seed) {
    const Tile t = RandomTile(seed % 2 ? 64 : 17, 0.05 * seed, seed);
    for (bool shuffle : {false, true}) {
      for (bool xor_delta : {false, true}) {
        ExpectIdentical(t, *RoundTrip(t, {shuffle, xor_delta}));
      }
    }
  }
}

TEST(TileCodecTest, UnusualBitPatternsSurvive) {
  Tile t(8);
  t.w()[0] = -0.0;  // not +0: must be kept
  t.s()[1] = std::numeric_limits<double>::quiet_NaN();
  t.a()[2] = std::numeric_limits<float>::denorm_min();
  t.b()[3] = -std::numeric_limits<float>::infinity();
  t.w()[63] = std::numeric_limits<double>::max();
  const auto back = RoundTrip(t);
  ExpectIdentical(t, *back);
  EXPECT_EQ(std::bit_cast<uint64_t>(back->w()[0]), std::bit_cast<uint64_t>(-0.0));
  EXPECT_FALSE(IsZeroTile(t));
}

TEST(TileCodecTest, SparseTileStoresOnlyPresentCells) {
  Tile t(64);
  t.w()[100] = 1.5;
  t.s()[100] = 2.5;
  // header + bitmap (512) + one cell (24) + crc
  EXPECT_LE(EncodeTile(t).size(), 8u + 512u + 24u + 4u);
}

TEST(TileCodecTest, EveryFlippedByteIsDetected) {
  const Tile t = RandomTile(16, 0.5, 3);
  const std::string good = EncodeTile(t);
  for (size_t i = 0; i < good.size(); ++i) {
    std::string bad = good;
    bad[i] = static_cast<char>(bad[i] ^ 0x10);
    const auto decoded = DecodeTile(bad, 16);
    ASSERT_FALSE(decoded.ok()) << "flip at byte " << i;
    EXPECT_EQ(decoded.status().code(), Status::Code::kDataLoss);
  }
}

TEST(TileCodecTest, TruncationAndWrongTileSizeAreDataLoss) {
  const Tile t = RandomTile(16, 0.5, 4);
  const std::string good = EncodeTile(t);
  for (size_t n : {size_t{0}, size_t{3}, good.size() / 2, good.size() - 1}) {
    EXPECT_EQ(DecodeTile(good.substr(0, n), 16).status().code(), Status::Code::kDataLoss);
  }
  const auto wrong = DecodeTile(good, 32);
  EXPECT_EQ(wrong.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(wrong.status().message().find("16 cells wide"), std::string::npos);
}

// Forgetting's stamp (format 3): stored only when non-zero, so a map without forgetting encodes
// byte for byte as format 2 did.
// Mutation checked: not writing the stamp (dropping `if (stamped) PutSignedVarint`) fails the
// round trips; writing kTileFormat for every tile fails the format-2 bytes.
TEST(TileCodecTest, StampedTilesRoundTripAsFormat3) {
  for (int64_t stamp : {int64_t{1'764'000'000'123'456'789}, int64_t{-5}, int64_t{1}}) {
    Tile t = RandomTile(16, 0.5, 7);
    t.set_stamp_ns(stamp);
    for (bool shuffle : {false, true}) {
      const std::string bytes = EncodeTile(t, {.shuffle = shuffle});
      EXPECT_EQ(bytes[0], 3);
      EXPECT_NE(bytes[1] & kTileStamp, 0);
      const std::unique_ptr<Tile> back = RoundTrip(t, {.shuffle = shuffle});
      ExpectIdentical(t, *back);
      EXPECT_EQ(back->stamp_ns(), stamp);
    }
  }
}

std::string WithCrc(std::string body) {
  const uint32_t crc = Crc32c(body);
  body.append(reinterpret_cast<const char*>(&crc), 4);
  return body;
}

// A format-2 tile written before forgetting, built by hand: it decodes (stamp 0), and an
// unstamped tile still encodes to exactly these bytes.
TEST(TileCodecTest, Format2TilesDecodeAndUnstampedTilesEncodeAsFormat2) {
  std::string body;
  body += '\x02';                           // format 2
  body += static_cast<char>(kTileMoments);  // flags
  body += '\x04';                           // tile_size 4
  body += '\x09';                           // version 9
  body += '\x01';                           // one present cell
  body += std::string("\x20\x00", 2);       // bitmap: cell 5
  const double w = 2.5, s = 1.25, q = 0.75;
  const float a = 0.5f, b = 1.5f;
  for (double v : {w, s, q}) body.append(reinterpret_cast<const char*>(&v), 8);
  for (float v : {a, b}) body.append(reinterpret_cast<const char*>(&v), 4);
  const std::string format2 = WithCrc(body);
  Result<std::unique_ptr<Tile>> decoded = DecodeTile(format2, 4);
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  const Tile& t = **decoded;
  EXPECT_EQ(t.version(), 9u);
  EXPECT_EQ(t.stamp_ns(), 0);
  EXPECT_EQ(t.w()[5], w);
  EXPECT_EQ(t.s()[5], s);
  EXPECT_EQ(t.q()[5], q);
  EXPECT_EQ(t.a()[5], a);
  EXPECT_EQ(t.b()[5], b);
  EXPECT_EQ(t.CountKnown(), 1);
  EXPECT_EQ(EncodeTile(t), format2);
}

TEST(TileCodecTest, NewerFormatsAreRefusedNamingBothAndStampsNeedFormat3) {
  Tile t = RandomTile(8, 0.5, 9);
  t.set_stamp_ns(77);
  std::string bytes = EncodeTile(t);
  std::string body = bytes.substr(0, bytes.size() - 4);
  body[0] = 6;
  const auto newer = DecodeTile(WithCrc(body), 8);
  EXPECT_EQ(newer.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_EQ(newer.status().message(), "tile format 6 is newer than this build reads (5)");
  body[0] = 2;  // a stamp in a format that has none
  EXPECT_EQ(DecodeTile(WithCrc(body), 8).status().code(), Status::Code::kDataLoss);
}

// bgk-ll tiles: the plane moments round-trip bitwise in every layout, in format 4; a map of the
// other methods is refused such a tile (and the reverse) as DataLoss; plane moments need
// format 4. Mutations: not writing the plane arrays (round trip differs); accepting a plane
// tile in a map without planes.
TEST(TileCodecTest, PlaneMomentsRoundTripInFormat4AndMustMatchTheMap) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const Tile base = RandomTile(8, 0.5, 11);
  Tile t(8, /*plane_moments=*/true);
  t.Add(base);
  t.set_version(base.version());
  for (int i = 0; i < t.cell_count(); ++i) {
    if (!(t.w()[i] > 0.0)) continue;
    for (int m = 0; m < Tile::kPlaneMoments; ++m) t.plane(m)[i] = u(rng) * 100.0;
  }
  for (bool shuffle : {false, true}) {
    for (bool xor_delta : {false, true}) {
      const std::string bytes = EncodeTile(t, {shuffle, xor_delta});
      EXPECT_EQ(bytes[0], 4);
      Result<std::unique_ptr<Tile>> back = DecodeTile(bytes, 8, /*plane_moments=*/true);
      ASSERT_TRUE(back.ok()) << back.status().ToString();
      ASSERT_TRUE((*back)->has_plane());
      ExpectIdentical(t, **back);
    }
  }
  const std::string bytes = EncodeTile(t);
  EXPECT_EQ(DecodeTile(bytes, 8).status().code(), Status::Code::kDataLoss);
  EXPECT_EQ(DecodeTile(EncodeTile(base), 8, true).status().code(), Status::Code::kDataLoss);
  std::string body = bytes.substr(0, bytes.size() - 4);
  body[0] = 3;  // plane moments in a format that has none
  EXPECT_EQ(DecodeTile(WithCrc(body), 8, true).status().code(), Status::Code::kDataLoss);
}

// Ground kept aside by transient objects (format 5): round-trips bitwise in every layout with
// the tile; a tile without any encodes as before (format 3 here); malformed entries (a cell
// twice, beyond the tile, truncated) are DataLoss, and format 4 cannot hold them.
// Mutations: not writing the entries (round trip differs); accepting a repeated cell.
TEST(TileCodecTest, KeptGroundRoundTripsInFormat5) {
  Tile t = RandomTile(8, 0.5, 13);
  t.set_stamp_ns(5'000'000'000);
  const std::string without = EncodeTile(t);
  EXPECT_EQ(without[0], 3);
  t.pending().push_back({3, {1.5, -0.25, 0.125, 0.5f, -0.0f}, 4'000'000'000, 4'300'000'000});
  t.pending().push_back({63, {2.0, 240.0, 28800.0, 1e-20f, 3.0f}, -7, -7});
  for (bool shuffle : {false, true}) {
    for (bool xor_delta : {false, true}) {
      const std::string bytes = EncodeTile(t, {shuffle, xor_delta});
      EXPECT_EQ(bytes[0], 5);
      std::unique_ptr<Tile> back = RoundTrip(t, {shuffle, xor_delta});
      ASSERT_NE(back, nullptr);
      ExpectIdentical(t, *back);
      EXPECT_EQ(back->pending(), t.pending());
    }
  }
  const std::string bytes = EncodeTile(t);
  for (size_t n : {bytes.size() - 5, bytes.size() - 20}) {
    EXPECT_EQ(DecodeTile(bytes.substr(0, n), 8).status().code(), Status::Code::kDataLoss);
  }
  std::string body = bytes.substr(0, bytes.size() - 4);
  body[0] = 4;  // kept ground in a format that has none
  EXPECT_EQ(DecodeTile(WithCrc(body), 8).status().code(), Status::Code::kDataLoss);
  Tile repeated = t;
  repeated.pending()[1].local = 3;  // the second entry's gap is 0: the same cell twice
  EXPECT_EQ(DecodeTile(EncodeTile(repeated), 8).status().code(), Status::Code::kDataLoss);
  Tile beyond = t;
  beyond.pending()[1].local = 64;  // past the tile's 64 cells
  EXPECT_EQ(DecodeTile(EncodeTile(beyond), 8).status().code(), Status::Code::kDataLoss);
  EXPECT_TRUE(IsZeroTile(Tile(8)));
  // An entry last seen before it appeared, or whose last sighting does not fit in 64 bits (the
  // tile_codec fuzzer's finding: the decoder overflowed adding them), is malformed.
  Tile backwards = t;
  backwards.pending()[0].last_seen_ns = backwards.pending()[0].appeared_ns - 5;
  EXPECT_EQ(DecodeTile(EncodeTile(backwards), 8).status().code(), Status::Code::kDataLoss);
  Tile overflowing = t;
  overflowing.pending()[0].appeared_ns = std::numeric_limits<int64_t>::max() - 1;
  overflowing.pending()[0].last_seen_ns = std::numeric_limits<int64_t>::min();
  EXPECT_EQ(DecodeTile(EncodeTile(overflowing), 8).status().code(), Status::Code::kDataLoss);
  Tile only_pending(8);
  only_pending.pending().push_back({0, {1.0, 0.0, 0.0, 0.0f, 1.0f}, 1, 1});
  EXPECT_FALSE(IsZeroTile(only_pending));
}

}  // namespace
}  // namespace bgkmap::storage
