#include "info_log.h"

#include <sys/time.h>

#include <cstdarg>
#include <ctime>
#include <filesystem>

namespace bgkmap::storage {

std::shared_ptr<rocksdb::Logger> InfoLog::Open(const std::string& dir) {
  const std::string path = dir + "/LOG";
  std::error_code ec;
  std::filesystem::rename(path, path + ".old", ec);  // (a rename needs no free blocks)
  std::FILE* file = std::fopen(path.c_str(), "we");
  return std::shared_ptr<rocksdb::Logger>(new InfoLog(file));
}

InfoLog::~InfoLog() {
  if (file_ != nullptr) std::fclose(file_);
}

void InfoLog::Logv(const char* format, va_list ap) {
  if (file_ == nullptr) return;
  timeval now;
  gettimeofday(&now, nullptr);
  tm t;
  localtime_r(&now.tv_sec, &t);
  char stamp[128];
  std::snprintf(stamp, sizeof(stamp), "%04d/%02d/%02d-%02d:%02d:%02d.%06ld ", t.tm_year + 1900,
                t.tm_mon + 1, t.tm_mday, t.tm_hour, t.tm_min, t.tm_sec,
                static_cast<long>(now.tv_usec));
  // One line per call; stdio locks the stream, so concurrent lines do not interleave.
  flockfile(file_);
  std::fputs(stamp, file_);
  std::vfprintf(file_, format, ap);
  std::fputc('\n', file_);
  funlockfile(file_);
}

void InfoLog::Flush() {
  if (file_ != nullptr) std::fflush(file_);
}

}  // namespace bgkmap::storage
