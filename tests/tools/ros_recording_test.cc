// The recording readers (MCAP, CDR PointCloud2, TF, rosbag2 SQLite, ROS 1 bags) on recordings
// written by Foxglove's own libraries (@mcap/core, @foxglove/rosmsg2-serialization, and
// @foxglove/rosmsg-serialization for the ROS 1 bag's messages) from the real Ouster street scans:
// tests/interop/ros2/write_recordings.mjs, run once for the suite.
#include "bgkmap/io/ros_recording.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/io/mcap_reader.h"
#include "bgkmap/io/point_cloud2.h"
#include "bgkmap/io/tf_buffer.h"
#include "test_files.h"

namespace bgkmap::io {
namespace {

namespace fs = std::filesystem;
using testing::ReadBytes;
using testing::TempDir;
using testing::WriteBytes;

const std::string kStreet = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";

class RosRecordingTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("bgkmap_ros2_recordings_" + std::to_string(getpid()));
    fs::create_directories(dir_);
    const std::string cmd = "node " BGKMAP_SOURCE_DIR "/tests/interop/ros2/write_recordings.mjs " +
                            std::string(BGKMAP_SHARED_DATA) + " " + dir_.string() + " >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static std::string Rec(const std::string& name) { return (dir_ / name).string(); }

  static Result<RecordingScans> Scans(const std::string& path, RecordingOptions o = {}) {
    Result<std::vector<RecordedMessage>> m = ReadRecordedMessages(path);
    if (!m.ok()) return m.status();
    return ExtractScans(*m, o, path);
  }

  static fs::path dir_;
};
fs::path RosRecordingTest::dir_;

std::vector<Point3f> Finite(const std::vector<Point3f>& points) {
  std::vector<Point3f> out;
  for (const Point3f& p : points) {
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) out.push_back(p);
  }
  return out;
}

bool SameBits(const std::vector<Point3f>& a, const std::vector<Point3f>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Point3f)) == 0;
}

double PoseError(const Pose& a, const Pose& b) {
  return std::max((a.rotation - b.rotation).cwiseAbs().maxCoeff(),
                  (a.translation - b.translation).cwiseAbs().maxCoeff());
}

// Each layout (float32 little-endian, float64 big-endian organized with row padding and NaN
// points), each compression, chunked or not, with or without a summary: the points are the
// .bin's bit for bit and the poses poses.txt's (through quaternions, a chain and interpolation).
TEST_F(RosRecordingTest, EveryLayoutAndCompressionReadsTheRealScans) {
  Result<KittiSequence> seq = KittiSequence::Open(kStreet);
  ASSERT_TRUE(seq.ok());
  for (const char* name : {"direct_none.mcap", "unchunked.mcap", "chain_lz4.mcap", "street.bag"}) {
    SCOPED_TRACE(name);
    Result<RecordingScans> rec = Scans(Rec(name));
    ASSERT_TRUE(rec.ok()) << rec.status().message();
    EXPECT_EQ(rec->topic, "/points");
    ASSERT_EQ(rec->scans.size(), 3u);
    EXPECT_EQ(rec->skipped, 0u);
    for (size_t k = 0; k < 3; ++k) {
      Result<Scan> want = seq->Read(k);
      ASSERT_TRUE(want.ok());
      EXPECT_TRUE(SameBits(Finite(rec->scans[k].points), want->points)) << "scan " << k;
      // A direct transform is a quaternion of the pose (1e-12); the chain composes three and
      // interpolates one (1e-9). Catches a swapped parent/child, a missing inverse, or slerp
      // at the wrong fraction (all of them metres or radians off).
      EXPECT_LT(PoseError(rec->scans[k].pose, want->pose), 1e-9) << "scan " << k;
      EXPECT_EQ(rec->scans[k].stamp_ns, 1'700'000'000'000'000'000 + int64_t(k) * 100'000'000);
    }
  }
}

TEST_F(RosRecordingTest, CloudWithoutTransformIsSkippedAndCounted) {
  Result<RecordingScans> rec = Scans(Rec("partial_zstd.mcap"));
  ASSERT_TRUE(rec.ok()) << rec.status().message();
  EXPECT_EQ(rec->scans.size(), 2u);
  EXPECT_EQ(rec->skipped, 1u);
  EXPECT_NE(rec->first_skip.find("tf never extrapolates"), std::string::npos) << rec->first_skip;
  // A map frame nobody publishes: every cloud skipped, none guessed.
  rec = Scans(Rec("direct_none.mcap"), {"/points", "earth"});
  ASSERT_TRUE(rec.ok());
  EXPECT_EQ(rec->scans.size(), 0u);
  EXPECT_EQ(rec->skipped, 3u);
  EXPECT_NE(rec->first_skip.find("no chain of transforms"), std::string::npos);
}

TEST_F(RosRecordingTest, MissingFieldUnknownSchemaAndUnknownTopicAreOneLine) {
  Result<RecordingScans> rec = Scans(Rec("no_z.mcap"));
  ASSERT_FALSE(rec.ok());
  EXPECT_NE(rec.status().message().find("no field 'z'"), std::string::npos)
      << rec.status().message();
  EXPECT_NE(rec.status().message().find("message 1 on /points"), std::string::npos);
  rec = Scans(Rec("direct_none.mcap"), {"/tf", "map"});
  ASSERT_FALSE(rec.ok());
  EXPECT_NE(rec.status().message().find("unknown schema 'tf2_msgs/msg/TFMessage'"),
            std::string::npos)
      << rec.status().message();
  rec = Scans(Rec("direct_none.mcap"), {"/velodyne_points", "map"});
  ASSERT_FALSE(rec.ok());
  EXPECT_NE(rec.status().message().find("no messages on topic /velodyne_points"),
            std::string::npos);
  EXPECT_EQ(rec.status().message().find('\n'), std::string::npos);
}

// Every cut of a real file and a flipped byte in each region: an error naming the file, never a
// crash, never a partial read (ParseMcap returns all or nothing).
TEST_F(RosRecordingTest, TruncatedOrCorruptFilesAreRefused) {
  for (const char* name :
       {"direct_none.mcap", "chain_lz4.mcap", "partial_zstd.mcap", "unchunked.mcap"}) {
    SCOPED_TRACE(name);
    const std::string bytes = ReadBytes(Rec(name));
    for (size_t cut = 0; cut < bytes.size(); cut += bytes.size() / 23 + 1) {
      Result<McapContents> r = ParseMcap(std::string_view(bytes).substr(0, cut), name);
      EXPECT_FALSE(r.ok()) << "cut at " << cut;
    }
    Result<McapContents> r = ParseMcap(std::string_view(bytes).substr(0, bytes.size() - 1), name);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("truncated"), std::string::npos) << r.status().message();
    // A flipped bit in the middle of the points: a chunk's CRC (chunked files) or the data
    // section's (unchunked) catches it; in compressed chunks the decompressor may see it first
    // (lz4 and zstd frames carry their own checksum).
    std::string bad = bytes;
    bad[bytes.size() / 3] ^= 0x10;
    r = ParseMcap(bad, name);
    ASSERT_FALSE(r.ok());
    const std::string& why = r.status().message();
    EXPECT_TRUE(why.find("CRC mismatch") != std::string::npos ||
                why.find("does not decompress") != std::string::npos)
        << why;
    EXPECT_NE(r.status().message().find(name), std::string::npos);
  }
}

// A ROS 1 bag cut anywhere is refused by rosbag_storage, as one line naming the file.
TEST_F(RosRecordingTest, TruncatedRos1BagIsOneLine) {
  const std::string bytes = ReadBytes(Rec("street.bag"));
  TempDir dir;
  for (size_t cut : {size_t{0}, size_t{13}, size_t{3000}, bytes.size() / 2, bytes.size() - 10}) {
    WriteBytes(dir.Path("cut.bag"), bytes.substr(0, cut));
    Result<std::vector<RecordedMessage>> r = ReadRecordedMessages(dir.Path("cut.bag"));
    ASSERT_FALSE(r.ok()) << "cut at " << cut;
    EXPECT_NE(r.status().message().find("cut.bag: not a readable ROS 1 bag"), std::string::npos)
        << r.status().message();
    EXPECT_EQ(r.status().message().find('\n'), std::string::npos);
  }
}

// Every prefix of a real PointCloud2 message: DataLoss naming a field, never a read past the end.
TEST_F(RosRecordingTest, TruncatedPointCloud2NamesTheField) {
  Result<std::vector<RecordedMessage>> m = ReadRecordedMessages(Rec("chain_lz4.mcap"));
  ASSERT_TRUE(m.ok());
  const auto cloud = std::find_if(m->begin(), m->end(),
                                  [](const RecordedMessage& x) { return x.topic == "/points"; });
  ASSERT_NE(cloud, m->end());
  const auto* bytes = reinterpret_cast<const uint8_t*>(cloud->data.data());
  for (size_t cut = 0; cut < 200; ++cut) {
    Result<PointCloud2> r = DecodePointCloud2({bytes, cut});
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find(cut < 4 ? "not CDR" : "field"), std::string::npos)
        << cut << ": " << r.status().message();
  }
  Result<PointCloud2> r = DecodePointCloud2({bytes, cloud->data.size() - 1});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("field"), std::string::npos) << r.status().message();
  ASSERT_TRUE(DecodePointCloud2({bytes, cloud->data.size()}).ok());
}

// A cloud of width 0 (or height 0) has no points, however many rows it declares: decoded at once
// (found by the cdr_reader fuzzer: height 2^32 - 1 of width 0 spun over its empty rows).
TEST_F(RosRecordingTest, EmptyRowsDecodeToNoPointsAtOnce) {
  Result<std::vector<RecordedMessage>> m = ReadRecordedMessages(Rec("chain_lz4.mcap"));
  ASSERT_TRUE(m.ok());
  const auto cloud = std::find_if(m->begin(), m->end(),
                                  [](const RecordedMessage& x) { return x.topic == "/points"; });
  ASSERT_NE(cloud, m->end());
  std::vector<uint8_t> bytes(cloud->data.begin(), cloud->data.end());
  Result<PointCloud2> real = DecodePointCloud2(bytes);
  ASSERT_TRUE(real.ok());
  // height and width follow the header, 4-aligned: the first such pair after the encapsulation.
  const uint32_t shape[2] = {real->height, real->width};
  size_t at = 4;
  while (at + 8 <= bytes.size() && std::memcmp(bytes.data() + at, shape, 8) != 0) at += 4;
  ASSERT_LE(at + 8, bytes.size());
  const uint32_t empty_rows[2] = {0xFFFFFFFFu, 0};
  std::memcpy(bytes.data() + at, empty_rows, 8);
  Result<PointCloud2> r = DecodePointCloud2(bytes);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_TRUE(r->points.empty());
  EXPECT_EQ(r->height, 0xFFFFFFFFu);
}

// The map of a sequence of posed scans, stamped as `bgkmap build` stamps them.
Raster BuildMap(const std::vector<std::pair<std::vector<Point3f>, Pose>>& scans,
                const std::vector<double>& times) {
  auto map = TerrainMap::Create(MapParams{});
  EXPECT_TRUE(map.ok());
  for (size_t k = 0; k < scans.size(); ++k) {
    const int64_t stamp = 1'000'000'000 + std::llround((times[k] - times[0]) * 1e9);
    EXPECT_TRUE((*map)->IntegrateScan(scans[k].first, scans[k].second, false, stamp).ok());
  }
  return ExtractRaster(**map, (*map)->KnownBounds(),
                       {Layer::kElevation, Layer::kElevationVariance, Layer::kTraversability,
                        Layer::kTraversabilityVariance, Layer::kState});
}

bool SameRaster(const Raster& a, const Raster& b) {
  if (a.cols != b.cols || a.rows != b.rows || a.x0 != b.x0 || a.y1 != b.y1) return false;
  for (size_t l = 0; l < a.data.size(); ++l) {
    if (std::memcmp(a.data[l].data(), b.data[l].data(), a.data[l].size() * sizeof(float)) != 0)
      return false;
  }
  return true;
}

// The map built from a recording equals, bit for bit, the map built from the same scans as a
// KITTI-like folder (the .bin files, the recording's poses written to poses.txt round-trip
// exact, its stamps to times.txt). For the float32 layout and for the float64 big-endian one
// with NaN points and a TF chain.
TEST_F(RosRecordingTest, MapFromRecordingEqualsMapFromFolder) {
  for (const char* name : {"direct_none.mcap", "chain_lz4.mcap"}) {
    SCOPED_TRACE(name);
    Result<RecordingScans> rec = Scans(Rec(name));
    ASSERT_TRUE(rec.ok()) << rec.status().message();
    TempDir folder;
    fs::create_directories(folder.path() / "velodyne");
    std::string times;
    std::vector<std::pair<std::vector<Point3f>, Pose>> from_rec;
    std::vector<double> rec_times;
    for (size_t k = 0; k < rec->scans.size(); ++k) {
      fs::copy_file(kStreet + "/velodyne/" + KittiScanFileName(k),
                    folder.path() / "velodyne" / KittiScanFileName(k));
      ASSERT_TRUE(AppendPose(folder.Path("poses.txt"), rec->scans[k].pose).ok());
      const double t = static_cast<double>(rec->scans[k].stamp_ns) * 1e-9;
      char line[64];
      std::snprintf(line, sizeof line, "%.17g\n", t);
      times += line;
      from_rec.emplace_back(rec->scans[k].points, rec->scans[k].pose);
      rec_times.push_back(t);
    }
    WriteBytes(folder.Path("times.txt"), times);
    Result<KittiSequence> seq = KittiSequence::Open(folder.path().string());
    ASSERT_TRUE(seq.ok()) << seq.status().message();
    std::vector<std::pair<std::vector<Point3f>, Pose>> from_folder;
    std::vector<double> folder_times;
    for (size_t k = 0; k < seq->size(); ++k) {
      Result<Scan> s = seq->Read(k);
      ASSERT_TRUE(s.ok());
      from_folder.emplace_back(s->points, s->pose);
      folder_times.push_back(s->time_s);
    }
    const Raster a = BuildMap(from_rec, rec_times);
    const Raster b = BuildMap(from_folder, folder_times);
    EXPECT_GT(a.cols * a.rows, 10'000);
    EXPECT_TRUE(SameRaster(a, b));
  }
}

// rosbag2's SQLite storage: the same messages in a .db3 (written here with SQLite from the
// Foxglove-written MCAP, in rosbag2's schema), read as a file and as a rosbag2 folder.
TEST_F(RosRecordingTest, Rosbag2SqliteReadsLikeMcap) {
  Result<McapContents> mcap = ReadMcapFile(Rec("partial_zstd.mcap"));
  ASSERT_TRUE(mcap.ok());
  TempDir bag;
  const std::string db_path = bag.Path("bag_0.db3");
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(db_path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type "
                         "TEXT NOT NULL, serialization_format TEXT NOT NULL, offered_qos_profiles "
                         "TEXT NOT NULL);"
                         "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT "
                         "NULL, timestamp INTEGER NOT NULL, data BLOB NOT NULL);",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  for (const auto& [id, c] : mcap->channels) {
    const std::string sql = "INSERT INTO topics VALUES(" + std::to_string(id) + ", '" + c.topic +
                            "', '" + mcap->schemas.at(c.schema_id).name + "', 'cdr', '')";
    ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  }
  sqlite3_stmt* insert = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "INSERT INTO messages(topic_id, timestamp, data) VALUES(?,?,?)",
                               -1, &insert, nullptr),
            SQLITE_OK);
  for (const McapMessage& m : mcap->messages) {
    sqlite3_bind_int(insert, 1, m.channel_id);
    sqlite3_bind_int64(insert, 2, static_cast<sqlite3_int64>(m.log_time));
    sqlite3_bind_blob(insert, 3, m.data.data(), static_cast<int>(m.data.size()), SQLITE_STATIC);
    ASSERT_EQ(sqlite3_step(insert), SQLITE_DONE);
    sqlite3_reset(insert);
  }
  sqlite3_finalize(insert);
  sqlite3_close(db);
  WriteBytes(bag.Path("metadata.yaml"), "rosbag2_bagfile_information:\n  version: 5\n");

  Result<RecordingScans> want = Scans(Rec("partial_zstd.mcap"));
  ASSERT_TRUE(want.ok());
  for (const std::string& path : {db_path, bag.path().string()}) {
    SCOPED_TRACE(path);
    Result<RecordingScans> got = Scans(path);
    ASSERT_TRUE(got.ok()) << got.status().message();
    ASSERT_EQ(got->scans.size(), want->scans.size());
    EXPECT_EQ(got->skipped, want->skipped);
    for (size_t k = 0; k < got->scans.size(); ++k) {
      EXPECT_TRUE(SameBits(got->scans[k].points, want->scans[k].points));
      EXPECT_EQ(PoseError(got->scans[k].pose, want->scans[k].pose), 0.0);
    }
  }
  WriteBytes(bag.Path("not_a_bag.db3"), "SQLite format 3 but not really");
  Result<std::vector<RecordedMessage>> bad = ReadRecordedMessages(bag.Path("not_a_bag.db3"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("not_a_bag.db3"), std::string::npos);
}

StampedTransform Edge(const char* parent, const char* child, int64_t ns, double x, double yaw = 0) {
  StampedTransform t;
  t.stamp_ns = ns;
  t.parent = parent;
  t.child = child;
  t.translation = {x, 0, 0};
  t.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  return t;
}

TEST(TfBufferTest, ChainsInterpolatesAndNeverExtrapolates) {
  TfBuffer tf;
  ASSERT_TRUE(tf.Add(Edge("map", "odom", 0, 10), true).ok());
  ASSERT_TRUE(tf.Add(Edge("odom", "base", 100, 0, 0), false).ok());
  ASSERT_TRUE(tf.Add(Edge("odom", "base", 200, 2, M_PI / 2), false).ok());
  ASSERT_TRUE(tf.Add(Edge("base", "lidar", 0, 1), true).ok());
  // Half way: base at x = 1, turned 45 degrees; lidar 1 m ahead of it along the heading.
  Result<Pose> p = tf.Lookup("map", "lidar", 150);
  ASSERT_TRUE(p.ok()) << p.status().message();
  EXPECT_NEAR(p->translation.x(), 10 + 1 + std::cos(M_PI / 4), 1e-12);
  EXPECT_NEAR(p->translation.y(), std::sin(M_PI / 4), 1e-12);
  // The inverse direction and a lookup between siblings go through the common ancestor.
  Result<Pose> back = tf.Lookup("lidar", "map", 150);
  ASSERT_TRUE(back.ok());
  EXPECT_LT((back->rotation * p->translation + back->translation).norm(), 1e-12);
  EXPECT_FALSE(tf.Lookup("map", "lidar", 99).ok());   // before the first sample
  EXPECT_FALSE(tf.Lookup("map", "lidar", 201).ok());  // after the last
  EXPECT_FALSE(tf.Lookup("map", "camera", 150).ok());
  // A second parent would make the tree ambiguous.
  EXPECT_FALSE(tf.Add(Edge("map", "base", 150, 0), false).ok());
}

}  // namespace
}  // namespace bgkmap::io
