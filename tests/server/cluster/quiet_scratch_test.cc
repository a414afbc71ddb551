// A cluster shard's log reader hands its engine scratch back after a quiet spell
// (cluster/quiet_scratch.h), once per spell, and keeps it while scans keep coming.
#include "cluster/quiet_scratch.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <thread>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/core/thread_scratch.h"

namespace bgkmap {
namespace {

using Clock = QuietScratch::Clock;
using std::chrono::milliseconds;

// A dense ring of ground around a sensor 1.2 m up: enough to fill the per-thread buffers.
void IntegrateAScan(TerrainMap& map) {
  std::vector<Point3f> points;
  for (int i = 0; i < 40000; ++i) {
    const double a = i * 0.0137, r = 1.0 + (i % 400) * 0.02;
    points.push_back({static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a)),
                      static_cast<float>(-1.2 + 0.02 * std::sin(3 * a))});
  }
  Pose pose;
  ASSERT_TRUE(map.IntegrateScan(points, pose).ok());
}

TEST(QuietScratchTest, ReleasesOncePerQuietSpellOnItsOwnThread) {
  // On a thread of its own: its buffers are this test's alone.
  std::thread([] {
    MapParams params;
    params.resolution = 0.1;
    std::unique_ptr<TerrainMap> made = std::move(TerrainMap::Create(params)).value();
    TerrainMap& map = *made;
    QuietScratch scratch(milliseconds(2000));
    const Clock::time_point t0 = Clock::now();

    EXPECT_FALSE(scratch.Quiet(t0 + milliseconds(5000))) << "nothing worked yet";
    IntegrateAScan(map);
    scratch.Worked(t0);
    ASSERT_GT(ThreadScratchBytes(), 0u);
    EXPECT_FALSE(scratch.Quiet(t0 + milliseconds(1999)));
    EXPECT_GT(ThreadScratchBytes(), 0u) << "released before the spell was long enough";
    EXPECT_TRUE(scratch.Quiet(t0 + milliseconds(2000)));
    EXPECT_EQ(ThreadScratchBytes(), 0u);
    EXPECT_FALSE(scratch.Quiet(t0 + milliseconds(9000))) << "one release per spell";

    // Scans again: warm, and released again after the next spell.
    IntegrateAScan(map);
    scratch.Worked(t0 + milliseconds(10000));
    EXPECT_FALSE(scratch.Quiet(t0 + milliseconds(11000)));
    EXPECT_GT(ThreadScratchBytes(), 0u);
    EXPECT_TRUE(scratch.Quiet(t0 + milliseconds(12000)));
    EXPECT_EQ(ThreadScratchBytes(), 0u);
  }).join();
}

TEST(QuietScratchTest, WorkKeepsPushingTheReleaseBack) {
  int releases = 0;
  QuietScratch scratch(milliseconds(100), [&] { ++releases; });
  const Clock::time_point t0 = Clock::now();
  for (int i = 0; i < 50; ++i) {
    scratch.Worked(t0 + milliseconds(50 * i));
    EXPECT_FALSE(scratch.Quiet(t0 + milliseconds(50 * i + 99)));
  }
  EXPECT_EQ(releases, 0);
  EXPECT_TRUE(scratch.Quiet(t0 + milliseconds(50 * 49 + 100)));
  EXPECT_EQ(releases, 1);
}

}  // namespace
}  // namespace bgkmap
