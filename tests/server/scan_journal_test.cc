// ScanScheduler with a journal: a change the journal refuses is not applied, still finishes (the
// changes after it are not blocked), and its robot's sequence number is not advanced so a retry
// is accepted; a barrier sees every change before it journaled and marked.
#include <gtest/gtest.h>

#include <boost/asio/thread_pool.hpp>
#include <future>
#include <set>

#include "bgkmap/core/scan.h"
#include "map_store.h"
#include "scan_scheduler.h"

namespace bgkmap {
namespace {

class FakeJournal final : public ChangeJournal {
 public:
  Status Record(const ChangeRecord& change) override {
    std::lock_guard lock(mu);
    if (fail) return Status::IoError("disk full");
    recorded.push_back(change.version);
    return Status::Ok();
  }
  void Applied(std::span<const TileKey> tiles) override {
    std::lock_guard lock(mu);
    marked.insert(tiles.begin(), tiles.end());
  }
  std::mutex mu;
  bool fail = false;
  std::vector<uint64_t> recorded;
  std::set<TileKey> marked;
};

std::shared_ptr<const PreparedScan> FlatScan(const MapParams& params) {
  std::vector<Point3f> points;
  for (float x = -4; x <= 4; x += 0.05f) {
    for (float y = -4; y <= 4; y += 0.05f) {
      if (x * x + y * y > 2) points.push_back({x, y, -1.0f});
    }
  }
  Result<PreparedScan> p = PrepareScan(params, points, Pose{});
  EXPECT_TRUE(p.ok()) << p.status().ToString();
  return std::make_shared<PreparedScan>(std::move(p).value());
}

class ScanJournalTest : public ::testing::Test {
 protected:
  ScanJournalTest()
      : store_(std::move(TerrainMap::Create(MapParams{})).value()),
        scheduler_(store_, pool_, 16, {}) {
    scheduler_.SetJournal(&journal_);
  }
  ~ScanJournalTest() override { scheduler_.WaitIdle(); }

  ScanOutcome Submit(uint64_t sequence, ScanScheduler::Admission* admission = nullptr) {
    std::promise<ScanOutcome> done;
    auto future = done.get_future();
    ScanScheduler::Admission a =
        scheduler_.SubmitScan("r", sequence, {}, FlatScan(store_.params()),
                              [&done](ScanOutcome o) { done.set_value(std::move(o)); });
    if (admission != nullptr) *admission = a;
    EXPECT_EQ(a, ScanScheduler::Admission::kAdmitted);
    return future.get();
  }

  boost::asio::thread_pool pool_{2};
  MapStore store_;
  FakeJournal journal_;
  ScanScheduler scheduler_;
};

TEST_F(ScanJournalTest, RefusedScanIsNotAppliedAndItsRetryIsAccepted) {
  ScanOutcome first = Submit(1);
  ASSERT_TRUE(first.status.ok());
  const uint64_t cells = store_.Summarize().known_cells;
  ASSERT_GT(cells, 0u);

  journal_.fail = true;
  ScanOutcome refused = Submit(2);
  EXPECT_FALSE(refused.status.ok());
  EXPECT_EQ(refused.version, 2u);
  scheduler_.WaitIdle();
  EXPECT_EQ(scheduler_.LastSequence("r"), 1u);  // a retry is not a duplicate
  EXPECT_EQ(scheduler_.scans_applied(), 1u);
  EXPECT_EQ(scheduler_.applied_version(), 2u);  // finished: later changes are not blocked
  std::unique_ptr<TerrainMap> snapshot = store_.Snapshot();
  snapshot->ForEachTile([](TileKey, const Tile& t) { EXPECT_LE(t.version(), 1u); });

  journal_.fail = false;
  ScanOutcome retry = Submit(2);
  EXPECT_TRUE(retry.status.ok());
  EXPECT_EQ(retry.version, 3u);
  EXPECT_EQ(journal_.recorded, (std::vector<uint64_t>{1, 3}));
  EXPECT_EQ(scheduler_.LastSequence("r"), 2u);

  // A refused clear clears nothing.
  journal_.fail = true;
  std::promise<Status> cleared;
  scheduler_.SubmitClear(CellBox{{-100, -100}, {100, 100}},
                         [&](uint64_t, std::vector<TileKey> tiles, Status s) {
                           EXPECT_TRUE(tiles.empty());
                           cleared.set_value(s);
                         });
  EXPECT_FALSE(cleared.get_future().get().ok());
  EXPECT_EQ(store_.Summarize().known_cells, cells);  // nothing was cleared
}

TEST_F(ScanJournalTest, BarrierSeesEveryEarlierChangeMarkedAndTakesNoVersion) {
  for (uint64_t s = 1; s <= 3; ++s) {
    scheduler_.SubmitScan("r", s, {}, FlatScan(store_.params()), [](ScanOutcome) {});
  }
  std::promise<std::pair<uint64_t, size_t>> seen;
  scheduler_.SubmitBarrier([&](uint64_t applied) {
    std::lock_guard lock(journal_.mu);
    seen.set_value({applied, journal_.marked.size()});
  });
  auto [applied, marked] = seen.get_future().get();
  EXPECT_EQ(applied, 3u);
  EXPECT_GT(marked, 0u);
  scheduler_.WaitIdle();
  EXPECT_EQ(scheduler_.applied_version(), 3u);
  EXPECT_EQ(scheduler_.assigned_version(), 3u);
}

}  // namespace
}  // namespace bgkmap
