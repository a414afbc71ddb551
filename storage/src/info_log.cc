#include "info_log.h"

#include <sys/time.h>

#include <cstdarg>
#include <cstring>
#include <ctime>
#include <filesystem>

namespace bgkmap::storage {

std::shared_ptr<rocksdb::Logger> InfoLog::Open(const std::string& dir, size_t max_bytes) {
  return std::shared_ptr<rocksdb::Logger>(new InfoLog(dir + "/LOG", max_bytes));
}

InfoLog::InfoLog(std::string path, size_t max_bytes)
    : path_(std::move(path)), max_bytes_(max_bytes) {
  StartOver();
}

InfoLog::~InfoLog() {
  if (file_ != nullptr) std::fclose(file_);
}

void InfoLog::StartOver() {
  if (file_ != nullptr) std::fclose(file_);
  std::error_code ec;
  std::filesystem::rename(path_, path_ + ".old", ec);  // (a rename needs no free blocks)
  file_ = std::fopen(path_.c_str(), "we");
  written_ = 0;
}

void InfoLog::Logv(const char* format, va_list ap) {
  timeval now;
  gettimeofday(&now, nullptr);
  tm t;
  localtime_r(&now.tv_sec, &t);
  char stamp[128];
  std::snprintf(stamp, sizeof(stamp), "%04d/%02d/%02d-%02d:%02d:%02d.%06ld ", t.tm_year + 1900,
                t.tm_mon + 1, t.tm_mday, t.tm_hour, t.tm_min, t.tm_sec,
                static_cast<long>(now.tv_usec));
  std::lock_guard lock(mu_);  // one line per call, never interleaved
  if (file_ == nullptr) return;
  const int stamped = std::fputs(stamp, file_) >= 0 ? static_cast<int>(std::strlen(stamp)) : 0;
  const int body = std::vfprintf(file_, format, ap);
  std::fputc('\n', file_);
  written_ += static_cast<size_t>(stamped) + (body > 0 ? static_cast<size_t>(body) : 0) + 1;
  if (written_ >= max_bytes_) StartOver();
}

void InfoLog::Flush() {
  std::lock_guard lock(mu_);
  if (file_ != nullptr) std::fflush(file_);
}

}  // namespace bgkmap::storage
