// A real full disk under the real bgkmapd: its data directory sits on a small tmpfs the test
// mounts, and scans are ingested until the file system is full (ENOSPC, not the file size limit
// of persistence_fault_test). Claims (docs/server.md, "Persistence"; docs/storage.md, "Faults"):
// a scan that cannot be logged is answered UNAVAILABLE "cannot persist ... (disk full)", the
// server keeps running and answering reads, and once there is room again (the test deletes a
// ballast file it put on the same file system) ingestion resumes without a restart; at SIGTERM
// it exits 0.
//
// Mounting needs CAP_SYS_ADMIN (root on the CI machine); without it the test is skipped, saying
// so.
//
// DISABLED: today bgkmapd aborts when the file system fills up. Debian's RocksDB 7.8 (built with
// assertions) fails `Assertion 'sync_without_flush_called_'` in
// WritableFileWriter::AssertFalseAndGetStatusForPrevError() (file/writable_file_writer.h:312),
// exit code 134, on the first write after the WAL write hit ENOSPC; the test reports exactly
// that ("bgkmapd died (exit code 134) when the disk filled up"). A free-space reserve in the
// server (the security work) is to keep RocksDB from reaching ENOSPC; enable the test with it.
// Run it by hand: real_disk_full_test --gtest_also_run_disabled_tests
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "bgkmapd_process.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

namespace fs = std::filesystem;

// A tmpfs of `megabytes` mounted on a fresh directory, unmounted (lazily) and removed on exit.
class SmallFileSystem {
 public:
  explicit SmallFileSystem(int megabytes) {
    path_ = (fs::temp_directory_path() / ("bgkmap_small_fs_" + std::to_string(getpid()))).string();
    fs::create_directories(path_);
    const std::string options = "size=" + std::to_string(megabytes) + "m,mode=0700";
    if (mount("tmpfs", path_.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, options.c_str()) != 0) {
      error_ = std::strerror(errno);
      return;
    }
    mounted_ = true;
  }
  ~SmallFileSystem() {
    if (mounted_) umount2(path_.c_str(), MNT_DETACH);
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  bool mounted() const { return mounted_; }
  const std::string& error() const { return error_; }
  std::string Sub(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
  std::string error_;
  bool mounted_ = false;
};

// Writes `megabytes` of real pages (tmpfs counts them against its size).
bool WriteBallast(const std::string& path, int megabytes) {
  std::ofstream out(path, std::ios::binary);
  const std::string block(1 << 20, 'b');
  for (int i = 0; i < megabytes && out; ++i) out.write(block.data(), block.size());
  out.flush();
  return static_cast<bool>(out);
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

TEST(RealDiskFullTest, DISABLED_ScansAreRefusedReadsServeAndIngestResumesOnceThereIsRoom) {
  // 48 MiB: a 32 MiB ballast leaves ~16 MiB for the store, which its write-ahead log fills
  // within a few hundred scans (before RocksDB's 32 MiB of memory tables flush); freeing the
  // ballast leaves room for the reopen after the failure, which writes the log's memory table
  // to a table file.
  SmallFileSystem disk(48);
  if (!disk.mounted()) {
    GTEST_SKIP() << "cannot mount a tmpfs here (" << disk.error()
                 << "; needs CAP_SYS_ADMIN, i.e. root): the real disk-full test needs its own "
                    "small file system";
  }
  const std::string ballast = disk.Sub("ballast");
  ASSERT_TRUE(WriteBallast(ballast, 32));
  BgkmapdProcess server({"--data-dir", disk.Sub("store"), "--worker-threads", "2", "--set",
                         "storage.checkpoint_interval_s=3600"});
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
  ASSERT_FALSE(refused.ok()) << "the file system never filled up (" << last_acked << " scans)";
  ASSERT_TRUE(StillRunning(server)) << "bgkmapd died (exit code " << server.Poll()
                                    << ") when the disk filled up; its last lines:\n"
                                    << LastLines(server);
  EXPECT_EQ(refused.code(), RpcCode::kUnavailable) << refused.ToString();
  EXPECT_NE(refused.message().find("cannot persist"), std::string::npos) << refused.message();
  EXPECT_NE(refused.message().find("disk full"), std::string::npos) << refused.message();
  EXPECT_GT(last_acked, 10u);

  // Full: reads are answered, the refused scan is still refused (not a duplicate), nothing was
  // applied beyond the acknowledged scans.
  RpcResult<MapInfo> info = client.Info();
  ASSERT_TRUE(info.ok()) << info.status().ToString() << "; bgkmapd exit code " << server.Wait(10)
                         << ", its last lines:\n"
                         << LastLines(server);
  EXPECT_EQ(info->scans_applied, last_acked);
  ASSERT_NE(info->FindRobot("alpha"), nullptr);
  EXPECT_EQ(info->FindRobot("alpha")->last_sequence, last_acked);
  const std::vector<std::array<double, 2>> points = {{8, 0}, {-8, 0}, {0, 5}};
  RpcResult<PointValues> values = client.QueryPoints(points, {Layer::kElevation});
  ASSERT_TRUE(values.ok()) << values.status().ToString();
  EXPECT_EQ(values->values.size(), points.size());
  RpcResult<Raster> region = client.QueryRegion({{-10, -10, 10, 10}, {}, 1});
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  RpcResult<ScanAck> again = client.Insert(Scan(base, sequence, &owned));
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.status().code(), RpcCode::kUnavailable) << again.status().ToString();
  ASSERT_TRUE(StillRunning(server)) << LastLines(server);

  // Room again: the server resumes its store (it retries every second) and takes the retry.
  ASSERT_TRUE(fs::remove(ballast));
  RpcResult<ScanAck> retry = again;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!retry.ok() && std::chrono::steady_clock::now() < deadline && StillRunning(server)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    retry = client.Insert(Scan(base, sequence, &owned));
  }
  ASSERT_TRUE(retry.ok()) << retry.status().ToString() << "; exit code " << server.Poll()
                          << "; last lines:\n"
                          << LastLines(server);
  EXPECT_EQ(retry->status, AckStatus::kApplied);
  EXPECT_NE(server.FindLine("event=storage_resumed"), "");
  for (int i = 0; i < 5; ++i) {  // and the next ones
    RpcResult<ScanAck> ack = client.Insert(Scan(base, ++sequence, &owned));
    ASSERT_TRUE(ack.ok()) << ack.status().ToString();
    EXPECT_EQ(ack->status, AckStatus::kApplied);
  }
  info = client.Info();
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->FindRobot("alpha")->last_sequence, sequence);

  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(60), 0);
}

}  // namespace
}  // namespace bgkmap::testing
