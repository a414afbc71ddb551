// A cluster shard integrates only the scans' cells within its partitions' halos
// (PartitionLayout::HaloCells, RestrictScan). The claim: its partitions' tiles are then bitwise
// those of the whole map. Checked on the real street scans, with dynamics on (free-space rays)
// and off, and shown to fail with a halo that is too small (so the test can see a wrong halo).
#include "cluster/partition_layout.h"

#include <gtest/gtest.h>

#include "test_support.h"

namespace bgkmap::testing {
namespace {

using cluster::PartitionKey;
using cluster::PartitionLayout;

TEST(PartitionLayoutTest, NamesAndGeometry) {
  const PartitionLayout layout(MapParams{}, 4);
  EXPECT_EQ(layout.PartitionOf({-1, -5}), (PartitionKey{-1, -2}));
  EXPECT_EQ(layout.PartitionOf({3, 4}), (PartitionKey{0, 1}));
  EXPECT_EQ(cluster::PartitionName({3, -2}), "3.-2");
  EXPECT_EQ(cluster::ParsePartitionName("3.-2"), (PartitionKey{3, -2}));
  EXPECT_FALSE(cluster::ParsePartitionName("3.").has_value());
  EXPECT_FALSE(cluster::ParsePartitionName("x.1").has_value());
  const CellBox cells = layout.Cells({-1, 0});
  EXPECT_EQ(cells.min, (CellIndex{-256, 0}));
  EXPECT_EQ(cells.max, (CellIndex{-1, 255}));
  // Defaults: 2 l + r + clear_ray_length = 0.6 + 0.3 + 2.0 m, in 0.1 m cells, plus 2.
  EXPECT_EQ(layout.halo_cells(), 31);
  EXPECT_EQ(layout.HaloCells({0, 0}).min, (CellIndex{-31, -31}));
}

// The map of `scans` restricted to the halo of `p` (cut to `halo_cells` when not -1).
std::unique_ptr<TerrainMap> RestrictedMap(const std::vector<OwnedScan>& scans,
                                          const MapParams& params, const PartitionLayout& layout,
                                          PartitionKey p, int halo_cells = -1) {
  CellBox keep = layout.HaloCells(p);
  if (halo_cells >= 0) {
    keep = layout.Cells(p);
    keep.min = {keep.min.x - halo_cells, keep.min.y - halo_cells};
    keep.max = {keep.max.x + halo_cells, keep.max.y + halo_cells};
  }
  std::unique_ptr<TerrainMap> map = TerrainMap::Create(params).value();
  uint64_t version = 0;
  for (const OwnedScan& s : scans) {
    // The points a shard integrates: as the client sends them (compact by default), like the
    // whole map's OfflineMap.
    const std::vector<Point3f> points = PointsAsIntegrated(s, params);
    Result<PreparedScan> prepared = PrepareScan(params, points, WirePose(s.pose));
    EXPECT_TRUE(prepared.ok());
    const PreparedScan cut = RestrictScan(params, *prepared, keep);
    ++version;
    if (cut.cells.empty()) continue;
    const TileWindow window = map->MakeWindow(cut);
    map->Integrate(cut, window, version);
  }
  return map;
}

// Tiles of `p` that differ between the maps (statistics, bitwise), and how many were compared.
std::pair<int, int> DifferingTiles(const TerrainMap& whole, const TerrainMap& part,
                                   const PartitionLayout& layout, PartitionKey p) {
  int differing = 0, compared = 0;
  const TileKey lo = layout.MinTile(p), hi = layout.MaxTile(p);
  for (int x = lo.x; x <= hi.x; ++x) {
    for (int y = lo.y; y <= hi.y; ++y) {
      const Tile* a = whole.FindTile({x, y});
      const Tile* b = part.FindTile({x, y});
      if (a == nullptr && b == nullptr) continue;
      ++compared;
      if (a == nullptr || b == nullptr || !(*a == *b)) ++differing;
    }
  }
  return {differing, compared};
}

class RestrictScanTest : public ::testing::TestWithParam<Dynamics> {};

TEST_P(RestrictScanTest, PartitionTilesEqualTheWholeMapsBitwise) {
  MapParams params;
  params.dynamics = GetParam();
  const std::vector<OwnedScan> scans = SubScans("r", 4);
  std::vector<const OwnedScan*> order;
  for (const OwnedScan& s : scans) order.push_back(&s);
  const std::unique_ptr<TerrainMap> whole = OfflineMap(order, params);
  const PartitionLayout layout(params, 2);
  // Partitions near the robot's path (where the free-space rays are), and far out.
  int compared = 0;
  for (PartitionKey p : {PartitionKey{0, 0}, PartitionKey{-1, 0}, PartitionKey{0, -1},
                         PartitionKey{3, 1}, PartitionKey{-5, -2}}) {
    const std::unique_ptr<TerrainMap> part = RestrictedMap(scans, params, layout, p);
    auto [differing, n] = DifferingTiles(*whole, *part, layout, p);
    EXPECT_EQ(differing, 0) << "partition " << cluster::PartitionName(p) << ": " << differing
                            << " of " << n << " tiles differ";
    compared += n;
  }
  EXPECT_GT(compared, 8);
}

INSTANTIATE_TEST_SUITE_P(Dynamics, RestrictScanTest,
                         ::testing::Values(Dynamics::kOn, Dynamics::kOff),
                         [](const ::testing::TestParamInfo<Dynamics>& p) {
                           return std::string(p.param == Dynamics::kOn ? "On" : "Off");
                         });

TEST(RestrictScanTest, TooSmallAHaloIsSeen) {
  // Mutation check of the test above: a halo without the free-space rays' reach (2 l + r + 2
  // cells = 11, not 31) misses rays that clear cells of the partition.
  const MapParams params;
  const std::vector<OwnedScan> scans = SubScans("r", 4);
  std::vector<const OwnedScan*> order;
  for (const OwnedScan& s : scans) order.push_back(&s);
  const std::unique_ptr<TerrainMap> whole = OfflineMap(order, params);
  const PartitionLayout layout(params, 2);
  const std::unique_ptr<TerrainMap> part =
      RestrictedMap(scans, params, layout, {0, 0}, /*halo_cells=*/11);
  EXPECT_GT(DifferingTiles(*whole, *part, layout, {0, 0}).first, 0);
}

}  // namespace
}  // namespace bgkmap::testing
