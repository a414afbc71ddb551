// The sizing rule bgkmapd checks at start (durability/disk_sizing.h, docs/storage.md "Sizing").
#include "durability/disk_sizing.h"

#include <gtest/gtest.h>

namespace bgkmap {
namespace {

constexpr uint64_t kMiB = uint64_t{1} << 20;

TEST(DiskSizingTest, EachTermFollowsItsSetting) {
  const DiskSizing s = SizingFor(/*retention_mb=*/1024, /*min_free_space_mb=*/64,
                                 /*memtable_bytes=*/32 * kMiB, /*map_bytes=*/61 * kMiB);
  EXPECT_EQ(s.retention_bytes, 1024 * kMiB);
  EXPECT_EQ(s.journal_bytes, 512 * kMiB);  // a checkpoint is forced at half the bound
  EXPECT_EQ(s.wal_bytes, 64 * kMiB);
  // The tiles, a checkpoint's new copies and their history before retention trims them.
  EXPECT_EQ(s.map_bytes, 3 * 61 * kMiB);
  EXPECT_EQ(s.transient_bytes, (32 + 8) * kMiB);  // a flush's file, the straddlers; LOG
  EXPECT_EQ(s.reserve_bytes, 64 * kMiB);
  EXPECT_EQ(s.total(), (1024 + 512 + 64 + 183 + 40 + 64) * kMiB);
}

TEST(DiskSizingTest, WithoutRetentionOnlyTheLogMapAndReserveCount) {
  const DiskSizing s = SizingFor(0, 16, 32 * kMiB, 0);
  EXPECT_EQ(s.total(), (64 + 40 + 16) * kMiB);
}

TEST(DiskSizingTest, TheWarningNamesEveryNumberAndFitsOnOneLine) {
  const DiskSizing s = SizingFor(1024, 64, 32 * kMiB, 61 * kMiB);
  EXPECT_EQ(CheckSizing(s, s.total()), "");  // exactly enough is enough
  const std::string why = CheckSizing(s, s.total() - 1);
  EXPECT_EQ(why,
            "the data dir's file system has 1886 MB for the store, the sizing rule asks 1887 MB: "
            "retention 1024 + journal 512 + write-ahead log 64 + map 183 + flushes and logs 40 + "
            "reserve 64 "
            "(storage.retention_mb, storage.min_free_space_mb)");
  EXPECT_EQ(CheckSizing(s, 300 * kMiB).find("has 300 MB for the store"), 27u);
  EXPECT_EQ(why.find('\n'), std::string::npos);
}

}  // namespace
}  // namespace bgkmap
