// Makes writes fail as on a full disk (a file size limit: writes past it fail with EFBIG) in the
// middle of ingestion: the failing append is an IoError, nothing acknowledged before it is lost,
// and appends succeed again once the limit is lifted.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>

#include <filesystem>

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

uintmax_t LargestFile(const std::string& dir) {
  uintmax_t largest = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.is_regular_file()) largest = std::max(largest, e.file_size());
  }
  return largest;
}

// Lowers the process's file size limit for its lifetime.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    signal(SIGXFSZ, SIG_IGN);  // get EFBIG instead of being killed
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

std::shared_ptr<const PreparedScan> ScanOf(uint64_t v) {
  return MakeScan(SmallParams(), static_cast<int>(v % 2), static_cast<int>(v), 4000);
}

TEST(DiskFullTest, FailedAppendIsIoErrorAndNothingAcknowledgedIsLost) {
  const MapParams params = SmallParams();
  TempDir dir;
  std::vector<uint64_t> acked;
  uint64_t v = 0;
  Status failure;
  {
    auto store = std::move(TileStore::Open(dir.path(), {}, params)).value();
    for (int i = 0; i < 5; ++i) {
      ++v;
      ASSERT_TRUE(store->log().Append(LogRecord::Scan(v, "r", v, ScanOf(v))).ok());
      acked.push_back(v);
    }
    {
      FileSizeLimit limit(LargestFile(dir.path()) + 200'000);
      for (int i = 0; i < 100 && failure.ok(); ++i) {
        ++v;
        failure = store->log().Append(LogRecord::Scan(v, "r", v, ScanOf(v)));
        if (failure.ok()) acked.push_back(v);
      }
      ASSERT_FALSE(failure.ok()) << "the limit never bit";
      EXPECT_EQ(failure.code(), Status::Code::kIoError) << failure.ToString();
      // While the disk stays full, appends keep failing rather than half-succeeding.
      // While the disk stays full, appends and checkpoints keep failing (never half-succeed).
      const Status again = store->log().Append(LogRecord::Scan(v + 1, "r", v + 1, ScanOf(v + 1)));
      EXPECT_EQ(again.code(), Status::Code::kIoError);
      EXPECT_EQ(store->Checkpoint(store->checkpoint_version(), {}).code(), Status::Code::kIoError);
      limit.Lift();
    }
    EXPECT_GE(store->counters().write_errors, 1u);
    std::cout << "append failed after " << acked.size() << " scans: " << failure.ToString() << "\n";
    // Room again: the store resumes and takes new scans (the failed versions are skipped, as
    // a server refusing them would).
    ASSERT_TRUE(store->Resume().ok());
    v += 2;
    ASSERT_TRUE(store->log().Append(LogRecord::Scan(v, "r", v, ScanOf(v))).ok());
    acked.push_back(v);
    EXPECT_EQ(store->LastSequence("r"), v);
  }
  // Reopen (as after a restart): every acknowledged scan is there, and only those.
  auto store = std::move(TileStore::OpenExisting(dir.path(), {})).value();
  std::vector<uint64_t> kept;
  ASSERT_TRUE(store->log()
                  .ForEach(0,
                           [&](uint64_t version, Result<LogRecord> r) {
                             EXPECT_TRUE(r.ok());
                             kept.push_back(version);
                             return Status::Ok();
                           })
                  .ok());
  EXPECT_EQ(kept, acked);
  auto recovered = NewMap(params);
  ASSERT_TRUE(RecoverMap(*store, *recovered).ok());
  auto reference = NewMap(params);
  for (uint64_t k : acked) Apply(*reference, *ScanOf(k), k);
  EXPECT_TRUE(MapsIdentical(*reference, *recovered));
}

}  // namespace
}  // namespace bgkmap::storage
