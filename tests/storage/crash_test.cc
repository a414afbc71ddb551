// SIGKILLs a process ingesting scans of three robots from three threads at random moments, then
// reopens its store: every scan the process acknowledged must be in the recovered map, and the map
// must equal an uninterrupted run of exactly the scans the store kept, in version order.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <random>
#include <set>
#include <sstream>

#include "bgkmap/storage/recovery.h"
#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using testing::Apply;
using testing::MakeScan;
using testing::MapsIdentical;
using testing::NewMap;
using testing::SmallParams;
using testing::TempDir;

constexpr int kRobots = 3;
constexpr uint64_t kChanges = 60;
constexpr uint64_t kCheckpointEvery = 16;

struct ChildRun {
  std::set<uint64_t> acked;
  bool finished = false;                     // printed "done" before the kill
  std::chrono::microseconds ingest_time{0};  // from "ready" to "done"
  std::string error;
};

// Starts the writer, kills it `kill_after` after it is ready (unless it finishes first) and
// collects what it acknowledged.
ChildRun RunAndKill(const std::string& dir, const char* durability,
                    std::chrono::microseconds kill_after) {
  int fds[2];
  EXPECT_EQ(pipe(fds), 0);
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(fds[1], STDOUT_FILENO);
    close(fds[0]);
    close(fds[1]);
    const std::string writer = std::string(BGKMAP_BINARY_DIR) + "/tests/storage/crash_writer";
    execl(writer.c_str(), writer.c_str(), dir.c_str(), durability, std::to_string(kChanges).c_str(),
          std::to_string(kCheckpointEvery).c_str(), "3", std::to_string(kRobots).c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  close(fds[1]);
  ChildRun run;
  std::string buffer;
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  bool killed = false;
  auto ready_at = std::chrono::steady_clock::now();
  for (;;) {
    const auto now = std::chrono::steady_clock::now();
    if (!killed && now >= deadline) {
      kill(pid, SIGKILL);
      killed = true;
    }
    const int wait_ms = static_cast<int>(std::max<int64_t>(
        0, std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now).count()));
    pollfd p{fds[0], POLLIN, 0};
    if (poll(&p, 1, killed ? 1000 : wait_ms) == 0) {
      if (killed) break;
      continue;
    }
    char chunk[4096];
    const ssize_t n = read(fds[0], chunk, sizeof(chunk));
    if (n <= 0) break;  // the child is gone
    buffer.append(chunk, static_cast<size_t>(n));
    size_t eol;
    while ((eol = buffer.find('\n')) != std::string::npos) {
      const std::string line = buffer.substr(0, eol);
      buffer.erase(0, eol + 1);
      if (line == "ready") {
        ready_at = std::chrono::steady_clock::now();
        deadline = ready_at + kill_after;
      } else if (line.rfind("ack ", 0) == 0) {
        run.acked.insert(std::stoull(line.substr(4)));
      } else if (line == "done") {
        run.finished = true;
        run.ingest_time = std::chrono::duration_cast<std::chrono::microseconds>(
            std::chrono::steady_clock::now() - ready_at);
      } else if (line.rfind("error", 0) == 0) {
        run.error = line;
      }
    }
  }
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  return run;
}

// What the kill left: the versions the store holds (all up to the checkpoint, then the logged
// ones), checked against the acknowledgements and an uninterrupted run of the same scans.
void CheckRecovered(const std::string& dir, const ChildRun& run) {
  const MapParams params = SmallParams();
  auto store = TileStore::OpenExisting(dir, {});
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  std::set<uint64_t> kept;
  for (uint64_t v = 1; v <= (*store)->checkpoint_version(); ++v) kept.insert(v);
  ASSERT_TRUE((*store)
                  ->log()
                  .ForEach((*store)->checkpoint_version(),
                           [&](uint64_t v, Result<LogRecord> r) {
                             EXPECT_TRUE(r.ok()) << r.status().ToString();
                             kept.insert(v);
                             return Status::Ok();
                           })
                  .ok());
  for (uint64_t v : run.acked) ASSERT_TRUE(kept.count(v)) << "acknowledged scan " << v << " lost";

  auto recovered = NewMap(params);
  auto report = RecoverMap(**store, *recovered);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->clean());
  ASSERT_TRUE(LoadAllTiles(**store, *recovered).ok());

  auto reference = NewMap(params);
  std::map<std::string, uint64_t> last_sequence;
  for (uint64_t v : kept) {
    const int robot = static_cast<int>(v % kRobots), index = static_cast<int>(v / kRobots);
    Apply(*reference, *MakeScan(params, robot, index), v);
    last_sequence["robot-" + std::to_string(robot)] = index + 1;
  }
  EXPECT_TRUE(MapsIdentical(*reference, *recovered));
  for (const auto& [robot, sequence] : last_sequence) {
    EXPECT_EQ((*store)->LastSequence(robot), sequence) << robot;
  }
}

// Kills `trials` writers at moments spread over an uninterrupted run's ingest time.
void KillAtRandomMoments(const char* durability, int trials, unsigned seed) {
  std::mt19937 rng(seed);
  TempDir calibration;
  const ChildRun full = RunAndKill(calibration.path(), durability, std::chrono::seconds(30));
  ASSERT_TRUE(full.finished) << full.error;
  ASSERT_EQ(full.acked.size(), kChanges);
  CheckRecovered(calibration.path(), full);

  const auto span = full.ingest_time;
  int interrupted = 0;
  for (int trial = 0; trial < trials; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    TempDir dir;
    std::uniform_int_distribution<int64_t> when(0, span.count());
    const ChildRun run = RunAndKill(dir.path(), durability, std::chrono::microseconds(when(rng)));
    ASSERT_TRUE(run.error.empty()) << run.error;
    interrupted += run.finished ? 0 : 1;
    CheckRecovered(dir.path(), run);
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GE(interrupted, trials / 2) << "most kills should land mid-run";
  std::cout << durability << ": " << interrupted << " of " << trials
            << " runs killed mid-ingest (full ingest " << span.count() / 1000 << " ms)\n";
}

TEST(CrashTest, SyncAcknowledgedScansSurviveSigkillAtRandomMoments) {
  KillAtRandomMoments("sync", 24, 20240611);
}

// Periodic durability acknowledges before the fsync, but the record is already in the page
// cache: a process crash loses nothing (only a power loss has a window).
TEST(CrashTest, PeriodicAcknowledgedScansSurviveSigkill) { KillAtRandomMoments("periodic", 8, 7); }

}  // namespace
}  // namespace bgkmap::storage
