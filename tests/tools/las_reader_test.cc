#include "bgkmap/io/las_reader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>

#include "test_files.h"

namespace bgkmap::io {
namespace {

namespace fs = std::filesystem;
using testing::ReadBytes;
using testing::TempDir;
using testing::WriteBytes;

const std::string kLas = std::string(BGKMAP_SHARED_DATA) + "/als_topography/topography.las";

template <typename T>
void Put(std::string& bytes, size_t at, T v) {
  std::memcpy(bytes.data() + at, &v, sizeof(T));
}

TEST(LasReaderTest, ReadsRealHeader) {
  Result<LasHeader> h = ReadLasHeader(kLas);
  ASSERT_TRUE(h.ok()) << h.status().message();
  EXPECT_EQ(h->version_major, 1);
  EXPECT_EQ(h->version_minor, 2);
  EXPECT_EQ(h->point_format, 1);
  EXPECT_EQ(h->point_record_length, 28);
  EXPECT_EQ(h->header_size, 227);
  EXPECT_EQ(h->point_data_offset, 297u);
  EXPECT_EQ(h->point_count, 73'403u);
  EXPECT_DOUBLE_EQ(h->scale[0], 0.00025);
  EXPECT_DOUBLE_EQ(h->offset[1], 5'270'000.0);
  // Its one VLR is a GeoKeyDirectory with ProjectedCSTypeGeoKey 2949 (NAD83(CSRS) / MTM zone 7).
  EXPECT_EQ(h->crs, "EPSG:2949");
}

// A LAS 1.2 header of 227 bytes followed by `vlrs` and no point.
std::string LasWithVlrs(const std::string& vlrs, uint32_t vlr_count) {
  std::string bytes(227, '\0');
  std::memcpy(bytes.data(), "LASF", 4);
  bytes[24] = 1;
  bytes[25] = 2;
  Put<uint16_t>(bytes, 94, 227);
  Put<uint32_t>(bytes, 96, static_cast<uint32_t>(227 + vlrs.size()));
  Put<uint32_t>(bytes, 100, vlr_count);
  bytes[104] = 0;
  Put<uint16_t>(bytes, 105, 20);
  for (int a = 0; a < 3; ++a) Put<double>(bytes, 131 + 8 * a, 0.01);
  return bytes + vlrs;
}

std::string Vlr(const std::string& user, uint16_t record, const std::string& data) {
  std::string v(54, '\0');
  std::memcpy(v.data() + 2, user.data(), std::min<size_t>(user.size(), 16));
  Put<uint16_t>(v, 18, record);
  Put<uint16_t>(v, 20, static_cast<uint16_t>(data.size()));
  return v + data;
}

TEST(LasReaderTest, CrsFromWktRecordOrGeoKeysAndNoneFromDamagedRecords) {
  TempDir dir;
  const std::string wkt = "PROJCS[\"WGS 84 / UTM zone 10N\",AUTHORITY[\"EPSG\",\"32610\"]]";
  std::string keys(16, '\0');  // version 1.1.0, one key: GeographicTypeGeoKey = 4326
  Put<uint16_t>(keys, 0, 1);
  Put<uint16_t>(keys, 2, 1);
  Put<uint16_t>(keys, 6, 1);
  Put<uint16_t>(keys, 8, 2048);
  Put<uint16_t>(keys, 12, 1);
  Put<uint16_t>(keys, 14, 4326);
  struct Case {
    std::string vlrs;
    uint32_t count;
    std::string crs;
  };
  const Case cases[] = {
      {Vlr("LASF_Projection", 2112, wkt + std::string(1, '\0')), 1, wkt},
      {Vlr("LASF_Projection", 34735, keys), 1, "EPSG:4326"},
      // The WKT wins over the keys, whatever the order.
      {Vlr("LASF_Projection", 34735, keys) + Vlr("LASF_Projection", 2112, wkt), 2, wkt},
      {Vlr("other", 2112, wkt), 1, ""},
      // A record longer than the space before the points is ignored, not read past.
      {Vlr("LASF_Projection", 2112, wkt).substr(0, 60), 1, ""},
  };
  for (const Case& c : cases) {
    const std::string path = dir.Path("crs.las");
    WriteBytes(path, LasWithVlrs(c.vlrs, c.count));
    Result<LasHeader> h = ReadLasHeader(path);
    ASSERT_TRUE(h.ok()) << h.status().message();
    EXPECT_EQ(h->crs, c.crs);
  }
}

TEST(LasReaderTest, ReadsRealPointsWithClassesAndPlausibleBounds) {
  Result<LasCloud> cloud = ReadLas(kLas);
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  ASSERT_EQ(cloud->points.size(), 73'403u);
  ASSERT_EQ(cloud->classification.size(), cloud->points.size());

  std::map<int, int> per_class;
  for (uint8_t c : cloud->classification) ++per_class[c];
  EXPECT_EQ(per_class, (std::map<int, int>{{1, 73'403 - 8'159 - 3'897}, {2, 8'159}, {9, 3'897}}));

  std::array<double, 3> lo = {1e300, 1e300, 1e300}, hi = {-1e300, -1e300, -1e300};
  for (const Point3d& p : cloud->points) {
    const double v[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], v[a]);
      hi[a] = std::max(hi[a], v[a]);
    }
  }
  // The points agree with the header bounds (to one scale step) ...
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(lo[a], cloud->header.min[a], cloud->header.scale[a]) << "axis " << a;
    EXPECT_NEAR(hi[a], cloud->header.max[a], cloud->header.scale[a]) << "axis " << a;
  }
  // ... and describe a 286 x 286 m UTM tile with tens of metres of relief.
  EXPECT_NEAR(hi[0] - lo[0], 286.0, 1.0);
  EXPECT_NEAR(hi[1] - lo[1], 286.0, 1.0);
  EXPECT_GT(lo[0], 100'000.0);
  EXPECT_LT(hi[0], 900'000.0);  // UTM eastings
  EXPECT_GT(lo[1], 5'000'000.0);
  EXPECT_GT(hi[2] - lo[2], 20.0);
  EXPECT_LT(hi[2] - lo[2], 60.0);
}

TEST(LasReaderTest, FiltersByClass) {
  Result<LasCloud> ground = ReadLas(kLas, {.classes = {2}});
  ASSERT_TRUE(ground.ok()) << ground.status().message();
  EXPECT_EQ(ground->points.size(), 8'159u);
  EXPECT_TRUE(std::all_of(ground->classification.begin(), ground->classification.end(),
                          [](uint8_t c) { return c == 2; }));
  Result<LasCloud> two = ReadLas(kLas, {.classes = {2, 9}});
  ASSERT_TRUE(two.ok());
  EXPECT_EQ(two->points.size(), 8'159u + 3'897u);
  Result<LasCloud> none = ReadLas(kLas, {.classes = {7}});
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->points.empty());
}

TEST(LasReaderTest, LocalFloatConversionKeepsPrecision) {
  Result<LasCloud> ground = ReadLas(kLas, {.classes = {2}});
  ASSERT_TRUE(ground.ok());
  const Point3d first = ground->points.front();
  const Eigen::Vector3d origin(std::floor(first.x), std::floor(first.y), 0.0);
  std::vector<Point3f> local = ToLocalFloat(ground->points, origin);
  ASSERT_EQ(local.size(), ground->points.size());
  for (size_t i = 0; i < local.size(); ++i) {
    ASSERT_NEAR(local[i].x + origin.x(), ground->points[i].x, 1e-4);
    ASSERT_NEAR(local[i].y + origin.y(), ground->points[i].y, 1e-4);
    ASSERT_NEAR(local[i].z, ground->points[i].z, 1e-4);
  }
}

// Each corrupt copy of the real file must fail with one DataLoss line naming the file.
TEST(LasReaderTest, CorruptCopiesGiveClearErrors) {
  TempDir dir;
  const std::string original = ReadBytes(kLas);
  ASSERT_EQ(original.size(), 297u + 73'403u * 28u);
  struct Case {
    std::string name;
    std::string bytes;
    std::string expected;
  };
  std::vector<Case> cases;
  cases.push_back({"truncated_points.las", original.substr(0, original.size() - 100), "truncated"});
  cases.push_back({"truncated_header.las", original.substr(0, 100), "truncated header"});
  cases.push_back({"empty.las", "", "no LASF signature"});
  std::string bad_sig = original;
  bad_sig[0] = 'X';
  cases.push_back({"bad_signature.las", bad_sig, "no LASF signature"});
  std::string laz = original;
  laz[104] = static_cast<char>(0x81);
  cases.push_back({"laz.las", laz, "LAZ"});
  std::string short_record = original;
  Put<uint16_t>(short_record, 105, 20);  // format 1 needs 28 bytes
  cases.push_back({"short_record.las", short_record, "below the 28 bytes of point format 1"});
  std::string bad_format = original;
  bad_format[104] = 11;
  cases.push_back({"bad_format.las", bad_format, "unsupported point format 11"});
  std::string bad_version = original;
  bad_version[25] = 7;
  cases.push_back({"bad_version.las", bad_version, "unsupported LAS version 1.7"});
  std::string huge_count = original;
  Put<uint32_t>(huge_count, 107, 0xFFFFFFFFu);
  cases.push_back({"huge_count.las", huge_count, "truncated: header promises 4294967295 points"});
  std::string bad_offset = original;
  Put<uint32_t>(bad_offset, 96, 100);
  cases.push_back({"bad_offset.las", bad_offset, "inside the 227-byte header"});
  std::string zero_scale = original;
  Put<double>(zero_scale, 131, 0.0);
  cases.push_back({"zero_scale.las", zero_scale, "invalid scale/offset of axis x"});

  for (const Case& c : cases) {
    const std::string path = dir.Path(c.name);
    WriteBytes(path, c.bytes);
    Result<LasCloud> cloud = ReadLas(path);
    ASSERT_FALSE(cloud.ok()) << c.name;
    EXPECT_EQ(cloud.status().code(), Status::Code::kDataLoss) << c.name;
    const std::string& msg = cloud.status().message();
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(c.expected), std::string::npos) << msg << " lacks " << c.expected;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
  EXPECT_EQ(ReadLas(dir.Path("missing.las")).status().code(), Status::Code::kIoError);
}

// A LAS 1.4 file in point format 6 (64-bit count, full classification byte at offset 16, extra
// bytes per record), written by hand.
TEST(LasReaderTest, ReadsLas14Format6) {
  TempDir dir;
  const uint16_t record = 30 + 4;    // 4 extra bytes
  const uint32_t offset = 375 + 10;  // 10 bytes of "VLR" padding
  const int n = 3;
  std::string bytes(offset + n * record, '\0');
  std::memcpy(bytes.data(), "LASF", 4);
  bytes[24] = 1;
  bytes[25] = 4;
  Put<uint16_t>(bytes, 94, 375);
  Put<uint32_t>(bytes, 96, offset);
  bytes[104] = 6;
  Put<uint16_t>(bytes, 105, record);
  Put<uint32_t>(bytes, 107, 0);  // legacy count is 0 for formats 6-10
  const double scale[3] = {0.01, 0.01, 0.001}, off[3] = {500000.0, 4000000.0, 0.0};
  for (int a = 0; a < 3; ++a) {
    Put<double>(bytes, 131 + 8 * a, scale[a]);
    Put<double>(bytes, 155 + 8 * a, off[a]);
  }
  Put<uint64_t>(bytes, 247, n);
  const int32_t xyz[n][3] = {{100, -200, 1500}, {0, 0, 0}, {-7, 8, -9}};
  const uint8_t cls[n] = {2, 40, 2};
  for (int i = 0; i < n; ++i) {
    const size_t at = offset + i * record;
    for (int a = 0; a < 3; ++a) Put<int32_t>(bytes, at + 4 * a, xyz[i][a]);
    bytes[at + 15] = static_cast<char>(0xFF);  // flags must not leak into the class
    bytes[at + 16] = static_cast<char>(cls[i]);
  }
  const std::string path = dir.Path("v14.las");
  WriteBytes(path, bytes);

  Result<LasCloud> cloud = ReadLas(path);
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  EXPECT_EQ(cloud->header.point_count, 3u);
  ASSERT_EQ(cloud->points.size(), 3u);
  EXPECT_EQ(cloud->classification, (std::vector<uint8_t>{2, 40, 2}));
  EXPECT_DOUBLE_EQ(cloud->points[0].x, 500001.0);
  EXPECT_DOUBLE_EQ(cloud->points[0].y, 3999998.0);
  EXPECT_DOUBLE_EQ(cloud->points[0].z, 1.5);
  EXPECT_DOUBLE_EQ(cloud->points[2].x, 500000.0 - 0.07);

  Result<LasCloud> ground = ReadLas(path, {.classes = {2}});
  ASSERT_TRUE(ground.ok());
  EXPECT_EQ(ground->points.size(), 2u);

  // One point fewer on disk than the 64-bit count promises.
  WriteBytes(path, bytes.substr(0, bytes.size() - 1));
  Result<LasCloud> truncated = ReadLas(path);
  ASSERT_FALSE(truncated.ok());
  EXPECT_NE(truncated.status().message().find("truncated"), std::string::npos);
}

// Format 0-5 classification is the low 5 bits; the high 3 are flags (synthetic, key, withheld).
TEST(LasReaderTest, LegacyFormatsMaskClassificationFlags) {
  TempDir dir;
  std::string bytes = ReadBytes(kLas).substr(0, 297 + 28);
  Put<uint32_t>(bytes, 107, 1);
  bytes[297 + 15] = static_cast<char>(0x80 | 2);  // withheld ground point
  const std::string path = dir.Path("one.las");
  WriteBytes(path, bytes);
  Result<LasCloud> cloud = ReadLas(path, {.classes = {2}});
  ASSERT_TRUE(cloud.ok()) << cloud.status().message();
  ASSERT_EQ(cloud->points.size(), 1u);
  EXPECT_EQ(cloud->classification[0], 2);
}

}  // namespace
}  // namespace bgkmap::io
