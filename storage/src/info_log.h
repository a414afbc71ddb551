// RocksDB's information log (<dir>/LOG) written with plain stdio, whose write errors are simply
// dropped. RocksDB 7.8's own log file goes through a WritableFileWriter: after one write fails
// on a full disk, its next line or its close fails an assertion (writable_file_writer.h:312)
// and aborts the process. This log only helps debugging; it must never stop the server, nor
// grow without bound on one that runs for months (RocksDB writes its statistics every 10 min).
// Internal to storage/.
#pragma once

#include <rocksdb/env.h>

#include <cstdio>
#include <memory>
#include <mutex>
#include <string>

namespace bgkmap::storage {

class InfoLog final : public rocksdb::Logger {
 public:
  // Past this size the log starts over, the full one kept as LOG.old: the two hold at most
  // twice this on disk.
  static constexpr size_t kMaxBytes = size_t{2} << 20;

  // Keeps the previous LOG as LOG.old (one generation) and starts a new one; a log that cannot
  // be opened (read-only or full directory) logs nothing.
  static std::shared_ptr<rocksdb::Logger> Open(const std::string& dir,
                                               size_t max_bytes = kMaxBytes);
  ~InfoLog() override;

  using rocksdb::Logger::Logv;
  void Logv(const char* format, va_list ap) override;
  void Flush() override;

 private:
  InfoLog(std::string path, size_t max_bytes);
  void StartOver();  // requires mu_

  const std::string path_;
  const size_t max_bytes_;
  std::mutex mu_;
  std::FILE* file_ = nullptr;  // null: discard
  size_t written_ = 0;         // bytes in the current file
};

}  // namespace bgkmap::storage
