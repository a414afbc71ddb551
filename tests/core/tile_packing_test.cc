// Tile::Pack() / Unpack() (tile.h): the packed form keeps every statistic bit for bit (-0.0,
// denormals, plane moments), answers the same per-cell reads and Known() as the dense form,
// compares equal to it, and holds fewer bytes when the tile is mostly empty.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>

#include "bgkmap/core/tile.h"

namespace bgkmap {
namespace {

// A tile with `fill` of its cells (about) holding random statistics, some of them -0.0, a
// denormal or a lone nonzero bit in one statistic only.
Tile RandomTile(std::mt19937& rng, int size, bool plane, double fill) {
  Tile t(size, plane);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  std::bernoulli_distribution take(fill);
  for (int i = 0; i < t.cell_count(); ++i) {
    if (!take(rng)) continue;
    switch (rng() % 5) {
      case 0:  // only a -0.0 somewhere: stored, yet not known
        (rng() % 2 ? t.s()[i] : t.q()[i]) = -0.0;
        break;
      case 1:
        t.a()[i] = std::numeric_limits<float>::denorm_min();
        break;
      default:
        t.w()[i] = std::abs(u(rng));
        t.s()[i] = u(rng);
        t.q()[i] = u(rng) * u(rng);
        t.a()[i] = static_cast<float>(std::abs(u(rng)));
        t.b()[i] = static_cast<float>(std::abs(u(rng)));
        break;
    }
    for (int m = 0; plane && m < Tile::kPlaneMoments; ++m) {
      if (rng() % 3 != 0) t.plane(m)[i] = m == 0 ? -0.0 : u(rng);
    }
  }
  t.set_version(rng());
  t.set_stamp_ns(static_cast<int64_t>(rng()));
  return t;
}

template <typename T>
bool SameBits(std::span<const T> a, std::span<const T> b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (std::bit_cast<std::conditional_t<sizeof(T) == 8, uint64_t, uint32_t>>(a[i]) !=
        std::bit_cast<std::conditional_t<sizeof(T) == 8, uint64_t, uint32_t>>(b[i])) {
      return false;
    }
  }
  return true;
}

void ExpectBitwiseEqualDense(const Tile& a, const Tile& b) {
  ASSERT_FALSE(a.is_packed());
  ASSERT_FALSE(b.is_packed());
  EXPECT_TRUE(SameBits(a.w(), b.w()));
  EXPECT_TRUE(SameBits(a.s(), b.s()));
  EXPECT_TRUE(SameBits(a.q(), b.q()));
  EXPECT_TRUE(SameBits(a.a(), b.a()));
  EXPECT_TRUE(SameBits(a.b(), b.b()));
  for (int m = 0; a.has_plane() && m < Tile::kPlaneMoments; ++m) {
    EXPECT_TRUE(SameBits(a.plane(m), b.plane(m))) << "plane moment " << m;
  }
  EXPECT_EQ(a.version(), b.version());
  EXPECT_EQ(a.stamp_ns(), b.stamp_ns());
}

TEST(TilePackingTest, RoundTripIsBitwiseAndReadsMatch) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 60; ++trial) {
    const bool plane = trial % 2 == 1;
    const int size = trial % 5 == 0 ? 7 : 64;  // 7: a cell count that is no multiple of 64
    const double fill = trial % 4 == 0 ? 0.0 : trial % 4 == 1 ? 1.0 : 0.05 * (trial % 7);
    const Tile dense = RandomTile(rng, size, plane, fill);
    Tile packed(dense);
    packed.Pack();
    ASSERT_TRUE(packed.is_packed());
    EXPECT_TRUE(packed == dense);
    EXPECT_TRUE(dense == packed);
    const Tile::KnownCells kd = dense.Known(), kp = packed.Known();
    EXPECT_EQ(kd.count, kp.count);
    EXPECT_EQ(kd.local_box.min.x, kp.local_box.min.x);
    EXPECT_EQ(kd.local_box.max.y, kp.local_box.max.y);
    EXPECT_EQ(kd.local_box.empty(), kp.local_box.empty());
    for (int i = 0; i < dense.cell_count(); ++i) {
      const Tile::CellStats c = packed.CellAt(i);
      ASSERT_EQ(std::bit_cast<uint64_t>(c.w), std::bit_cast<uint64_t>(dense.w()[i]));
      ASSERT_EQ(std::bit_cast<uint64_t>(c.s), std::bit_cast<uint64_t>(dense.s()[i]));
      ASSERT_EQ(std::bit_cast<uint64_t>(c.q), std::bit_cast<uint64_t>(dense.q()[i]));
      ASSERT_EQ(std::bit_cast<uint32_t>(c.a), std::bit_cast<uint32_t>(dense.a()[i]));
      ASSERT_EQ(std::bit_cast<uint32_t>(c.b), std::bit_cast<uint32_t>(dense.b()[i]));
      ASSERT_EQ(packed.IsKnown(i), dense.IsKnown(i));
      if (plane) {
        double pp[Tile::kPlaneMoments], pd[Tile::kPlaneMoments];
        packed.PlaneOf(i, pp);
        dense.PlaneOf(i, pd);
        for (int m = 0; m < Tile::kPlaneMoments; ++m) {
          ASSERT_EQ(std::bit_cast<uint64_t>(pp[m]), std::bit_cast<uint64_t>(pd[m]));
        }
      }
    }
    // A copy keeps the form; two packed tiles compare packed.
    const Tile copy(packed);
    EXPECT_TRUE(copy.is_packed());
    EXPECT_TRUE(copy == packed);
    if (fill < 1.0) {
      EXPECT_LT(packed.MemoryBytes(), dense.MemoryBytes()) << "fill " << fill;
    }
    Tile back(packed);
    back.Unpack();
    ExpectBitwiseEqualDense(back, dense);
  }
}

// What a checkpoint holds: PackedCopy() of a dense tile equals the tile packed in place, bit for
// bit, and leaves the source dense; of a packed tile, a copy.
TEST(TilePackingTest, PackedCopyEqualsPackingInPlace) {
  std::mt19937 rng(29);
  for (int trial = 0; trial < 24; ++trial) {
    const bool plane = trial % 2 == 1;
    const int size = trial % 3 == 0 ? 7 : 64;
    const Tile dense = RandomTile(rng, size, plane, 0.1 * (trial % 6));
    const std::unique_ptr<Tile> copy = Tile::PackedCopy(dense);
    ASSERT_TRUE(copy->is_packed());
    EXPECT_FALSE(dense.is_packed());
    Tile in_place(dense);
    in_place.Pack();
    EXPECT_EQ(copy->MemoryBytes(), in_place.MemoryBytes());
    EXPECT_TRUE(*copy == in_place);
    Tile back(*copy);
    back.Unpack();
    ExpectBitwiseEqualDense(back, dense);
    const std::unique_ptr<Tile> again = Tile::PackedCopy(*copy);
    EXPECT_TRUE(again->is_packed());
    EXPECT_TRUE(*again == dense);
  }
}

TEST(TilePackingTest, AMinusZeroIsADifference) {
  Tile a(8), b(8);
  b.s()[5] = -0.0;  // equal as numbers, not as bits
  a.Pack();
  b.Pack();
  EXPECT_FALSE(a == b);
  Tile c(8);
  EXPECT_TRUE(a == c);
  EXPECT_FALSE(c == b);
}

TEST(TilePackingTest, BytesFollowTheStoredCells) {
  Tile t(64, /*plane_moments=*/true);
  const size_t dense = t.MemoryBytes();
  EXPECT_GE(dense, 64u * 64u * t.bytes_per_cell());
  for (int i = 0; i < 100; ++i) t.w()[i * 40] = 1.0;
  t.Pack();
  // 100 cells of statistics plus the mask and its ranks (12 bytes per 64 cells).
  EXPECT_EQ(t.MemoryBytes(), sizeof(Tile) + 64 * 12 + 100 * t.bytes_per_cell());
  EXPECT_EQ(t.CountKnown(), 100);
}

TEST(TilePackingTest, AddAndClearOnPackedTiles) {
  std::mt19937 rng(3);
  const Tile x = RandomTile(rng, 16, false, 0.3), y = RandomTile(rng, 16, false, 0.3);
  Tile sum_dense(x);
  sum_dense.Add(y);
  Tile y_packed(y);
  y_packed.Pack();
  Tile sum(x);
  sum.Add(y_packed);  // a packed addend adds like its dense form (+0 + -0 included)
  ExpectBitwiseEqualDense(sum, sum_dense);
  Tile cleared(y_packed);
  cleared.Clear();
  EXPECT_FALSE(cleared.is_packed());
  EXPECT_TRUE(cleared.Empty());
}

}  // namespace
}  // namespace bgkmap
