// The ingest stream's encode pipeline (client/src/encode_pipeline.h) without a server: scans are
// written in the order submitted whatever the encoders' timing, never more than `ahead` are
// waiting, and after a failed write nothing more is written and Submit() says so; a stream's
// order hint tries both orders on its first scan and every 16th, and keeps the winner between.
#include "encode_pipeline.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <mutex>
#include <vector>

#include "bgkmap/proto/compact_points.h"
#include "bgkmap/proto/scan_codec.h"

namespace bgkmap::client_codec {
namespace {

// Scan i has a size that varies a lot from one to the next, so that encoders finish out of order.
std::vector<Point3f> PointsOf(uint64_t i) {
  const size_t n = (i % 3 == 0) ? 40000 : 50 + 7 * i;
  std::vector<Point3f> points(n);
  for (size_t k = 0; k < n; ++k) {
    const double a = 0.001 * static_cast<double>(k);
    points[k] = {static_cast<float>(5 * std::cos(a)), static_cast<float>(5 * std::sin(a)),
                 static_cast<float>(0.01 * static_cast<double>(i))};
  }
  return points;
}

ScanEncoding Compact() {
  ScanEncoding e;
  e.step = kDefaultCompactStep;
  return e;
}

TEST(EncodePipelineTest, WritesInSubmissionOrderWithAtMostAheadWaiting) {
  constexpr int kAhead = 3;
  constexpr uint64_t kScans = 40;
  std::mutex mu;
  std::vector<uint64_t> written;
  std::vector<uint32_t> counts;
  std::atomic<uint64_t> submitted{0};
  bool never_too_far_ahead = true;
  EncodePipeline pipeline(Compact(), 3, kAhead, [&](EncodedScan& s) {
    std::lock_guard lock(mu);
    // The scan being written still counts among the `ahead` ones.
    never_too_far_ahead &= submitted.load() <= written.size() + kAhead;
    written.push_back(s.sequence);
    counts.push_back(s.message.compact_points().count());
    return true;
  });
  for (uint64_t i = 1; i <= kScans; ++i) {
    const std::vector<Point3f> points = PointsOf(i);
    ScanData scan;
    scan.robot_id = "r";
    scan.sequence = i;
    scan.points = points;  // freed right after Submit: the pipeline keeps its own copy
    ASSERT_TRUE(pipeline.Submit(scan));
    ++submitted;
  }
  pipeline.Close();
  EXPECT_FALSE(pipeline.broken());
  ASSERT_EQ(written.size(), kScans);
  for (uint64_t i = 1; i <= kScans; ++i) {
    EXPECT_EQ(written[i - 1], i);
    EXPECT_EQ(counts[i - 1], PointsOf(i).size()) << "scan " << i;
  }
  EXPECT_TRUE(never_too_far_ahead);
  ScanData late;
  late.sequence = kScans + 1;
  EXPECT_FALSE(pipeline.Submit(late)) << "submitted after Close()";
}

TEST(EncodePipelineTest, AfterAFailedWriteNothingMoreIsWrittenAndSubmitSaysSo) {
  constexpr int kAhead = 4;
  constexpr uint64_t kFailing = 5;
  std::mutex mu;
  std::vector<uint64_t> written;
  EncodePipeline pipeline(Compact(), 2, kAhead, [&](EncodedScan& s) {
    std::lock_guard lock(mu);
    written.push_back(s.sequence);
    return s.sequence != kFailing;
  });
  uint64_t accepted = 0;
  for (uint64_t i = 1; i <= 100; ++i) {
    const std::vector<Point3f> points = PointsOf(i);
    ScanData scan;
    scan.sequence = i;
    scan.points = points;
    if (!pipeline.Submit(scan)) break;
    ++accepted;
  }
  pipeline.Close();
  EXPECT_TRUE(pipeline.broken());
  // Submit() noticed within `ahead` scans of the failing one.
  EXPECT_GE(accepted, kFailing);
  EXPECT_LE(accepted, kFailing + kAhead);
  const std::vector<uint64_t> expected{1, 2, 3, 4, 5};
  EXPECT_EQ(written, expected);
}

TEST(EncodePipelineTest, Float32ScansKeepTheirBytes) {
  ScanEncoding raw;  // step 0: packed float32
  std::vector<std::string> bytes;
  EncodePipeline pipeline(raw, 2, 2, [&](EncodedScan& s) {
    bytes.push_back(s.message.points());
    EXPECT_FALSE(s.message.has_compact_points());
    return true;
  });
  for (uint64_t i = 1; i <= 6; ++i) {
    const std::vector<Point3f> points = PointsOf(i);
    ScanData scan;
    scan.sequence = i;
    scan.points = points;
    ASSERT_TRUE(pipeline.Submit(scan));
  }
  pipeline.Close();
  ASSERT_EQ(bytes.size(), 6u);
  for (uint64_t i = 1; i <= 6; ++i) {
    const std::vector<Point3f> points = PointsOf(i);
    ASSERT_EQ(bytes[i - 1].size(), points.size() * sizeof(Point3f));
    EXPECT_EQ(std::memcmp(bytes[i - 1].data(), points.data(), bytes[i - 1].size()), 0);
  }
}

TEST(OrderHintTest, ProbesTheFirstScanAndEverySixteenthAndOtherwiseKeepsTheWinner) {
  OrderHint hint;
  EXPECT_FALSE(hint.For(0).has_value());
  EXPECT_FALSE(hint.For(1).has_value()) << "nothing learnt yet: try both";
  hint.Learn(PointOrder::kSpatialSort);
  EXPECT_EQ(hint.For(1), PointOrder::kSpatialSort);
  EXPECT_EQ(hint.For(15), PointOrder::kSpatialSort);
  EXPECT_FALSE(hint.For(OrderHint::kProbeEvery).has_value());
  hint.Learn(PointOrder::kScanRay);
  EXPECT_EQ(hint.For(OrderHint::kProbeEvery + 1), PointOrder::kScanRay);
}

TEST(OrderHintTest, AHintedScanDecodesToTheSamePointsAsOneThatTriedBoth) {
  const std::vector<Point3f> points = PointsOf(3);
  ScanData scan;
  scan.points = points;
  OrderHint hint;
  v1::Scan probed, hinted;
  EncodeHinted(scan, 0, Compact(), &hint, &probed);
  ASSERT_TRUE(hint.For(1).has_value());
  EXPECT_EQ(FromProto(probed.compact_points()).order, *hint.For(1));
  EncodeHinted(scan, 1, Compact(), &hint, &hinted);
  EXPECT_EQ(hinted.compact_points().SerializeAsString(),
            probed.compact_points().SerializeAsString());
}

}  // namespace
}  // namespace bgkmap::client_codec
