// The free-space reserve (free_space.h) with an injected probe and clock: when it probes, what
// it estimates in between, what it refuses and when it lets writes through again; then the same
// reserve in a real TileStore (RocksDB on a temporary directory, only statvfs replaced): refused
// writes latch nothing and change nothing, a store opened below the reserve is read-only and
// Resume() reopens it for writing once there is room.
//
// Mutations checked by hand: Admit() without subtracting admitted bytes (EstimateBetweenProbes
// fails); the time rule dropped (ProbesAgainAfterRefreshInterval fails); OpenImpl() opening
// read-write below the reserve (OpensReadOnlyBelowTheReserve fails).
#include "bgkmap/storage/free_space.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>

#include "bgkmap/storage/recovery.h"
#include "bgkmap/storage/tile_store.h"
#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using testing::Apply;
using testing::MakeScan;
using testing::MapsIdentical;
using testing::NewMap;
using testing::SmallParams;
using testing::TempDir;

constexpr uint64_t kMB = uint64_t{1} << 20;

// A file system whose free space the test sets, and a clock it moves.
struct FakeDisk {
  std::atomic<uint64_t> free{100 * kMB};
  std::atomic<int> probes{0};
  std::atomic<bool> fail{false};
  std::chrono::steady_clock::time_point now{};

  FreeSpaceOptions Options(uint64_t reserve, uint32_t refresh_ms = 100,
                           uint64_t refresh_bytes = kMB) {
    FreeSpaceOptions o;
    o.reserve_bytes = reserve;
    o.refresh_ms = refresh_ms;
    o.refresh_bytes = refresh_bytes;
    o.probe = [this](const std::string&) -> Result<uint64_t> {
      ++probes;
      if (fail) return Status::IoError("statvfs failed (fake)");
      return free.load();
    };
    o.clock = [this] { return now; };
    return o;
  }
  void Advance(int ms) { now += std::chrono::milliseconds(ms); }
};

TEST(FreeSpaceGuardTest, NoReserveProbesNothing) {
  FakeDisk disk;
  disk.free = 0;
  FreeSpaceGuard guard("/data", disk.Options(0));
  EXPECT_TRUE(guard.Admit(10 * kMB).ok());
  EXPECT_TRUE(guard.Check().ok());
  EXPECT_EQ(disk.probes, 0);
}

TEST(FreeSpaceGuardTest, EstimateBetweenProbes) {
  FakeDisk disk;
  disk.free = 20 * kMB;
  // Neither rule fires during the test: one probe, then the estimate alone.
  FreeSpaceGuard guard("/data", disk.Options(10 * kMB, 1'000'000, 1000 * kMB));
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(guard.Admit(kMB).ok()) << i;
  EXPECT_EQ(disk.probes, 1);
  EXPECT_EQ(guard.free_bytes(), 10 * kMB);  // 20 probed - 10 admitted
  const Status refused = guard.Admit(1);
  ASSERT_EQ(refused.code(), Status::Code::kIoError);
  EXPECT_EQ(refused.message(),
            "data dir /data has 10.0 MB free, below the reserve of 10.0 MB "
            "(storage.min_free_space_mb); writes resume when space is freed");
  EXPECT_TRUE(guard.below_reserve());
  EXPECT_EQ(guard.free_bytes(), 10 * kMB);  // a refused write admits nothing
  EXPECT_TRUE(guard.Admit(0).ok());         // exactly the reserve left: nothing more
}

// Issue 25: the robots stopped at the reserve, then RocksDB flushed its memory tables into the
// reserve and the operator's clear met ENOSPC. What the store holds in memory counts as
// written. Mutation caught: FreeLocked() without pending_ (both Admit calls below pass).
TEST(FreeSpaceGuardTest, MemoryTablesAwaitingAFlushCountAsWritten) {
  FakeDisk disk;
  disk.free = 40 * kMB;
  FreeSpaceGuard guard("/data", disk.Options(10 * kMB, 1'000'000, 1000 * kMB));
  uint64_t in_memory = 25 * kMB;
  guard.SetPendingBytes([&] { return in_memory; });
  EXPECT_EQ(guard.free_bytes(), 0u);       // (before the first probe)
  ASSERT_TRUE(guard.Admit(5 * kMB).ok());  // 40 - 25 - 5 = 10: exactly the reserve
  EXPECT_EQ(guard.free_bytes(), 10 * kMB);
  const Status refused = guard.Admit(1);
  ASSERT_EQ(refused.code(), Status::Code::kIoError);
  EXPECT_EQ(refused.message(),
            "data dir /data has 10.0 MB free once the store's 25.0 MB in memory are flushed, "
            "below the reserve of 10.0 MB (storage.min_free_space_mb); writes resume when "
            "space is freed");
  // A freeing write may use the upper half of the reserve, counted the same way.
  EXPECT_TRUE(guard.AdmitFreeing(5 * kMB).ok());
  EXPECT_FALSE(guard.AdmitFreeing(1).ok());
  in_memory = 0;  // flushed: its write-ahead log went, the probe will say so
}

TEST(FreeSpaceGuardTest, ProbesAgainAfterRefreshBytes) {
  FakeDisk disk;
  FreeSpaceGuard guard("/data", disk.Options(10 * kMB, 1'000'000, 4 * kMB));
  ASSERT_TRUE(guard.Admit(3 * kMB).ok());
  ASSERT_TRUE(guard.Admit(kMB / 2).ok());
  EXPECT_EQ(disk.probes, 1);
  ASSERT_TRUE(guard.Admit(kMB).ok());  // 3.5 MB since the probe: below 4, no probe yet
  EXPECT_EQ(disk.probes, 1);
  // Another writer filled the disk meanwhile; 4.5 MB admitted since the probe: probe now.
  disk.free = 12 * kMB;
  EXPECT_FALSE(guard.Admit(3 * kMB).ok());
  EXPECT_EQ(disk.probes, 2);
  EXPECT_TRUE(guard.Admit(2 * kMB).ok());  // 12 - 2 = 10: exactly the reserve
}

TEST(FreeSpaceGuardTest, ProbesAgainAfterRefreshInterval) {
  FakeDisk disk;
  FreeSpaceGuard guard("/data", disk.Options(10 * kMB, 100, 1000 * kMB));
  disk.free = 5 * kMB;
  ASSERT_FALSE(guard.Admit(1).ok());
  EXPECT_EQ(disk.probes, 1);
  disk.free = 50 * kMB;  // space freed
  disk.Advance(99);
  EXPECT_FALSE(guard.Admit(1).ok()) << "answered from the cached probe";
  EXPECT_EQ(disk.probes, 1);
  disk.Advance(1);
  EXPECT_TRUE(guard.Admit(1).ok()) << "the next write after the interval sees the space";
  EXPECT_EQ(disk.probes, 2);
  EXPECT_FALSE(guard.below_reserve());
}

TEST(FreeSpaceGuardTest, CheckProbesAtOnce) {
  FakeDisk disk;
  FreeSpaceGuard guard("/data", disk.Options(10 * kMB, 1'000'000, 1000 * kMB));
  disk.free = 5 * kMB;
  EXPECT_FALSE(guard.Check().ok());
  disk.free = 15 * kMB;
  EXPECT_TRUE(guard.Check().ok());
  EXPECT_EQ(disk.probes, 2);
}

TEST(FreeSpaceGuardTest, AFailedProbeRefuses) {
  FakeDisk disk;
  disk.fail = true;
  FreeSpaceGuard guard("/data", disk.Options(kMB));
  const Status s = guard.Admit(1);
  EXPECT_EQ(s.code(), Status::Code::kIoError);
  EXPECT_NE(s.message().find("statvfs failed"), std::string::npos) << s.message();
  EXPECT_TRUE(guard.below_reserve());
}

TEST(FreeSpaceGuardTest, StatvfsOfARealDirectory) {
  Result<uint64_t> free = StatvfsFreeBytes("/");
  ASSERT_TRUE(free.ok()) << free.status().ToString();
  EXPECT_GT(*free, 0u);
  EXPECT_EQ(StatvfsFreeBytes("/no/such/dir").status().code(), Status::Code::kIoError);
}

std::shared_ptr<const PreparedScan> ScanOf(uint64_t v) {
  return MakeScan(SmallParams(), static_cast<int>(v % 2), static_cast<int>(v), 4000);
}

std::vector<uint64_t> LoggedVersions(const TileStore& store) {
  std::vector<uint64_t> versions;
  EXPECT_TRUE(store.log()
                  .ForEach(0,
                           [&](uint64_t version, Result<LogRecord> r) {
                             EXPECT_TRUE(r.ok());
                             versions.push_back(version);
                             return Status::Ok();
                           })
                  .ok());
  return versions;
}

StoreOptions WithReserve(FakeDisk& disk) {
  StoreOptions o;
  o.free_space = disk.Options(10 * kMB, /*refresh_ms=*/0);  // probe on every write
  return o;
}

TEST(StoreReserveTest, WritesBelowTheReserveAreRefusedAndLatchNothing) {
  const MapParams params = SmallParams();
  TempDir dir;
  FakeDisk disk;
  auto store = std::move(TileStore::Open(dir.path(), WithReserve(disk), params)).value();
  ASSERT_FALSE(store->read_only());
  for (uint64_t v = 1; v <= 3; ++v) {
    ASSERT_TRUE(store->log().Append(LogRecord::Scan(v, "r", v, ScanOf(v))).ok());
  }
  disk.free = 10 * kMB;  // exactly the reserve: any write would go below it
  const Status refused = store->log().Append(LogRecord::Scan(4, "r", 4, ScanOf(4)));
  ASSERT_EQ(refused.code(), Status::Code::kIoError);
  EXPECT_NE(refused.message().find("below the reserve of 10.0 MB"), std::string::npos)
      << refused.message();
  // A checkpoint and a robot's retirement free space: they may use the upper half of the
  // reserve (FreeSpaceGuard::AdmitFreeing, issue 25); below half of it they are refused too.
  disk.free = 4 * kMB;
  EXPECT_EQ(store->Checkpoint(3, {}).code(), Status::Code::kIoError);
  EXPECT_EQ(store->log().RetireRobot("r").code(), Status::Code::kIoError);
  // Nothing written, nothing latched: the robot, versions and log are as before.
  EXPECT_TRUE(store->log().write_failure().ok());
  EXPECT_EQ(store->LastSequence("r"), 3u);
  EXPECT_EQ(store->map_version(), 3u);
  EXPECT_EQ(store->checkpoint_version(), 0u);
  EXPECT_EQ(LoggedVersions(*store), (std::vector<uint64_t>{1, 2, 3}));
  EXPECT_EQ(store->counters().writes_refused_for_space, 3u);
  EXPECT_EQ(store->counters().write_errors, 0u);
  EXPECT_TRUE(store->free_space().below_reserve());

  disk.free = 50 * kMB;  // room again: the next write goes through, no Resume() needed
  ASSERT_TRUE(store->log().Append(LogRecord::Scan(4, "r", 4, ScanOf(4))).ok());
  EXPECT_FALSE(store->free_space().below_reserve());
  store.reset();
  store = std::move(TileStore::OpenExisting(dir.path(), {})).value();
  EXPECT_EQ(LoggedVersions(*store), (std::vector<uint64_t>{1, 2, 3, 4}));
}

TEST(StoreReserveTest, OpensReadOnlyBelowTheReserve) {
  const MapParams params = SmallParams();
  TempDir dir;
  FakeDisk disk;
  {
    auto store = std::move(TileStore::Open(dir.path(), WithReserve(disk), params)).value();
    for (uint64_t v = 1; v <= 4; ++v) {
      ASSERT_TRUE(store->log().Append(LogRecord::Scan(v, "r", v, ScanOf(v))).ok());
    }
  }
  auto reference = NewMap(params);
  for (uint64_t v = 1; v <= 4; ++v) Apply(*reference, *ScanOf(v), v);

  disk.free = 3 * kMB;
  auto store = std::move(TileStore::Open(dir.path(), WithReserve(disk), params)).value();
  ASSERT_TRUE(store->read_only());
  // Reads: the whole log replays into the same map.
  auto recovered = NewMap(params);
  ASSERT_TRUE(RecoverMap(*store, *recovered).ok());
  EXPECT_TRUE(MapsIdentical(*reference, *recovered));
  // Writes: refused, naming why.
  const Status refused = store->log().Append(LogRecord::Scan(5, "r", 5, ScanOf(5)));
  ASSERT_EQ(refused.code(), Status::Code::kIoError);
  EXPECT_NE(refused.message().find("read-only"), std::string::npos) << refused.message();
  EXPECT_NE(refused.message().find("below the reserve"), std::string::npos) << refused.message();
  EXPECT_EQ(store->Checkpoint(4, {}).code(), Status::Code::kIoError);
  EXPECT_TRUE(store->log().Sync().ok());  // nothing to sync; no failure
  // A second opener is refused as for a writable store (the store holds RocksDB's lock).
  EXPECT_FALSE(TileStore::Open(dir.path(), {}, params).ok());
  // Still no room: Resume() says so and stays read-only.
  EXPECT_EQ(store->Resume().code(), Status::Code::kIoError);
  EXPECT_TRUE(store->read_only());
  // Room: reopened for writing, with everything stored.
  disk.free = 50 * kMB;
  ASSERT_TRUE(store->Resume().ok());
  EXPECT_FALSE(store->read_only());
  ASSERT_TRUE(store->log().Append(LogRecord::Scan(5, "r", 5, ScanOf(5))).ok());
  EXPECT_EQ(LoggedVersions(*store), (std::vector<uint64_t>{1, 2, 3, 4, 5}));
  EXPECT_EQ(store->LastSequence("r"), 5u);
}

TEST(StoreReserveTest, NoStoreIsCreatedBelowTheReserve) {
  TempDir dir;
  FakeDisk disk;
  disk.free = kMB;
  const std::string path = dir.path() + "/map";
  std::filesystem::create_directories(path);
  Result<std::unique_ptr<TileStore>> store =
      TileStore::Open(path, WithReserve(disk), SmallParams());
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.status().code(), Status::Code::kIoError);
  EXPECT_NE(store.status().message().find("cannot create a map store"), std::string::npos)
      << store.status().message();
  EXPECT_FALSE(std::filesystem::exists(path + "/CURRENT"));
}

}  // namespace
}  // namespace bgkmap::storage
