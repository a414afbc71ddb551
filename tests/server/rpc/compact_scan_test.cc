// Compact scans through the real server and client (docs/server.md "Compact scans"): the map the
// server serves for the client's default encoding is the map of the dequantized points, bit for
// bit, and mostly within 5 mm of elevation of the map of the raw float32 points; an old client
// sending float32 still gets the map of its raw points; acks count every point the caller gave.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "bgkmap/core/raster.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

std::vector<ScanData> DataOf(const std::vector<OwnedScan>& scans) {
  std::vector<ScanData> out;
  for (const OwnedScan& s : scans) out.push_back(s.Data());
  return out;
}

std::vector<const OwnedScan*> Pointers(const std::vector<OwnedScan>& scans) {
  std::vector<const OwnedScan*> out;
  for (const OwnedScan& s : scans) out.push_back(&s);
  return out;
}

struct ElevationDifference {
  double worst = 0;     // metres, over the cells both maps know
  size_t both = 0;      // cells both maps know
  size_t only_one = 0;  // cells one map knows and the other does not
  size_t over_5mm = 0;  // cells both know whose elevations differ by more than 5 mm
};

ElevationDifference CompareElevation(const TerrainMap& a, const TerrainMap& b) {
  CellBox box = a.KnownBounds();
  box.Extend(b.KnownBounds().min);
  box.Extend(b.KnownBounds().max);
  const Raster ra = ExtractRaster(a, box, {Layer::kElevation});
  const Raster rb = ExtractRaster(b, box, {Layer::kElevation});
  ElevationDifference d;
  for (size_t i = 0; i < ra.data[0].size(); ++i) {
    const float x = ra.data[0][i], y = rb.data[0][i];
    if (std::isnan(x) != std::isnan(y)) ++d.only_one;
    if (std::isnan(x) || std::isnan(y)) continue;
    ++d.both;
    const double e = std::abs(static_cast<double>(x) - y);
    d.worst = std::max(d.worst, e);
    if (e > 0.005) ++d.over_5mm;
  }
  return d;
}

TEST(CompactScanTest, TheServedMapIsTheMapOfTheDequantizedPoints) {
  const std::vector<OwnedScan> scans = SubScans("compact", 4, 8);
  ServerFixture fixture;
  RpcResult<std::vector<ScanAck>> acks = fixture.client().IngestAll(DataOf(scans));
  ASSERT_TRUE(acks.ok()) << acks.status().ToString();
  ASSERT_EQ(acks->size(), scans.size());
  for (size_t i = 0; i < scans.size(); ++i) {
    const ScanPointCounts& c = (*acks)[i].counts;
    EXPECT_EQ((*acks)[i].status, AckStatus::kApplied);
    // Counted as if every point had been sent, though the client dropped what the map drops.
    EXPECT_EQ(c.input, scans[i].points.size());
    EXPECT_EQ(
        c.kept + c.dropped_nonfinite + c.dropped_range + c.dropped_height + c.dropped_out_of_bounds,
        c.input);
  }
  const std::unique_ptr<TerrainMap> served = fixture.server().SnapshotMap();
  const MapParams params;
  EXPECT_TRUE(MapsEqual(*served, *OfflineMap(Pointers(scans), params, Wire::kClientDefault)));
  // Not the raw points' map to the bit (else this test could not tell the encodings apart). Nor
  // within 5 mm everywhere: a point that the 1 mm quantization moves across a cell's edge changes
  // that cell's max, and the kernel spreads it. Measured on these scans: 2.4 % of the cells both
  // maps know differ by more than 5 mm (the worst by 2.3 m, a wall's top changing cells), 0.2 %
  // are known by one map only. The bound below is loose on purpose; it catches a step or an
  // order that moves the points far more (a 1 cm step gives several times these figures).
  const std::unique_ptr<TerrainMap> raw = OfflineMap(Pointers(scans), params, Wire::kFloat32);
  EXPECT_FALSE(MapsEqual(*served, *raw));
  const ElevationDifference d = CompareElevation(*served, *raw);
  ASSERT_GT(d.both, 10000u);
  EXPECT_LE(d.over_5mm * 20, d.both) << d.over_5mm << " of " << d.both << " cells";
  EXPECT_LE(d.only_one * 100, d.both) << d.only_one << " of " << d.both;
  std::printf("compact vs raw: %zu cells both, %zu only one, %zu over 5 mm, worst %.3g m\n", d.both,
              d.only_one, d.over_5mm, d.worst);
}

TEST(CompactScanTest, AClientSendingFloat32GetsTheMapOfItsRawPoints) {
  const std::vector<OwnedScan> scans = SubScans("float32", 4, 4);
  ServerFixture fixture;
  ClientOptions old;
  old.compact_step = 0;
  old.drop_filtered_points = false;
  Client client(fixture.target(), old);
  RpcResult<std::vector<ScanAck>> acks = client.IngestAll(DataOf(scans));
  ASSERT_TRUE(acks.ok()) << acks.status().ToString();
  ASSERT_EQ(acks->size(), scans.size());
  EXPECT_TRUE(MapsEqual(*fixture.server().SnapshotMap(),
                        *OfflineMap(Pointers(scans), MapParams{}, Wire::kFloat32)));
}

}  // namespace
}  // namespace bgkmap::testing
