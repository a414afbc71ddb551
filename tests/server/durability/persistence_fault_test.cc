// An in-process server with a data directory whose disk fills up (a file size limit makes the
// scan log's writes fail with EFBIG): a scan that cannot be logged is answered UNAVAILABLE, is not
// in the map and does not advance its robot. Once there is room the server resumes the store and
// the retry is applied; after a restart every acknowledged scan is there.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <thread>

#include "test_support.h"

namespace bgkmap::testing {
namespace {

namespace fs = std::filesystem;

uintmax_t LargestFile(const fs::path& dir) {
  uintmax_t largest = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file()) largest = std::max(largest, e.file_size());
  }
  return largest;
}

// Lowers the process's file size limit until Lift() or destruction.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    signal(SIGXFSZ, SIG_IGN);  // EFBIG instead of being killed
    getrlimit(RLIMIT_FSIZE, &saved_);
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    setrlimit(RLIMIT_FSIZE, &limit);
  }
  ~FileSizeLimit() { Lift(); }
  void Lift() { setrlimit(RLIMIT_FSIZE, &saved_); }

 private:
  rlimit saved_;
};

TEST(PersistenceFaultTest, ScanThatCannotBeLoggedIsRefusedAndItsRetryAcceptedOnceThereIsRoom) {
  const fs::path dir = fs::temp_directory_path() / ("bgkmap_fault_" + std::to_string(getpid()));
  fs::remove_all(dir);
  ServerConfig config = TestConfig();
  config.storage.data_dir = dir.string();
  const std::vector<OwnedScan> scans = SubScans("alpha", 8);
  uint64_t last_acked = 0;
  uint64_t refused = 0;
  uint64_t known_cells = 0;
  {
    ServerFixture fixture(config);
    for (size_t i = 0; i < 3; ++i) {
      ASSERT_TRUE(fixture.client().Insert(scans[i].Data()).ok());
      last_acked = scans[i].sequence;
    }
    FileSizeLimit limit(LargestFile(dir) + 100'000);
    for (size_t i = 3; i < scans.size() && refused == 0; ++i) {
      RpcResult<ScanAck> ack = fixture.client().Insert(scans[i].Data());
      if (ack.ok()) {
        last_acked = scans[i].sequence;
        continue;
      }
      refused = scans[i].sequence;
      EXPECT_EQ(ack.status().code(), RpcCode::kUnavailable);
      EXPECT_NE(ack.status().message().find("cannot persist"), std::string::npos)
          << ack.status().message();
    }
    ASSERT_NE(refused, 0u) << "the limit never bit";
    RpcResult<MapInfo> info = fixture.client().Info();
    ASSERT_TRUE(info.ok());
    EXPECT_EQ(info->FindRobot("alpha")->last_sequence, last_acked);  // a retry is not a duplicate
    EXPECT_EQ(info->scans_applied, last_acked);
    known_cells = info->known_cells;
    // While the disk stays full the retry is refused again, not taken for a duplicate.
    RpcResult<ScanAck> again = fixture.client().Insert(scans[refused - 1].Data());
    ASSERT_FALSE(again.ok());
    EXPECT_EQ(again.status().code(), RpcCode::kUnavailable);
    limit.Lift();
    // Room again: the server resumes the store (within a second) and takes the retry.
    RpcResult<ScanAck> retry = again;
    for (int i = 0; i < 50 && !retry.ok(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      retry = fixture.client().Insert(scans[refused - 1].Data());
    }
    ASSERT_TRUE(retry.ok()) << retry.status().ToString();
    EXPECT_EQ(retry->status, AckStatus::kApplied);
    last_acked = refused;
    info = fixture.client().Info();
    ASSERT_TRUE(info.ok());
    known_cells = info->known_cells;
  }
  {
    ServerFixture fixture(config);  // room again
    RpcResult<MapInfo> info = fixture.client().Info();
    ASSERT_TRUE(info.ok());
    EXPECT_EQ(info->FindRobot("alpha")->last_sequence, last_acked);
    EXPECT_EQ(info->known_cells, known_cells);
    RpcResult<ScanAck> again = fixture.client().Insert(scans[refused - 1].Data());
    ASSERT_TRUE(again.ok()) << again.status().ToString();
    EXPECT_EQ(again->status, AckStatus::kDuplicate);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap::testing
