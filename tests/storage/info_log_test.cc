// RocksDB's information log of a store (storage/src/info_log.h): bounded on disk, so a server
// that runs for months does not fill its disk with RocksDB's statistics.
#include "info_log.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace bgkmap::storage {
namespace {

namespace fs = std::filesystem;

class InfoLogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("bgkmap_info_log_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  uint64_t Size(const std::string& name) const {
    std::error_code ec;
    const uint64_t size = fs::file_size(dir_ / name, ec);
    return ec ? 0 : size;
  }
  fs::path dir_;
};

TEST_F(InfoLogTest, StartsOverPastItsBoundKeepingOneFullGeneration) {
  constexpr size_t kMax = 4096;
  {
    std::shared_ptr<rocksdb::Logger> log = InfoLog::Open(dir_.string(), kMax);
    const std::string line(100, 'x');
    for (int i = 0; i < 1000; ++i)
      rocksdb::Log(rocksdb::InfoLogLevel::INFO_LEVEL, log, "%d %s", i, line.c_str());
    log->Flush();
  }
  // 1000 lines of ~130 bytes: 130 KB written, at most two generations kept.
  EXPECT_LT(Size("LOG"), kMax);
  EXPECT_GE(Size("LOG.old"), kMax);
  EXPECT_LT(Size("LOG.old"), kMax + 200);
  // The newest line is in LOG, whole.
  std::ifstream in(dir_ / "LOG");
  std::string last, line;
  while (std::getline(in, line)) last = line;
  EXPECT_NE(last.find(" 999 xxx"), std::string::npos) << last;
}

TEST_F(InfoLogTest, OpeningKeepsThePreviousLogAsOld) {
  {
    std::shared_ptr<rocksdb::Logger> log = InfoLog::Open(dir_.string());
    rocksdb::Log(rocksdb::InfoLogLevel::INFO_LEVEL, log, "first run");
  }
  {
    std::shared_ptr<rocksdb::Logger> log = InfoLog::Open(dir_.string());
    rocksdb::Log(rocksdb::InfoLogLevel::INFO_LEVEL, log, "second run");
  }
  std::ifstream old(dir_ / "LOG.old");
  const std::string text((std::istreambuf_iterator<char>(old)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("first run"), std::string::npos);
}

}  // namespace
}  // namespace bgkmap::storage
