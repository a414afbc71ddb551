// A real full disk under the real bgkmapd: its data directory sits on a small tmpfs the test
// mounts, and the file system is filled (ENOSPC for any writer, not the file size limit of
// persistence_fault_test). Claims (docs/storage.md, "Free-space reserve"; docs/server.md,
// "Persistence"): bgkmapd keeps storage.min_free_space_mb free and refuses writes below it with
// UNAVAILABLE before RocksDB meets a full disk, so it keeps running and answering reads; nothing
// beyond the acknowledged scans is applied; once there is room again (the test deletes the
// ballast it put on the same file system) ingestion resumes without a restart; a restart on the
// full disk opens the store read-only (recovery in memory, its checkpoint deferred) rather than
// aborting; at SIGTERM it exits 0.
//
// bgkmapd used to abort here: Debian's RocksDB 7.8 (built with assertions) failed `Assertion
// 'sync_without_flush_called_'` in WritableFileWriter::AssertFalseAndGetStatusForPrevError()
// (file/writable_file_writer.h:312), exit code 134, right after a write hit ENOSPC: the writer
// was that of RocksDB's own information log (<data_dir>/LOG), which is now written through stdio
// (storage/src/info_log.h). The reserve keeps RocksDB's writes from meeting the full disk at
// all; the third test runs without it.
//
// Mounting needs CAP_SYS_ADMIN (root on the CI machine); without it the tests are skipped,
// saying so.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/statvfs.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bgkmapd_process.h"
#include "small_file_system.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

namespace fs = std::filesystem;

// Writes `megabytes` of real pages (tmpfs counts them against its size).
bool WriteBallast(const std::string& path, int megabytes) {
  std::ofstream out(path, std::ios::binary);
  const std::string block(1 << 20, 'b');
  for (int i = 0; i < megabytes && out; ++i) out.write(block.data(), block.size());
  out.flush();
  return static_cast<bool>(out);
}

// Writes to `path` until the file system is full (ENOSPC): every byte a writer can get.
bool FillUp(const std::string& path) {
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) return false;
  std::string block(1 << 20, 'f');
  int error = 0;
  for (size_t size = block.size(); size > 0;) {
    if (write(fd, block.data(), size) < 0) {
      error = errno;
      if (error != ENOSPC) break;
      size /= 2;  // the last pages
    }
  }
  close(fd);
  return error == ENOSPC;
}

uint64_t FreeBytes(const std::string& path) {
  struct statvfs st;
  if (statvfs(path.c_str(), &st) != 0) return UINT64_MAX;
  return static_cast<uint64_t>(st.f_bavail) * st.f_frsize;
}

bool StillRunning(BgkmapdProcess& server) { return server.Poll() < 0; }

std::string LastLines(BgkmapdProcess& server, size_t n = 12) {
  const std::vector<std::string> log = server.Log();
  std::string out;
  for (size_t i = log.size() > n ? log.size() - n : 0; i < log.size(); ++i) out += log[i] + "\n";
  return out;
}

// The street sub-scans over and over, with increasing sequence numbers (each one a new scan).
ScanData Scan(const std::vector<OwnedScan>& base, uint64_t sequence, OwnedScan* storage) {
  *storage = base[(sequence - 1) % base.size()];
  storage->sequence = sequence;
  return storage->Data();
}

// The region every sub-scan of the street covers, and what an uninterrupted offline run of the
// acknowledged scans (in sequence order) answers there.
const MetricBox kBox{-30, -30, 30, 30};

Raster Reference(const std::vector<OwnedScan>& base, uint64_t last_sequence) {
  std::vector<const OwnedScan*> scans;
  for (uint64_t s = 1; s <= last_sequence; ++s) scans.push_back(&base[(s - 1) % base.size()]);
  return OfflineRegion(*OfflineMap(scans), kBox);
}

// Retries `sequence` until it is applied (the server polls the free space every second).
RpcResult<ScanAck> InsertOnceThereIsRoom(Client& client, BgkmapdProcess& server,
                                         const std::vector<OwnedScan>& base, uint64_t sequence) {
  OwnedScan owned;
  RpcResult<ScanAck> ack = client.Insert(Scan(base, sequence, &owned));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!ack.ok() && std::chrono::steady_clock::now() < deadline && StillRunning(server)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    ack = client.Insert(Scan(base, sequence, &owned));
  }
  return ack;
}

constexpr const char* kReserveMb = "16";

// Ingests until refused, fills the file system to the last page, checks that reads are served
// and nothing unacknowledged was applied, frees the space and ingests again. `reserve_mb` 0:
// RocksDB itself meets ENOSPC (the failed write latches, the store is reopened once there is
// room; read-only while there is none).
void FillRefuseAndResume(const std::string& reserve_mb) {
  const bool reserve = reserve_mb != "0";
  // 64 MiB with a 32 MiB ballast: ~32 MiB for the store, of which the reserve keeps 16 and
  // RocksDB's memory tables, which count as written, up to a few more.
  SmallFileSystem disk(64);
  if (!disk.mounted()) {
    GTEST_SKIP() << "cannot mount a tmpfs here (" << disk.error()
                 << "; needs CAP_SYS_ADMIN, i.e. root): the real disk-full test needs its own "
                    "small file system";
  }
  const std::string ballast = disk.Sub("ballast");
  ASSERT_TRUE(WriteBallast(ballast, 32));
  BgkmapdProcess server({"--data-dir", disk.Sub("store"), "--worker-threads", "2", "--set",
                         "storage.checkpoint_interval_s=3600", "--set",
                         "storage.min_free_space_mb=" + reserve_mb,
                         // The tmpfs holds ~8 MiB of store: without the raw scans kept for
                         // corrections (~400 KB each here), enough scans to see the log fill it.
                         "--set", "storage.retention_mb=0"});
  ASSERT_TRUE(server.started());
  Client client(server.target());
  const std::vector<OwnedScan> base = SubScans("alpha", 4);
  OwnedScan owned;

  uint64_t sequence = 0, last_acked = 0;
  RpcStatus refused;
  for (int i = 0; i < 3000 && refused.ok(); ++i) {
    ++sequence;
    RpcResult<ScanAck> ack = client.Insert(Scan(base, sequence, &owned));
    if (ack.ok()) {
      last_acked = sequence;
    } else {
      refused = ack.status();
    }
  }
  ASSERT_FALSE(refused.ok()) << "the reserve was never reached (" << last_acked << " scans)";
  ASSERT_TRUE(StillRunning(server)) << "bgkmapd died (exit code " << server.Poll()
                                    << ") when the disk filled up; its last lines:\n"
                                    << LastLines(server);
  EXPECT_EQ(refused.code(), RpcCode::kUnavailable) << refused.ToString();
  EXPECT_NE(refused.message().find("cannot persist"), std::string::npos) << refused.message();
  if (reserve) {
    EXPECT_NE(refused.message().find("below the reserve of 16.0 MB"), std::string::npos)
        << refused.message();
    EXPECT_NE(refused.message().find("writes resume when space is freed"), std::string::npos);
    EXPECT_NE(server.WaitForLine("event=storage_full", 10), "");  // the log pipe lags the RPC
  } else {
    EXPECT_NE(refused.message().find("(disk full)"), std::string::npos) << refused.message();
  }
  EXPECT_GT(last_acked, 10u) << refused.ToString();

  // Now fill the file system to the last page: a real ENOSPC for anyone who writes.
  ASSERT_TRUE(FillUp(disk.Sub("filler")));
  EXPECT_LT(FreeBytes(disk.Sub("")), uint64_t{1} << 20);
  // Full: reads are answered, the refused scan is still refused (not a duplicate), nothing was
  // applied beyond the acknowledged scans.
  RpcResult<ScanAck> again = client.Insert(Scan(base, sequence, &owned));
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.status().code(), RpcCode::kUnavailable) << again.status().ToString();
  // The maintenance thread retries every second (checkpoint, resume) on the full disk.
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  ASSERT_TRUE(StillRunning(server)) << LastLines(server);
  RpcResult<MapInfo> info = client.Info();
  ASSERT_TRUE(info.ok()) << info.status().ToString() << "; bgkmapd exit code " << server.Wait(10)
                         << ", its last lines:\n"
                         << LastLines(server);
  EXPECT_EQ(info->scans_applied, last_acked);
  ASSERT_NE(info->FindRobot("alpha"), nullptr);
  EXPECT_EQ(info->FindRobot("alpha")->last_sequence, last_acked);
  ASSERT_TRUE(info->storage.has_value());
  if (reserve) {
    EXPECT_TRUE(info->storage->writes_paused_for_space);
    EXPECT_FALSE(info->storage->read_only);
    EXPECT_EQ(info->storage->free_space_reserve_bytes, uint64_t{16} << 20);
    EXPECT_LT(info->storage->free_bytes, uint64_t{16} << 20);
    EXPECT_NE(info->storage->writes_paused_reason.find("below the reserve"), std::string::npos)
        << info->storage->writes_paused_reason;
  }
  const std::vector<std::array<double, 2>> points = {{8, 0}, {-8, 0}, {0, 5}};
  RpcResult<PointValues> values = client.QueryPoints(points, {Layer::kElevation});
  ASSERT_TRUE(values.ok()) << values.status().ToString();
  EXPECT_EQ(values->values.size(), points.size());
  RpcResult<Raster> region = client.QueryRegion({kBox, {}, 1});
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  EXPECT_TRUE(BitwiseEqual(*region, Reference(base, last_acked)))
      << "the map is not the one of the " << last_acked << " acknowledged scans";
  RpcResult<ClearResult> clear = client.ClearRegion({0, 0, 1, 1});
  ASSERT_FALSE(clear.ok());
  EXPECT_EQ(clear.status().code(), RpcCode::kUnavailable) << clear.status().ToString();
  if (reserve) {
    // An import: its spool file would eat the reserve, its checkpoint cannot be written.
    TempDir scratch("bgkmap_disk_full");
    const std::string archive = scratch.Sub("map.bgkmap");
    {
      BgkmapdProcess other({"--worker-threads", "1"});
      ASSERT_TRUE(other.started());
      Client to_export(other.target());
      OwnedScan one;
      ASSERT_TRUE(to_export.Insert(Scan(SubScans("beta", 4), 1, &one)).ok());
      ASSERT_TRUE(to_export.ExportMap(std::nullopt, archive).ok());
      other.Signal(SIGTERM);
      ASSERT_EQ(other.Wait(60), 0);
    }
    RpcResult<ImportResult> imported = client.ImportMap(archive);
    ASSERT_FALSE(imported.ok());
    EXPECT_EQ(imported.status().code(), RpcCode::kUnavailable) << imported.status().ToString();
    EXPECT_NE(imported.status().message().find("below the reserve"), std::string::npos)
        << imported.status().message();
    EXPECT_TRUE(BitwiseEqual(*client.QueryRegion({kBox, {}, 1}), Reference(base, last_acked)));
  }

  // Room again: the server sees it within a second and takes the retry.
  ASSERT_TRUE(fs::remove(ballast));
  ASSERT_TRUE(fs::remove(disk.Sub("filler")));
  RpcResult<ScanAck> retry = InsertOnceThereIsRoom(client, server, base, sequence);
  ASSERT_TRUE(retry.ok()) << retry.status().ToString() << "; exit code " << server.Poll()
                          << "; last lines:\n"
                          << LastLines(server);
  EXPECT_EQ(retry->status, AckStatus::kApplied);
  if (reserve) {
    EXPECT_NE(server.WaitForLine("event=storage_resumed", 10), "");
  }
  for (int i = 0; i < 5; ++i) {  // and the next ones
    RpcResult<ScanAck> ack = client.Insert(Scan(base, ++sequence, &owned));
    ASSERT_TRUE(ack.ok()) << ack.status().ToString();
    EXPECT_EQ(ack->status, AckStatus::kApplied);
  }
  info = client.Info();
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->FindRobot("alpha")->last_sequence, sequence);
  EXPECT_FALSE(info->storage->writes_paused_for_space);
  EXPECT_FALSE(info->storage->read_only);
  region = client.QueryRegion({kBox, {}, 1});
  ASSERT_TRUE(region.ok());
  EXPECT_TRUE(BitwiseEqual(*region, Reference(base, sequence)));

  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(60), 0) << LastLines(server);
}

TEST(RealDiskFullTest, ScansAreRefusedReadsServeAndIngestResumesOnceThereIsRoom) {
  FillRefuseAndResume(kReserveMb);
}

// Without the reserve, RocksDB's own writes meet ENOSPC. bgkmapd used to abort then: RocksDB's
// information log (<data_dir>/LOG), after one failed line, fails an assertion on the next
// (writable_file_writer.h:312); it is written through stdio now (storage/src/info_log.h).
// Mutation: StoreDb::Open without InfoLog -> bgkmapd dies with exit code 134 here.
TEST(RealDiskFullTest, WithoutTheReserveRocksDbMeetsTheFullDiskAndTheServerStillSurvives) {
  FillRefuseAndResume("0");
}

TEST(RealDiskFullTest, ARestartOnTheFullDiskOpensTheStoreReadOnly) {
  SmallFileSystem disk(64);
  if (!disk.mounted()) {
    GTEST_SKIP() << "cannot mount a tmpfs here (" << disk.error()
                 << "; needs CAP_SYS_ADMIN, i.e. root): the real disk-full test needs its own "
                    "small file system";
  }
  const std::vector<std::string> args = {"--data-dir",
                                         disk.Sub("store"),
                                         "--worker-threads",
                                         "2",
                                         "--set",
                                         "storage.checkpoint_interval_s=3600",
                                         "--set",
                                         std::string("storage.min_free_space_mb=") + kReserveMb,
                                         "--set",
                                         "storage.retention_mb=0"};
  const std::vector<OwnedScan> base = SubScans("alpha", 4);
  OwnedScan owned;
  constexpr uint64_t kScans = 20;
  {
    // Killed, so the next start has the whole log to replay (and a checkpoint to write).
    BgkmapdProcess server(args);
    ASSERT_TRUE(server.started());
    Client client(server.target());
    for (uint64_t s = 1; s <= kScans; ++s) {
      RpcResult<ScanAck> ack = client.Insert(Scan(base, s, &owned));
      ASSERT_TRUE(ack.ok()) << ack.status().ToString();
    }
    server.Signal(SIGKILL);
    server.Wait();
  }
  ASSERT_TRUE(FillUp(disk.Sub("filler")));
  ASSERT_LT(FreeBytes(disk.Sub("")), uint64_t{1} << 20);

  BgkmapdProcess server(args);
  ASSERT_TRUE(server.started()) << "bgkmapd did not start on the full disk (exit code "
                                << server.Poll() << "); its last lines:\n"
                                << LastLines(server);
  const std::string why = server.FindLine("event=storage_read_only");
  EXPECT_NE(why.find("below the reserve of 16.0 MB"), std::string::npos) << why;
  EXPECT_NE(server.FindLine("event=recovery_checkpoint_deferred"), "");
  Client client(server.target());
  RpcResult<MapInfo> info = client.Info();
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  ASSERT_TRUE(info->storage.has_value());
  EXPECT_TRUE(info->storage->read_only);
  EXPECT_TRUE(info->storage->writes_paused_for_space);
  ASSERT_NE(info->FindRobot("alpha"), nullptr);
  EXPECT_EQ(info->FindRobot("alpha")->last_sequence, kScans);
  RpcResult<Raster> region = client.QueryRegion({kBox, {}, 1});
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  EXPECT_TRUE(BitwiseEqual(*region, Reference(base, kScans)));
  RpcResult<ScanAck> refused = client.Insert(Scan(base, kScans + 1, &owned));
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), RpcCode::kUnavailable) << refused.status().ToString();
  EXPECT_NE(refused.status().message().find("read-only"), std::string::npos)
      << refused.status().message();
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));  // resume attempts on a full disk
  ASSERT_TRUE(StillRunning(server)) << LastLines(server);

  // Room again: the store is reopened for writing and the deferred checkpoint is written.
  ASSERT_TRUE(fs::remove(disk.Sub("filler")));
  RpcResult<ScanAck> ack = InsertOnceThereIsRoom(client, server, base, kScans + 1);
  ASSERT_TRUE(ack.ok()) << ack.status().ToString() << "; last lines:\n" << LastLines(server);
  EXPECT_EQ(ack->status, AckStatus::kApplied);
  info = client.Info();
  ASSERT_TRUE(info.ok());
  EXPECT_FALSE(info->storage->read_only);
  EXPECT_FALSE(info->storage->writes_paused_for_space);
  server.Signal(SIGTERM);
  ASSERT_EQ(server.Wait(60), 0) << LastLines(server);

  BgkmapdProcess again(args);
  ASSERT_TRUE(again.started());
  EXPECT_NE(again.FindLine("scans_replayed=0"), "") << "the shutdown checkpoint held everything";
  Client second(again.target());
  region = second.QueryRegion({kBox, {}, 1});
  ASSERT_TRUE(region.ok());
  EXPECT_TRUE(BitwiseEqual(*region, Reference(base, kScans + 1)));
  again.Signal(SIGTERM);
  EXPECT_EQ(again.Wait(60), 0);
}

// Measurement, not a check (run with --gtest_also_run_disabled_tests; docs/storage.md,
// "Free-space reserve"): the bytes a scan adds to the store before a checkpoint, and the free
// space a restart needs at most to replay a log of N scans and checkpoint it (lowest free space
// seen by a thread polling statvfs every 0.2 ms while bgkmapd starts).
TEST(RealDiskFullTest, DISABLED_MeasureTheSpaceRecoveryNeeds) {
  for (const auto& [name, base] : {std::pair{std::string("street"), StreetScans()},
                                   std::pair{std::string("street/4"), SubScans("alpha", 4)}}) {
    for (uint64_t n : {35, 150}) {
      SmallFileSystem disk(2048);
      if (!disk.mounted()) GTEST_SKIP() << disk.error();
      const std::vector<std::string> args = {"--data-dir",
                                             disk.Sub("store"),
                                             "--worker-threads",
                                             "2",
                                             "--set",
                                             "storage.checkpoint_interval_s=3600",
                                             "--set",
                                             "storage.min_free_space_mb=0",
                                             "--set",
                                             "storage.retention_mb=0"};
      OwnedScan owned;
      uint64_t empty = 0, logged = 0;
      {
        BgkmapdProcess server(args);
        ASSERT_TRUE(server.started());
        empty = DirectoryBytes(disk.Sub("store"));
        Client client(server.target());
        for (uint64_t s = 1; s <= n; ++s) {
          ASSERT_TRUE(client.Insert(Scan(base, s, &owned)).ok());
        }
        logged = DirectoryBytes(disk.Sub("store"));
        server.Signal(SIGKILL);
        server.Wait();
      }
      const uint64_t free_before = FreeBytes(disk.Sub(""));
      std::atomic<bool> stop{false};
      std::atomic<uint64_t> lowest{free_before};
      std::thread sampler([&] {
        while (!stop.load()) {
          lowest.store(std::min(lowest.load(), FreeBytes(disk.Sub(""))));
          std::this_thread::sleep_for(std::chrono::microseconds(200));
        }
      });
      BgkmapdProcess server(args);
      const bool started = server.started();
      stop.store(true);
      sampler.join();
      ASSERT_TRUE(started);
      const uint64_t after = DirectoryBytes(disk.Sub("store"));
      server.Signal(SIGTERM);
      EXPECT_EQ(server.Wait(60), 0);
      std::printf(
          "%s, %3lu scans: store %.1f MB (empty %.2f MB), %.0f KB per scan; restart needed "
          "%.1f MB free at its peak; store after recovery %.1f MB\n",
          name.c_str(), static_cast<unsigned long>(n), logged / 1e6, empty / 1e6,
          (logged - empty) / 1e3 / static_cast<double>(n), (free_before - lowest.load()) / 1e6,
          after / 1e6);
    }
  }
}

}  // namespace
}  // namespace bgkmap::testing
