#include "bgkmap/storage/tile_codec.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>
#include <random>

namespace bgkmap::storage {
namespace {

// Bitwise equality including the version (Tile::operator== compares statistics only).
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

}  // namespace
}  // namespace bgkmap::storage
