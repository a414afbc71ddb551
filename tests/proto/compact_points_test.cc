// The compact point encoding (proto/codec's compact_points.h): every order decodes to exactly the
// dequantized points (the scan orders in order, the spatial sort as the same multiset), on a real
// Ouster scan, on edge values and on random walks with jumps that overflow the ray's residuals;
// every malformed payload is refused with a message naming the fault, before anything is inflated
// where the count already tells.
#include "bgkmap/proto/compact_points.h"

#include <gtest/gtest.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

namespace bgkmap {
namespace {

constexpr double kStep = kDefaultCompactStep;

// The rule every decoder must follow: round to the step, then float(double(q) * step).
Point3f Expected(const Point3f& p, double step) {
  return {Dequantize(std::llround(p.x / step), step), Dequantize(std::llround(p.y / step), step),
          Dequantize(std::llround(p.z / step), step)};
}

bool BitEqual(const Point3f& a, const Point3f& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

std::vector<Point3f> OusterScan() {
  std::ifstream in(std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street/velodyne/000000.bin",
                   std::ios::binary);
  std::vector<Point3f> points;
  float xyzi[4];
  while (in.read(reinterpret_cast<char*>(xyzi), sizeof xyzi)) {
    points.push_back({xyzi[0], xyzi[1], xyzi[2]});
  }
  return points;
}

std::vector<Point3f> Sorted(std::vector<Point3f> p) {
  std::sort(p.begin(), p.end(), [](const Point3f& a, const Point3f& b) {
    return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
  });
  return p;
}

std::string Zstd(const std::string& raw) {
  std::string out(ZSTD_compressBound(raw.size()), '\0');
  out.resize(ZSTD_compress(out.data(), out.size(), raw.data(), raw.size(), 1));
  return out;
}

TEST(CompactPointsTest, TheScanOrderDecodesToTheDequantizedPointsInOrder) {
  const std::vector<Point3f> scan = OusterScan();
  ASSERT_GT(scan.size(), 100000u) << "needs ../shared/data/ouster_os1_128_street";
  Result<CompactPoints> compact = EncodeCompactPoints(scan, kStep, nullptr, PointOrder::kScanOrder);
  ASSERT_TRUE(compact.ok()) << compact.status().ToString();
  EXPECT_EQ(compact->order, PointOrder::kScanOrder);
  EXPECT_LT(compact->data.size(), scan.size() * 12 / 3);  // what zstd of the deltas buys
  Result<std::vector<Point3f>> decoded = DecodeCompactPoints(*compact, scan.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  ASSERT_EQ(decoded->size(), scan.size());
  for (size_t i = 0; i < scan.size(); ++i) {
    ASSERT_TRUE(BitEqual((*decoded)[i], Expected(scan[i], kStep))) << "point " << i;
    ASSERT_LE(std::abs((*decoded)[i].x - scan[i].x), kStep / 2 + 1e-6);
  }
}

// Along the rays: the same points in the same order, and (what it is for) smaller than the plain
// differences on a real spinning lidar's sweep. Mutation caught: the decoder leaving out the
// ray's correction (the points come back off the ray).
TEST(CompactPointsTest, TheScanRayDecodesToTheDequantizedPointsInOrderAndIsSmaller) {
  const std::vector<Point3f> scan = OusterScan();
  ASSERT_GT(scan.size(), 100000u) << "needs ../shared/data/ouster_os1_128_street";
  Result<CompactPoints> ray = EncodeCompactPoints(scan, kStep, nullptr, PointOrder::kScanRay);
  Result<CompactPoints> plain = EncodeCompactPoints(scan, kStep, nullptr, PointOrder::kScanOrder);
  ASSERT_TRUE(ray.ok() && plain.ok());
  EXPECT_EQ(ray->order, PointOrder::kScanRay);
  // Measured: 206 kB against 295 kB (scan 0 of the Ouster street).
  EXPECT_LT(ray->data.size(), plain->data.size() * 4 / 5);
  Result<CompactPoints> chosen = EncodeCompactPoints(scan, kStep);
  ASSERT_TRUE(chosen.ok());
  EXPECT_EQ(chosen->order, PointOrder::kScanRay);
  Result<std::vector<Point3f>> decoded = DecodeCompactPoints(*ray, scan.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  ASSERT_EQ(decoded->size(), scan.size());
  for (size_t i = 0; i < scan.size(); ++i) {
    ASSERT_TRUE(BitEqual((*decoded)[i], Expected(scan[i], kStep))) << "point " << i;
  }
}

// Random walks with jumps across the whole quantized range, negative coordinates and zeros on the
// ray's axis: every order the encoder picks decodes to the same points (in order where it keeps
// it), and where a ray residual would not fit int32 the plain scan order takes the points.
TEST(CompactPointsTest, RandomWalksWithJumpsRoundTripInEveryOrder) {
  uint64_t state = 88172645463325252ULL;
  const auto next = [&state] {  // xorshift64: the same walks on every machine
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    return state;
  };
  const int64_t limit = (int64_t{1} << 30) - 1;
  for (int walk = 0; walk < 40; ++walk) {
    std::vector<QuantizedPoint> points(2000);
    int64_t q[3] = {0, 0, 0};
    for (QuantizedPoint& p : points) {
      for (int c = 0; c < 3; ++c) {
        const uint64_t r = next();
        if (r % 97 == 0) {
          q[c] = static_cast<int64_t>(next() % (2 * limit + 1)) - limit;  // a jump anywhere
        } else if (r % 89 == 0) {
          q[c] = 0;
        } else {
          q[c] = std::clamp<int64_t>(q[c] + static_cast<int64_t>(r % 2001) - 1000, -limit, limit);
        }
        p.q[c] = q[c];
      }
    }
    if (walk % 2 == 1) {  // the overflow case: alternating extremes
      for (size_t i = 0; i < 6; ++i) points[i].q[0] = i % 2 == 0 ? limit : -limit;
    }
    for (std::optional<PointOrder> order :
         {std::optional<PointOrder>(), {PointOrder::kScanRay}, {PointOrder::kScanOrder}}) {
      Result<CompactPoints> compact = EncodeQuantizedPoints(points, kStep, order);
      ASSERT_TRUE(compact.ok());
      if (walk % 2 == 1) {
        EXPECT_EQ(compact->order, PointOrder::kScanOrder) << walk;
      }
      Result<std::vector<Point3f>> decoded = DecodeCompactPoints(*compact, points.size());
      ASSERT_TRUE(decoded.ok()) << walk << ": " << decoded.status().ToString();
      ASSERT_EQ(decoded->size(), points.size());
      for (size_t i = 0; i < points.size(); ++i) {
        ASSERT_TRUE(BitEqual((*decoded)[i], DequantizePoint(points[i], kStep)))
            << "walk " << walk << " point " << i;
      }
    }
  }
}

TEST(CompactPointsTest, TheSpatialSortDecodesToTheSameMultisetAndItsOwnOrderAgain) {
  const std::vector<Point3f> scan = OusterScan();
  ASSERT_FALSE(scan.empty());
  Result<CompactPoints> compact =
      EncodeCompactPoints(scan, kStep, nullptr, PointOrder::kSpatialSort);
  ASSERT_TRUE(compact.ok());
  EXPECT_EQ(compact->order, PointOrder::kSpatialSort);
  Result<std::vector<Point3f>> decoded = DecodeCompactPoints(*compact, scan.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  std::vector<Point3f> expected;
  for (const Point3f& p : scan) expected.push_back(Expected(p, kStep));
  const std::vector<Point3f> a = Sorted(*decoded), b = Sorted(expected);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) ASSERT_TRUE(BitEqual(a[i], b[i])) << i;
  // Encoding the decoded points again gives the same points in the same order: what a store
  // that keeps the compact form relies on.
  Result<CompactPoints> again = EncodeCompactPoints(*decoded, kStep);
  ASSERT_TRUE(again.ok());
  Result<std::vector<Point3f>> twice = DecodeCompactPoints(*again, scan.size());
  ASSERT_TRUE(twice.ok());
  for (size_t i = 0; i < decoded->size(); ++i) {
    ASSERT_TRUE(BitEqual((*twice)[i], (*decoded)[i])) << i;
  }
}

TEST(CompactPointsTest, EdgeValuesAndUnquantizablePoints) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<Point3f> points = {{0, 0, 0},
                                       {-0.001f, 0.001f, 0.003f},
                                       {2000.f, -2000.f, 1.f},  // |q| = 10^6 < 2^20
                                       {nan, 1, 1},
                                       {1, inf, 1},
                                       {3e6f, 0, 0},     // 3e6 / 0.002 > 2^30
                                       {5000.f, 0, 0}};  // only the scan order
  uint64_t skipped = 0;
  Result<CompactPoints> compact = EncodeCompactPoints(points, kStep, &skipped);
  ASSERT_TRUE(compact.ok());
  EXPECT_EQ(skipped, 3u);
  EXPECT_EQ(compact->count, 4u);
  EXPECT_EQ(compact->order, PointOrder::kScanRay);  // 5000 m does not fit the Morton key
  Result<std::vector<Point3f>> decoded = DecodeCompactPoints(*compact, 100);
  ASSERT_TRUE(decoded.ok());
  const std::vector<Point3f> kept = {points[0], points[1], points[2], points[6]};
  ASSERT_EQ(decoded->size(), kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    EXPECT_TRUE(BitEqual((*decoded)[i], Expected(kept[i], kStep))) << i;
  }
  // Nothing to send is a valid scan of no points.
  Result<CompactPoints> empty = EncodeCompactPoints({}, kStep);
  ASSERT_TRUE(empty.ok());
  EXPECT_TRUE(DecodeCompactPoints(*empty, 0).ok());
  EXPECT_FALSE(EncodeCompactPoints(points, 0.0).ok());
}

TEST(CompactPointsTest, AMalformedPayloadIsRefusedNamingTheFault) {
  std::vector<Point3f> points;
  for (int i = 0; i < 500; ++i) points.push_back({0.01f * i, 1.f, -1.5f});
  const CompactPoints good = *EncodeCompactPoints(points, kStep, nullptr, PointOrder::kScanOrder);
  const auto fault = [](CompactPoints c, uint64_t max = 1000) {
    Result<std::vector<Point3f>> r = DecodeCompactPoints(c, max);
    return r.ok() ? std::string("accepted") : r.status().message();
  };
  for (double step :
       {0.0, -0.002, 0.0100001, std::nan(""), std::numeric_limits<double>::infinity()}) {
    CompactPoints c = good;
    c.step = step;
    EXPECT_EQ(fault(c).rfind("compact_points.step: ", 0), 0u) << step;
  }
  CompactPoints truncated = good;
  truncated.data.resize(good.data.size() / 2);
  EXPECT_NE(fault(truncated).find("compact_points.data: "), std::string::npos);
  EXPECT_EQ(fault(good, 499), "compact_points.count: 500 points exceed the limit of 499");
  CompactPoints fewer = good;  // the frame holds more points than count says
  fewer.count = 100;
  EXPECT_EQ(fault(fewer),
            "compact_points.data: inflates to 6000 bytes, more than count allows (1200)");
  CompactPoints more = good;  // ... or fewer
  more.count = 501;
  EXPECT_EQ(fault(more), "compact_points.data: inflates to 6000 bytes, not 12 x count = 6012");
  CompactPoints garbage = good;
  garbage.data = "not zstd at all";
  EXPECT_EQ(fault(garbage), "compact_points.data: not a zstd frame");
  CompactPoints order = good;
  order.order = static_cast<PointOrder>(7);
  EXPECT_EQ(fault(order), "compact_points.order: 7 is unknown");
  // A delta walking out of |q| < 2^30: zigzag(2^31 - 1) twice on x.
  std::string planes(24, '\0');
  for (int b = 0; b < 4; ++b) planes[b * 3 * 2] = planes[b * 3 * 2 + 1] = '\xff';
  planes[3 * 3 * 2] = planes[3 * 3 * 2 + 1] = '\x7f';
  CompactPoints far{kStep, 2, PointOrder::kScanOrder, Zstd(planes)};
  EXPECT_EQ(fault(far), "compact_points.data: point 0 leaves the quantized range |q| < 2^30");
  // Along the rays: a residual walking out of |q| < 2^30 (the same planes).
  CompactPoints far_ray{kStep, 2, PointOrder::kScanRay, Zstd(planes)};
  EXPECT_EQ(fault(far_ray), "compact_points.data: point 0 leaves the quantized range |q| < 2^30");
  CompactPoints short_ray{kStep, 3, PointOrder::kScanRay, Zstd(planes)};
  EXPECT_EQ(fault(short_ray), "compact_points.data: inflates to 24 bytes, not 12 x count = 36");
  // The spatial sort: trailing bytes, and a key over 63 bits.
  CompactPoints trailing{kStep, 1, PointOrder::kSpatialSort, Zstd(std::string("\x05\x05", 2))};
  EXPECT_EQ(fault(trailing), "compact_points.data: 1 bytes after the last of count keys");
  CompactPoints wide{kStep, 1, PointOrder::kSpatialSort,
                     Zstd(std::string(9, '\xff') + std::string("\x01", 1))};
  EXPECT_EQ(fault(wide), "compact_points.data: key 0 exceeds 63 bits");
  CompactPoints cut{kStep, 2, PointOrder::kSpatialSort, Zstd(std::string("\x05", 1))};
  EXPECT_EQ(fault(cut), "compact_points.data: key 1 is truncated or over 64 bits");
}

}  // namespace
}  // namespace bgkmap
