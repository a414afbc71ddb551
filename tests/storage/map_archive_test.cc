#include "bgkmap/storage/map_archive.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>

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

// bgk-ll maps: the plane moments go through an archive bitwise, two robots' archives merge into
// their sum (moments included), and a bgk-ll archive is refused by a map of another method.
TEST(MapArchiveTest, BgkLlArchivesRoundTripAndMerge) {
  TempDir dir;
  MapParams params = SmallParams();
  params.method = Method::kBgkLocalLinear;
  std::unique_ptr<TerrainMap> maps[2];
  for (int robot : {0, 1}) {
    maps[robot] = NewMap(params);
    for (int i = 1; i <= 4; ++i) Apply(*maps[robot], *MakeScan(params, robot, i), i);
    ASSERT_TRUE(
        ExportMap(*maps[robot], MetadataOf(*maps[robot]), dir.Sub(std::to_string(robot))).ok());
  }
  auto imported = NewMap(params);
  ASSERT_TRUE(ImportMap(dir.Sub("0"), *imported).ok());
  EXPECT_TRUE(MapsIdentical(*maps[0], *imported));
  ASSERT_TRUE(ImportMap(dir.Sub("1"), *imported).ok());
  int planes = 0;
  imported->ForEachTile([&](TileKey k, const Tile& t) {
    Tile want(t.tile_size(), /*plane_moments=*/true);
    for (const auto& m : maps) {
      if (const Tile* part = m->FindTile(k)) want.Add(*part);
    }
    planes += t.has_plane();
    EXPECT_TRUE(t == want) << k.x << "," << k.y;
  });
  EXPECT_EQ(planes, static_cast<int>(imported->tile_count()));
  EXPECT_FALSE(ImportMap(dir.Sub("0"), *NewMap(SmallParams())).ok());
}

TEST(MapArchiveTest, GeoreferenceRoundTrips) {
  TempDir dir;
  const auto map = RobotMap(0, 2);
  MapMetadata metadata = MetadataOf(*map);
  metadata.georeference = {"EPSG:32610", {551000.5, 4180000.25, 12.5}};
  ASSERT_TRUE(ExportMap(*map, metadata, dir.Sub("geo")).ok());
  auto imported = NewMap(SmallParams());
  Result<ImportReport> report = ImportMap(dir.Sub("geo"), *imported);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->metadata.georeference, metadata.georeference);
  EXPECT_TRUE(MapsIdentical(*map, *imported));
  // An archive without one (as every archive before it was kept): a local frame.
  ASSERT_TRUE(ExportMap(*map, MetadataOf(*map), dir.Sub("local")).ok());
  report = ImportMap(dir.Sub("local"), *NewMap(SmallParams()));
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->metadata.georeference.empty());
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

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteFile(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), static_cast<long>(bytes.size()));
}

// Every tile of `map` into `writer`, then the trailer.
Status WriteAll(const TerrainMap& map, MapArchiveWriter& writer) {
  Status status;
  map.ForEachTile([&](TileKey k, const Tile& t) {
    if (status.ok()) status = writer.Add(k, t);
  });
  return status.ok() ? writer.Finish() : status;
}

TEST(MapArchiveTest, SinkWriterWritesTheFileWritersBytes) {
  TempDir dir;
  const auto map = RobotMap(0, 5);
  ASSERT_TRUE(ExportMap(*map, MetadataOf(*map), dir.Sub("file")).ok());
  std::string streamed;
  size_t calls = 0;
  auto writer = MapArchiveWriter::CreateForSink(
      [&](std::string_view bytes) {
        streamed.append(bytes);
        ++calls;
        return Status::Ok();
      },
      MetadataOf(*map));
  ASSERT_TRUE(writer.ok());
  ASSERT_TRUE(WriteAll(*map, **writer).ok());
  EXPECT_EQ((*writer)->tiles(), map->tile_count());
  EXPECT_EQ((*writer)->bytes(), streamed.size());
  EXPECT_GT(calls, map->tile_count());  // header, one call per tile, trailer
  EXPECT_EQ(streamed, ReadFile(dir.Sub("file")));
  // And it reads back as the map.
  WriteFile(dir.Sub("streamed"), streamed);
  auto imported = NewMap(SmallParams());
  ASSERT_TRUE(ImportMap(dir.Sub("streamed"), *imported).ok());
  EXPECT_TRUE(MapsIdentical(*map, *imported));
}

TEST(MapArchiveTest, SinkErrorStopsTheWriter) {
  const auto map = RobotMap(0, 3);
  std::string streamed;
  auto writer = MapArchiveWriter::CreateForSink(
      [&](std::string_view bytes) {
        if (streamed.size() > 2000) return Status::IoError("peer went away");
        streamed.append(bytes);
        return Status::Ok();
      },
      MetadataOf(*map));
  ASSERT_TRUE(writer.ok());
  const Status s = WriteAll(*map, **writer);
  EXPECT_EQ(s.code(), Status::Code::kIoError);
  EXPECT_EQ(s.message(), "peer went away");
  EXPECT_EQ((*writer)->Finish().message(), "peer went away");  // sticky
  EXPECT_LT((*writer)->tiles(), map->tile_count());
}

TEST(MapArchiveTest, TrailingBytesAndAbsurdLengthsAreDataLoss) {
  TempDir dir;
  const auto map = RobotMap(0, 2);
  const std::string path = dir.Sub("a");
  ASSERT_TRUE(ExportMap(*map, MetadataOf(*map), path).ok());
  const std::string good = ReadFile(path);

  WriteFile(dir.Sub("trailing"), good + "xyz");
  auto target = NewMap(SmallParams());
  Result<ImportReport> r = ImportMap(dir.Sub("trailing"), *target);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(r.status().message().find("after its trailer"), std::string::npos);
  EXPECT_EQ(target->tile_count(), 0u);

  // A metadata length of 4 GiB in a tiny file: refused as truncated, nothing that large read.
  std::string huge = good;
  for (int i = 8; i < 12; ++i) huge[i] = static_cast<char>(0xff);
  WriteFile(dir.Sub("huge"), huge);
  EXPECT_EQ(ImportMap(dir.Sub("huge"), *target).status().code(), Status::Code::kDataLoss);

  WriteFile(dir.Sub("text"), "this is not a map archive at all\n");
  r = ImportMap(dir.Sub("text"), *target);
  EXPECT_EQ(r.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(r.status().message().find("not a bgkmap map archive"), std::string::npos);
}

}  // namespace
}  // namespace bgkmap::storage
