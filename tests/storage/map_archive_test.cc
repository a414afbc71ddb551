#include "bgkmap/storage/map_archive.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using testing::Apply;
using testing::MakeScan;
using testing::MapsIdentical;
using testing::NewMap;
using testing::SmallParams;
using testing::TempDir;

std::unique_ptr<TerrainMap> RobotMap(int robot, int scans) {
  const MapParams params = SmallParams();
  auto map = NewMap(params);
  for (int i = 1; i <= scans; ++i) Apply(*map, *MakeScan(params, robot, i), i);
  return map;
}

MapMetadata MetadataOf(const TerrainMap& map) {
  MapMetadata m;
  m.params = map.params();
  m.map_version = map.version();
  m.checkpoint_version = map.version();
  m.robot_sequences = {{"robot-a", 7}};
  return m;
}

TEST(MapArchiveTest, ExportImportRoundTripIsBitwise) {
  TempDir dir;
  const auto map = RobotMap(0, 6);
  const std::string path = dir.Sub("map.bgkmap");
  ASSERT_TRUE(ExportMap(*map, MetadataOf(*map), path).ok());
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
  auto imported = NewMap(SmallParams());
  Result<ImportReport> report = ImportMap(path, *imported);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->tiles, map->tile_count());
  EXPECT_EQ(report->metadata.robot_sequences.at("robot-a"), 7u);
  EXPECT_TRUE(MapsIdentical(*map, *imported));
}

TEST(MapArchiveTest, ImportingTwoArchivesMergesTheirSum) {
  TempDir dir;
  const auto a = RobotMap(0, 5), b = RobotMap(1, 5);  // overlapping lanes
  ASSERT_TRUE(ExportMap(*a, MetadataOf(*a), dir.Sub("a")).ok());
  ASSERT_TRUE(ExportMap(*b, MetadataOf(*b), dir.Sub("b")).ok());
  auto merged = NewMap(SmallParams());
  ASSERT_TRUE(ImportMap(dir.Sub("a"), *merged).ok());
  ASSERT_TRUE(ImportMap(dir.Sub("b"), *merged).ok());
  int overlapping = 0;
  merged->ForEachTile([&](TileKey k, const Tile& t) {
    const Tile* ta = a->FindTile(k);
    const Tile* tb = b->FindTile(k);
    Tile want(t.tile_size());
    if (ta) want.Add(*ta);
    if (tb) want.Add(*tb);
    overlapping += (ta && tb) ? 1 : 0;
    EXPECT_TRUE(t == want) << k.x << "," << k.y;
  });
  EXPECT_GT(overlapping, 0);
  EXPECT_EQ(merged->tile_count(), [&] {
    std::set<TileKey> keys;
    a->ForEachTile([&](TileKey k, const Tile&) { keys.insert(k); });
    b->ForEachTile([&](TileKey k, const Tile&) { keys.insert(k); });
    return keys.size();
  }());
}

TEST(MapArchiveTest, IncompatibleArchiveIsRefusedNamingTheKey) {
  TempDir dir;
  const auto map = RobotMap(0, 2);
  ASSERT_TRUE(ExportMap(*map, MetadataOf(*map), dir.Sub("a")).ok());
  MapParams other = SmallParams();
  other.kernel_length = 0.8;
  auto target = NewMap(other);
  Result<ImportReport> report = ImportMap(dir.Sub("a"), *target);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(report.status().message().find("kernel_length"), std::string::npos);
}

TEST(MapArchiveTest, DamagedArchiveIsDataLossAndTheMapIsUntouched) {
  TempDir dir;
  const auto map = RobotMap(0, 4);
  const std::string path = dir.Sub("a");
  ASSERT_TRUE(ExportMap(*map, MetadataOf(*map), path).ok());
  const auto size = std::filesystem::file_size(path);
  for (double where : {0.5, 0.99}) {
    const std::string bad = dir.Sub("bad");
    std::filesystem::copy_file(path, bad, std::filesystem::copy_options::overwrite_existing);
    {
      std::fstream f(bad, std::ios::in | std::ios::out | std::ios::binary);
      const auto at = static_cast<std::streamoff>(where * size);
      f.seekg(at);
      char c;
      f.read(&c, 1);
      c = static_cast<char>(c ^ 0x08);
      f.seekp(at);
      f.write(&c, 1);
    }
    auto target = NewMap(SmallParams());
    Result<ImportReport> report = ImportMap(bad, *target);
    ASSERT_FALSE(report.ok()) << "flip at " << where;
    EXPECT_EQ(report.status().code(), Status::Code::kDataLoss);
    EXPECT_EQ(target->tile_count(), 0u);
  }
  std::filesystem::resize_file(path, size - 3);
  auto target = NewMap(SmallParams());
  EXPECT_EQ(ImportMap(path, *target).status().code(), Status::Code::kDataLoss);
}

}  // namespace
}  // namespace bgkmap::storage
