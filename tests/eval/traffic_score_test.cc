// Trails and new obstacles of moving vehicles (eval/traffic_score.h), on a hand-made vehicle
// moving 1 m per scan over ground that is traversable except where the truth says otherwise:
// which cells are judged when, and what counts as stale or missed on hand-filled maps. Mutation
// checked by hand: a trail judged one scan late fails the first two tests.
#include "bgkmap/eval/traffic_score.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace bgkmap::eval {
namespace {

using CellSet = std::vector<CellIndex>;

CellSet Minus(const CellSet& a, const CellSet& b) {
  CellSet out;
  std::set_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(out));
  return out;
}

class TrafficScoreTest : public ::testing::Test {
 protected:
  TrafficScoreTest() : geometry_(params_.resolution, params_.tile_size) {
    // A 1 x 1 m vehicle moving +1 m per scan along x for 6 scans.
    track_.first_scan = 0;
    for (int k = 0; k < kScans; ++k) track_.boxes.push_back({1.0 * k, 0.0, 1.0 * k + 1, 1.0});
    for (int k = 0; k < kScans; ++k) {
      occupied_.push_back(CellsNearBox(geometry_, track_.boxes[k], params_.robot_radius));
      std::sort(occupied_.back().begin(), occupied_.back().end());
    }
    // The truth without the vehicle: traversable over [-5, 15] x [-5, 5] m.
    truth_.box = geometry_.CellsOfRegion(-5, -5, 15, 5);
    truth_.cols = truth_.box.width();
    truth_.rows = truth_.box.height();
    truth_.resolution = params_.resolution;
    truth_.layers = {Layer::kState};
    truth_.data = {
        std::vector<float>(truth_.cols * truth_.rows, static_cast<float>(CellState::kTraversable))};
    // Every scan sees every cell of the truth's box.
    CellSet all;
    for (int y = truth_.box.min.y; y <= truth_.box.max.y; ++y)
      for (int x = truth_.box.min.x; x <= truth_.box.max.x; ++x) all.push_back({x, y});
    std::sort(all.begin(), all.end());
    observed_.assign(kScans, all);
  }

  void SetTruth(CellIndex c, CellState s) {
    const size_t k =
        static_cast<size_t>(truth_.box.max.y - c.y) * truth_.cols + (c.x - truth_.box.min.x);
    truth_.data[0][k] = static_cast<float>(s);
  }

  // A map in which `blocked` cells are non-traversable and every other cell of the truth's box
  // traversable.
  std::unique_ptr<TerrainMap> MapWith(const CellSet& blocked) const {
    std::unique_ptr<TerrainMap> map = std::move(TerrainMap::Create(params_)).value();
    for (int y = truth_.box.min.y; y <= truth_.box.max.y; ++y) {
      for (int x = truth_.box.min.x; x <= truth_.box.max.x; ++x) {
        const CellIndex c{x, y};
        Tile& t = map->GetOrCreateTile(geometry_.TileOf(c));
        const int i = geometry_.LocalIndex(c);
        const bool b = std::binary_search(blocked.begin(), blocked.end(), c);
        t.w()[i] = 10.0;
        t.a()[i] = b ? 9.5f : 0.5f;
        t.b()[i] = b ? 0.5f : 9.5f;
      }
    }
    return map;
  }

  static constexpr int kScans = 6;
  MapParams params_;
  GridGeometry geometry_;
  VehicleTrack track_;
  std::vector<CellSet> occupied_;
  Raster truth_;
  std::vector<CellSet> observed_;
};

TEST_F(TrafficScoreTest, TrailsAreJudgedAfterTheirScansAndNewCellsAtOnce) {
  const TrafficJudge judge(params_, {track_}, kScans, truth_, observed_, /*trail_scans=*/2,
                           /*new_scans=*/1);
  // Left at k (occupied at k - 1, not at k) and judged on the map after k + 1; entered at k and
  // judged on the map after k.
  EXPECT_EQ(judge.DueAt(0), 0u);
  EXPECT_EQ(judge.DueAt(1), Minus(occupied_[1], occupied_[0]).size());
  for (int k = 2; k < kScans; ++k) {
    EXPECT_EQ(judge.DueAt(k), Minus(occupied_[k - 1], occupied_[k]).size() +
                                  Minus(occupied_[k], occupied_[k - 1]).size())
        << k;
  }
  EXPECT_GT(judge.DueAt(3), 10u);
  EXPECT_TRUE(judge.Occupied(2, {25, 5}));  // (2.55, 0.55) inside the box of scan 2
  EXPECT_FALSE(judge.Occupied(2, {5, 5}));  // left at scan 1 and 2
  EXPECT_TRUE(judge.Near(2, {15, 5}));      // 0.45 m behind: within robot radius + l
  EXPECT_FALSE(judge.Near(2, {13, 5}));     // 0.65 m behind
}

TEST_F(TrafficScoreTest, StaleAndMissedAgainstTheMap) {
  TrafficJudge judge(params_, {track_}, kScans, truth_, observed_, 2, 1);
  // Map: the trail left at scan 1 still blocked; of the cells entered at scan 3, only the
  // vehicle's own footprint shown.
  const CellSet left_at_1 = Minus(occupied_[0], occupied_[1]);
  const CellSet entered_at_3 = Minus(occupied_[3], occupied_[2]);
  CellSet shown;
  for (const CellIndex& c : entered_at_3) {
    if (c.y >= 0 && c.y < 10) shown.push_back(c);  // inside y in [0, 1)
  }
  CellSet blocked = left_at_1;
  blocked.insert(blocked.end(), shown.begin(), shown.end());
  std::sort(blocked.begin(), blocked.end());
  // That map after scans 2 and 3 (where those cells are due), one blocking nothing otherwise.
  const std::unique_ptr<TerrainMap> map = MapWith(blocked), clear = MapWith({});
  for (int k = 0; k < kScans; ++k) judge.Score(k, k == 2 || k == 3 ? *map : *clear);
  const TrafficCounts& c = judge.counts();
  EXPECT_EQ(c.trail_stale, static_cast<int64_t>(left_at_1.size()));  // judged after scan 2
  EXPECT_EQ(c.stale_mean, c.trail_stale);  // blocked by their Beta mean (9.5 of 10)
  EXPECT_EQ(c.stale_no_value + c.stale_variance + c.stale_disagreement, 0);
  int64_t trails = 0, news = 0;
  for (int k = 1; k + 1 < kScans; ++k) trails += Minus(occupied_[k - 1], occupied_[k]).size();
  for (int k = 1; k < kScans; ++k) news += Minus(occupied_[k], occupied_[k - 1]).size();
  EXPECT_EQ(c.trail_judged, trails);
  EXPECT_EQ(c.new_judged, news);
  EXPECT_EQ(c.new_missed, news - static_cast<int64_t>(shown.size()));
  EXPECT_EQ(c.new_unknown, 0);
  EXPECT_NEAR(c.stale_rate(), static_cast<double>(left_at_1.size()) / trails, 1e-12);
}

TEST_F(TrafficScoreTest, EachVehicleHasItsShare) {
  // A second vehicle 3 m beside the first, standing still from scan 2 on: it enters its cells
  // once and leaves none. The trail left at scan 1 stays blocked, as above.
  VehicleTrack parked;
  parked.first_scan = 2;
  for (int k = 2; k < kScans; ++k) parked.boxes.push_back({0.0, 3.0, 1.0, 4.0});
  TrafficJudge judge(params_, {track_, parked}, kScans, truth_, observed_, 2, 1);
  const CellSet left_at_1 = Minus(occupied_[0], occupied_[1]);
  const std::unique_ptr<TerrainMap> map = MapWith(left_at_1), clear = MapWith({});
  for (int k = 0; k < kScans; ++k) judge.Score(k, k == 2 ? *map : *clear);
  const TrafficCounts& c = judge.counts();
  ASSERT_EQ(c.by_vehicle.size(), 2u);
  const VehicleCounts &moving = c.by_vehicle[0], &standing = c.by_vehicle[1];
  EXPECT_EQ(moving.trail_stale, static_cast<int64_t>(left_at_1.size()));
  EXPECT_EQ(moving.trail_judged, c.trail_judged);
  EXPECT_EQ(standing.trail_judged, 0);
  EXPECT_TRUE(std::isnan(standing.stale_rate()));
  EXPECT_EQ(
      standing.new_judged,
      static_cast<int64_t>(CellsNearBox(geometry_, parked.boxes[0], params_.robot_radius).size()));
  EXPECT_EQ(standing.new_missed, standing.new_judged);  // the clear map shows none of it
  EXPECT_EQ(moving.new_judged + standing.new_judged, c.new_judged);
  EXPECT_EQ(moving.new_missed + standing.new_missed, c.new_missed);
}

TEST_F(TrafficScoreTest, OnlyCellsTheTruthCallsTraversableAndAScanSawAreJudged) {
  const CellSet left_at_1 = Minus(occupied_[0], occupied_[1]);
  SetTruth(left_at_1.front(), CellState::kNonTraversable);  // a kerb there anyway
  observed_[1].clear();                                     // scans 1 and 2 see nothing
  observed_[2].clear();
  const TrafficJudge judge(params_, {track_}, kScans, truth_, observed_, 2, 1);
  // Scan 2's judgments: the trail left at 1 (seen by neither scan 1 nor 2) and the cells
  // entered at 2 (not seen at 2): none.
  EXPECT_EQ(judge.DueAt(2), 0u);
  EXPECT_EQ(judge.DueAt(1), 0u);
  EXPECT_GT(judge.DueAt(3), 0u);
}

}  // namespace
}  // namespace bgkmap::eval
