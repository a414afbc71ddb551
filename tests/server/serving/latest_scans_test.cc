// LatestScans, what the Foxglove port reads of the robots: bounded in robots and in points,
// newest sequence kept, listeners told.
#include "serving/latest_scans.h"

#include <gtest/gtest.h>

#include <vector>

namespace bgkmap {
namespace {

std::vector<Point3f> Points(size_t n) {
  std::vector<Point3f> p(n);
  for (size_t i = 0; i < n; ++i) p[i] = {static_cast<float>(i), 0, 0};
  return p;
}

TEST(LatestScansTest, ThinningKeepsEveryKthPointWithinTheBound) {
  const std::vector<Point3f> p = Points(10);
  std::vector<Point3f> kept = ThinPoints(p, 4);  // step 3: 0, 3, 6, 9
  ASSERT_EQ(kept.size(), 4u);
  EXPECT_EQ(kept[1].x, 3.0f);
  EXPECT_EQ(kept[3].x, 9.0f);
  EXPECT_EQ(ThinPoints(p, 10).size(), 10u);  // within the bound: all, unchanged
  EXPECT_EQ(ThinPoints(p, 0).size(), 0u);
  for (size_t bound = 1; bound <= 12; ++bound) EXPECT_LE(ThinPoints(p, bound).size(), bound);
}

TEST(LatestScansTest, KeepsTheNewestScanOfEachRobotAndEvictsTheLeastRecent) {
  LatestScans scans(2, 100);
  std::vector<std::string> told;
  scans.Listen([&told](const std::string& robot) { told.push_back(robot); });
  Pose pose;
  pose.translation = {1, 2, 3};
  scans.Record("a", 5, {10, 0}, pose, Points(3));
  scans.Record("a", 4, {9, 0}, Pose{}, Points(1));  // older: ignored
  ASSERT_NE(scans.Find("a"), nullptr);
  EXPECT_EQ(scans.Find("a")->sequence, 5u);
  EXPECT_EQ(scans.Find("a")->pose.translation.y(), 2.0);
  EXPECT_EQ(scans.Find("a")->points.size(), 3u);
  scans.Record("b", 1, {}, Pose{}, Points(1000));
  EXPECT_EQ(scans.Find("b")->points.size(), 100u);  // thinned to the bound
  EXPECT_EQ(scans.Find("b")->points_sent, 1000u);
  scans.Record("a", 6, {}, Pose{}, Points(1));  // a is now the most recent
  scans.Record("c", 1, {}, Pose{}, Points(1));  // evicts b, the least recently updated
  ASSERT_EQ(scans.All().size(), 2u);
  EXPECT_EQ(scans.All()[0]->robot_id, "a");
  EXPECT_EQ(scans.All()[1]->robot_id, "c");
  EXPECT_EQ(scans.Find("b"), nullptr);
  EXPECT_EQ(told, (std::vector<std::string>{"a", "b", "a", "c"}));  // not the ignored one
}

}  // namespace
}  // namespace bgkmap
