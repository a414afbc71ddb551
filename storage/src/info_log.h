// RocksDB's information log (<dir>/LOG) written with plain stdio, whose write errors are simply
// dropped. RocksDB 7.8's own log file goes through a WritableFileWriter: after one write fails
// on a full disk, its next line or its close fails an assertion (writable_file_writer.h:312)
// and aborts the process. This log only helps debugging; it must never stop the server.
// Internal to storage/.
#pragma once

#include <rocksdb/env.h>

#include <cstdio>
#include <memory>
#include <string>

namespace bgkmap::storage {

class InfoLog final : public rocksdb::Logger {
 public:
  // Keeps the previous LOG as LOG.old (one generation) and starts a new one; a log that cannot
  // be opened (read-only or full directory) logs nothing.
  static std::shared_ptr<rocksdb::Logger> Open(const std::string& dir);
  ~InfoLog() override;

  using rocksdb::Logger::Logv;
  void Logv(const char* format, va_list ap) override;
  void Flush() override;

 private:
  explicit InfoLog(std::FILE* file) : file_(file) {}
  std::FILE* file_;  // null: discard
};

}  // namespace bgkmap::storage
